"""Call sites and script symbols kept beside the bytecode: every `callc` of the `.bo` gets the
call as written at its own line and column, the `.bo`/`.bdb` bytes stay the reference's, and
the global lint finds what is read but never defined."""

from __future__ import annotations

from pathlib import Path

from bbzide.compiler import bittybuzz_string_table, compile_source
from bbzide.compiler.bytecode import read_bbo, read_bo
from bbzide.compiler.call_sites import (
    CallSite,
    ScriptSymbols,
    explain_failed_call,
    undefined_global_message,
    undefined_globals,
)
from bbzide.compiler.opcodes import Op
from bbzide.diagnostics import SourceLocation

SCRIPT = """\
var t = {}
function helper(a) {
  return a
}
function step() {
  t.f = function(v) { return helper(v) }
  t.f(helper(1))
  g = t[1]
  neighbors.broadcast("k", 1)
  helper(2)(3)
  log(math.max(1, 2))
}
"""


def _compile(text: str, tmp_path: Path):  # noqa: ANN202 - a CompiledProgram
    return compile_source(text, str(tmp_path / "s.bzz"),
                          string_table=bittybuzz_string_table(["log"]))


def test_each_callc_has_the_call_as_written_at_its_first_token(tmp_path: Path) -> None:
    compiled = _compile(SCRIPT, tmp_path)
    instructions = read_bo(compiled.bo).by_offset()
    assert all(instructions[offset].opcode == Op.CALLC for offset in compiled.call_sites)
    callc_count = sum(1 for i in instructions.values() if i.opcode == Op.CALLC)
    assert len(compiled.call_sites) == callc_count
    found = sorted((s.location.line, s.location.col, s.callee, s.global_name)
                   for s in compiled.call_sites.values())
    assert found == [
        (6, 29, "helper", "helper"),              # inside the lambda's own code chunk
        (7, 2, "t.f", None),
        (7, 6, "helper", "helper"),
        (9, 2, "neighbors.broadcast", None),
        (10, 2, "helper", "helper"),
        (10, 2, "helper(…)", None),               # the chained call
        (11, 2, "log", "log"),
        (11, 6, "math.max", None),
    ]


def test_the_bbo_keeps_the_call_sites_at_its_own_offsets(tmp_path: Path) -> None:
    compiled = _compile(SCRIPT, tmp_path)
    program = compiled.to_bbo()
    bbo = read_bbo(program.bbo).by_offset()
    assert sorted(program.call_sites.values(), key=str) == \
        sorted(compiled.call_sites.values(), key=str)
    assert all(bbo[offset].opcode == Op.CALLC for offset in program.call_sites)


def test_symbols_are_what_the_script_defines_and_reads(tmp_path: Path) -> None:
    symbols = _compile(SCRIPT + "function init() { x = y + 1 }\n", tmp_path).symbols
    assert symbols.defined == {"t", "helper", "step", "g", "init", "x"}
    assert set(symbols.first_reads) == {"t", "helper", "neighbors", "log", "math", "y"}
    assert symbols.first_reads["y"].line == 13 and symbols.first_reads["y"].col == 22


def test_undefined_globals_exclude_the_vm_and_the_platform(tmp_path: Path) -> None:
    symbols = _compile(SCRIPT, tmp_path).symbols
    assert [name for name, _ in undefined_globals(symbols, ["log"])] == ["math"]
    assert [name for name, _ in undefined_globals(symbols, ["log", "math"])] == []
    message = undefined_global_message("lgo", ScriptSymbols({"step"}), ["log", "led"],
                                       "the Kilobot")
    assert message.startswith("`lgo` is never defined")
    assert "Known names: `log`, " in message   # the close match first


def test_explanations_tell_nil_from_a_wrong_value() -> None:
    where = SourceLocation("s.bzz", 3, 2)
    assert explain_failed_call(CallSite(where, "nosuchfunction", "nosuchfunction"), set(),
                               ["led"], "the Kilobot") == (
        "`nosuchfunction` is nil here: it is not defined, and no host function of the Kilobot "
        "has that name")
    assert "did you mean `led`" in explain_failed_call(CallSite(where, "lde", "lde"), set(),
                                                       ["led"], "the Kilobot")
    assert explain_failed_call(CallSite(where, "t.f", None), set(), [], "the Kilobot") == \
        "`t.f` is not a function here, so it cannot be called"
    assert "defines it, but as another value" in explain_failed_call(
        CallSite(where, "speed", "speed"), {"speed"}, [], "the Kilobot")
