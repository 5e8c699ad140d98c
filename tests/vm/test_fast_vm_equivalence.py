"""The fast VM (compiled collector + skipped collections) against the reference mode.

``VM(stress_gc=True)`` collects with the transcription of ``bbzheap_gc`` before every
instruction, as the firmware does; ``VM(stress_gc=False)`` runs the compiled collector and
skips the collections it proves changeless (ARCHITECTURE.md "Two modes, and the seam"). Every
observable state must be identical: heap bytes (stale bytes, mark and valid bits included),
rtobj/ltseg, stack, pc, state, error events with their pc, the GC run count.

Observed: every dump of the 92 corpus harness runs (``tests/vm/test_core_corpus.py`` also
compares the vm-core driver's dumps), and for generated
Buzz programs (hypothesis) after every phase and after random instruction counts — a budget
stops the run mid-step, as an inspector pausing the VM would. Mutated bytecode exercises the
corrupt states (stale references, freed-but-referenced objects) where a shortcut would show.
"""

from __future__ import annotations

import random
import sys
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

sys.path.insert(0, str(Path(__file__).parent))

from corpus import BBZ_DIR  # noqa: E402

from bbzide.compiler import compile_source  # noqa: E402
from bbzide.diagnostics import CompileError  # noqa: E402
from bbzide.vm.profiles import KILOBOT, PC, Profile  # noqa: E402
from bbzide.vm.vm import VM, State  # noqa: E402


def _observe(vm: VM) -> tuple:
    return (vm.state, vm.error, vm.pc, list(vm.stack[:vm.stackptr + 1]), vm.blockptr,
            vm.heap.rtobj, vm.heap.ltseg, bytes(vm.heap.data), list(vm.error_events),
            vm.heap.gc_runs, vm.instructions_executed, vm.heap.peak_used)


def _harness_lines() -> list[tuple[str, list[str]]]:
    """(profile name, arguments) of every harness run in the corpus ``.cmd`` files."""
    runs = []
    for cmd in sorted(Path(BBZ_DIR).glob("*.cmd")):
        for line in cmd.read_text().splitlines():
            words = line.split()
            if words and words[0] in ("bbzharness-pc", "bbzavr.py") and ">" in words:
                runs.append(("pc" if words[0] == "bbzharness-pc" else "kilobot",
                             words[1:words.index(">")]))
    return runs


HARNESS_RUNS = _harness_lines()


def test_the_corpus_has_every_harness_run() -> None:
    assert len(HARNESS_RUNS) == 92


# one case per run (the suite's longest check as one test): a parallel run spreads them
@pytest.mark.parametrize(("profile", "argv"), HARNESS_RUNS,
                         ids=[" ".join(argv) for _profile, argv in HARNESS_RUNS])
def test_corpus_harness_runs_identical(profile: str, argv: list[str]) -> None:
    """The whole firmware loop (messages, neighbors, stigmergy, swarms, injections) through
    vm-runtime's harness: every ``#BBZDUMP 1`` line (all heap bytes) equal in both modes."""
    from bbzide.harness.runner import run_command_line
    from bbzide.vm.profiles import get_profile

    stress = run_command_line(argv, Path(BBZ_DIR), get_profile(profile), stress_gc=True)
    fast = run_command_line(argv, Path(BBZ_DIR), get_profile(profile), stress_gc=False)
    assert (stress.lines, stress.status) == (fast.lines, fast.status), argv
    assert stress.robot.vm.heap.gc_runs == fast.robot.vm.heap.gc_runs, argv
    assert stress.robot.vm.heap.peak_used == fast.robot.vm.heap.peak_used, argv


def test_kernel_skip_rules_are_the_vm_rules() -> None:
    """The compiled kernel (fastloop.py) repeats the VM's skip-rule table."""
    from bbzide.vm.compiled import fastloop
    from bbzide.vm.vm import _SKIP_RULES

    assert list(fastloop.RULES) == _SKIP_RULES


# ---- generated programs ---------------------------------------------------------------
# Small Buzz programs built to reach every skip rule's edge: locals and globals (pushes of
# existing objects), literals (new leaves), tables nested deeper than the GC mark depth
# (freed-but-referenced objects, first-visit-wins order), lambdas with activation records,
# strings (dedupe), errors (division by zero, calls of non-closures, floats on Kilobot).

_NAMES = ["a", "b", "c"]


def _operand(draw: st.DrawFn, depth: int) -> str:
    """An arithmetic operand (Buzz accepts table literals and lambdas only as whole
    expressions, spec §A.3)."""
    kind = draw(st.sampled_from(["int", "int", "var", "var", "field"]
                                + (["bin", "cmp", "unary", "logic"] if depth < 3
                                   else ["str", "float"])))
    if kind == "int":
        return str(draw(st.integers(0, 40000)))
    if kind == "float":  # a TYPE error on Kilobot, float arithmetic (Python) on PC
        return f"{draw(st.integers(0, 99))}.5"
    if kind == "unary":
        return f"({draw(st.sampled_from(['-', 'not ']))}{_operand(draw, depth + 1)})"
    if kind == "logic":
        op = draw(st.sampled_from(["and", "or"]))
        return f"({_operand(draw, depth + 1)} {op} {_operand(draw, depth + 1)})"
    if kind == "var":
        return draw(st.sampled_from(_NAMES + ["g", "i"]))
    if kind == "str":
        return repr(draw(st.sampled_from(["x", "y", "a"])))
    if kind == "field":
        return f"t.{draw(st.sampled_from(['x', 'y', 'n', 'h']))}"
    if kind == "bin":
        op = draw(st.sampled_from(["+", "-", "*", "/", "%", "^"]))
        # literal divisors: a division by zero would end most runs early (MATH error)
        rhs = str(draw(st.integers(1, 9))) if op in "/%^" else _operand(draw, depth + 1)
        return f"({_operand(draw, depth + 1)} {op} {rhs})"
    op = draw(st.sampled_from(["==", "!=", "<", ">=", ">", "<="]))
    return f"({_operand(draw, depth + 1)} {op} {_operand(draw, depth + 1)})"


def _expr(draw: st.DrawFn, depth: int) -> str:
    kind = draw(st.sampled_from(["op", "op", "op", "table", "lambda"]))
    if kind == "op":
        return _operand(draw, depth)
    if kind == "table":
        return f"{{.x = {_expr(draw, depth + 1)}, .y = {_operand(draw, depth + 1)}}}"
    return f"function(p) {{ return p + {_operand(draw, depth + 1)} }}"


def _nested(levels: int) -> str:
    text = "1"
    for _ in range(levels):
        text = f"{{.n = {text}, .x = 2}}"
    return text


def _stmt(draw: st.DrawFn, depth: int) -> str:
    kind = draw(st.sampled_from(["set", "set", "global", "field", "if", "while", "call",
                                 "nest", "lambda"] if depth < 2 else ["set", "global"]))
    if kind == "set":
        return f"{draw(st.sampled_from(_NAMES))} = {_expr(draw, 0)}"
    if kind == "global":
        return f"g = {_expr(draw, 0)}"
    if kind == "field":
        return f"t.{draw(st.sampled_from(['x', 'y']))} = {_expr(draw, 0)}"
    if kind == "if":
        return (f"if ({_operand(draw, 1)}) {{ {_stmt(draw, depth + 1)} }} "
                f"else {{ {_stmt(draw, depth + 1)} }}")
    if kind == "while":
        n = draw(st.integers(0, 8))
        body = " ".join(_stmt(draw, depth + 1) for _ in range(draw(st.integers(1, 4))))
        return f"i = 0 while (i < {n}) {{ {body} i = i + 1 }}"
    if kind == "call":
        return f"{draw(st.sampled_from(_NAMES))} = helper({_operand(draw, 1)})"
    if kind == "nest":
        return f"t.n = {_nested(draw(st.integers(5, 11)))}"
    return f"f = function(q) {{ return q * {_operand(draw, 1)} }} a = f(3)"


@st.composite
def programs(draw: st.DrawFn) -> str:
    body = [_stmt(draw, 0) for _ in range(draw(st.integers(1, 8)))]
    init = [_stmt(draw, 0) for _ in range(draw(st.integers(0, 3)))]
    return "\n".join([
        "g = 0",
        "i = 0",
        "t = {.x = 1}",
        "function helper(v) { var w = v t.h = w return w }",
        "function init() {",
        "  var a = 1 var b = 2 var c = 3 var f = nil",
        *init,
        "}",
        "function step() {",
        "  var a = g var b = 1 var c = t var f = nil",
        *body,
        "}",
    ]) + "\n"


def _new_vm(profile: Profile, stress: bool, budget: int | None) -> VM:
    vm = VM(profile, stress_gc=stress)
    # nested loops may share their counter and never end: always bounded
    vm.instruction_budget = budget if budget is not None else 5_000
    vm.construct()
    return vm


def _run(bbo: bytes, strings: list[str], profile: Profile, stress: bool,
         budget: int | None, snapshots: list[bytes] | None = None) -> list[tuple]:
    """Top level, init, 4 steps; observed after each phase. ``budget`` stops every phase
    after that many instructions (a mid-step observation). ``snapshots``: after init and
    each step, the VM is replaced by a new one restored from its snapshot (kept there)."""
    vm = _new_vm(profile, stress, budget)
    vm.set_bcode(bbo)
    out = [_observe(vm)]
    vm.run()
    out.append(_observe(vm))
    for name in ["init"] + ["step"] * 4:
        if snapshots is not None:
            snapshots.append(vm.snapshot())
            vm = _new_vm(profile, stress, budget)
            vm.restore(snapshots[-1])
        if vm.state == State.ERROR:
            break
        if name not in strings:
            continue
        vm.state = State.READY
        vm.push_nil()
        vm.function_call(strings.index(name), 0)
        if vm.state == State.READY:
            vm.pop()
        out.append(_observe(vm))
    return out


def _compare(bbo: bytes, strings: list[str], seed: int) -> None:
    rng = random.Random(seed)
    for profile in (PC, KILOBOT):
        for budget in (None, rng.randrange(1, 60), rng.randrange(60, 600)):
            stress = _run(bbo, strings, profile, True, budget)
            fast = _run(bbo, strings, profile, False, budget)
            assert stress == fast, (profile.name, budget)


@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(programs(), st.integers(0, 2**32))
def test_generated_programs_identical(source: str, seed: int) -> None:
    try:
        program = compile_source(source, "gen.bzz").to_bbo()
    except CompileError:
        return
    _compare(program.bbo, program.strings, seed)


_BASE = compile_source(
    "t = {.x = {.y = {.z = 1}}}\n"
    "function step() { var a = t.x var b = 3 * 4 a.q = b t.l = function(p) { return p + b }"
    " var c = t.l(2) g = {.n = {.n = {.n = {.n = {.n = {.n = {.n = {.n = 1}}}}}}}} }\n",
    "mutate.bzz",
).to_bbo()


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.lists(st.tuples(st.integers(0, len(_BASE.bbo) - 1), st.integers(0, 255)),
                min_size=1, max_size=4), st.integers(0, 2**32))
def test_mutated_bytecode_identical(mutations: list[tuple[int, int]], seed: int) -> None:
    code = bytearray(_BASE.bbo)
    for offset, value in mutations:
        code[offset] = value
    _compare(bytes(code), _BASE.strings, seed)


#: a nest deeper than the collector's depth limit: the tables below the limit are freed while
#: still referenced, and a later collection reaches such a freed slot at the top of the
#: objects, marks it and retreats the object end past it; the next collection does not walk it
#: again (its mark bit above the end stays set), so the two collections differ
_UNSETTLING = """g = 0
i = 0
t = {.x = 1}
function init() {
  var a = 1 var b = 2 var c = 3 var f = nil
}
function step() {
  var a = g var b = 1 var c = t var f = nil
  b = {.x = function(p) { return p + 0 }, .y = b}
  g = function(p) { return p + 20420 }
  b = 1024
  c = 0
  i = 0 while (i < 7) { t.n = {.n = {.n = {.n = {.n = {.n = {.n = {.n = {.n = {.n = 1, .x = 2},
    .x = 2}, .x = 2}, .x = 2}, .x = 2}, .x = 2}, .x = 2}, .x = 2}, .x = 2} g = 39451 i = i + 1 }
}
"""


def test_a_collection_that_is_not_a_fixed_point_of_itself_is_not_skipped_after() -> None:
    program = compile_source(_UNSETTLING, "unsettling.bzz").to_bbo()
    assert _run(program.bbo, program.strings, PC, False, None) == \
        _run(program.bbo, program.strings, PC, True, None)


#: a nest deeper than the Kilobot's depth limit: the collector frees a table a global still
#: names, the slot is reused by a number that a global then holds, and the fast mode took that
#: number for the global's alone (freed when the global changed) while the stale word kept it
_TRUNCATING = """g = 0
i = 0
t = {.x = 1}
function helper(v) { var w = v t.h = w return w }
function init() {
  var a = 1 var b = 2 var c = 3 var f = nil
if (((not i) < (a and t.y))) { i = 0 while (i < 7) { g = (not t.n) i = i + 1 } } else { g = g }
}
function step() {
  var a = g var b = 1 var c = t var f = nil
b = {.x = function(p) { return p + 0 }, .y = 0}
g = function(p) { return p + 20420 }
b = 1024
c = 0
t.n = {.n = {.n = {.n = {.n = {.n = {.n = {.n = {.n = {.n = {.n = 1, .x = 2}, .x = 2}, .x = 2},
  .x = 2}, .x = 2}, .x = 2}, .x = 2}, .x = 2}, .x = 2}, .x = 2}
i = 0 while (i < 3) {
  if (((90 or c) - g)) { g = (i and (not t.y)) } else { c = ((t.n >= (i or 25356)) >= 153) }
  g = (((514 == 'a') and 817) ^ 3)
  g = {.x = b, .y = ((not t.h) <= 128)}
  c = {.x = 524, .y = (t.x - 64)}
  i = i + 1
}
}
"""


def test_a_heap_whose_collector_stopped_at_the_depth_limit_is_never_taken_for_settled() -> None:
    program = compile_source(_TRUNCATING, "truncating.bzz").to_bbo()
    assert _run(program.bbo, program.strings, KILOBOT, False, None) == \
        _run(program.bbo, program.strings, KILOBOT, True, None)


@pytest.mark.parametrize("source, profile, flag", [(_UNSETTLING, PC, 5),
                                                   (_TRUNCATING, KILOBOT, 6)],
                         ids=["unsettled", "truncated"])
def test_a_vm_restored_after_every_phase_goes_on_as_the_reference(source: str,
                                                                   profile: Profile,
                                                                   flag: int) -> None:
    """A VM replaced after every phase by one restored from its snapshot (a recording's
    keyframe, a debugger's checkpoint) goes on exactly as the reference, and the snapshots of
    these heaps hold their flag. (Whether the flags survive a restore is
    test_snapshot_layout's: here each call's first step collects, and both programs set
    their flag again at once.)"""
    program = compile_source(source, "flags.bzz").to_bbo()
    snapshots: list[bytes] = []
    assert _run(program.bbo, program.strings, profile, False, None, snapshots) == \
        _run(program.bbo, program.strings, profile, True, None)
    assert any(VM.decode_snapshot(snapshot)[0][flag] for snapshot in snapshots)
