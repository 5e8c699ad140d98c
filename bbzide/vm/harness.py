"""The corpus run loop (``bbzharness-pc`` / ``bbzavr.py``, conformance README §1 "Run loop"):
one :class:`~bbzide.vm.robot.Robot` driven like the reference harnesses, writing the
``#BBZDUMP 1`` text, so every harness line of ``bbz/*.cmd`` can be replayed on the model and
diffed with the reference dump.

    header (config, input, reg lines)
    construct+set_bcode → dump · --reg closures → dump "setup" · top level → dump "script"
    · init → dump "init" · per step s: injections of s, process_inmsgs, step,
    process_outmsgs, drain (``outmsg`` lines) → dump "step s" · ``finished`` | ``halt``

The host closures are the harness kinds (``print``/``log``, ``ret0``, ``ret0/N``,
``retnil``, ``rand``, ``min``, ``reti:V``) written as ordinary host functions on
:class:`~bbzide.vm.host.HostCall`; their C symbols (``h_print`` ...) give the PC addresses
of ``pc_cfunctions.tsv``, so PC heaps match byte for byte. Injections are applied the way
the harness does: a ``bc`` with a position (and an ``nb``) feeds ``bbzneighbors_add`` first;
``bc``/``vput``/``vquery`` become wire payloads queued with ``bbzinmsg_queue_append``.
The harness runs Buzz code without an instruction budget (as the reference does) unless
one is given.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from bbzide.compiler import bbzfloat
from bbzide.compiler.program import BittyBuzzProgram
from bbzide.vm import messages, neighbors
from bbzide.vm.dump import dump_block, format_value, header_lines
from bbzide.vm.harness_options import HostKind, Registration
from bbzide.vm.host import LIBRARY_ADDRESSES, HostCall
from bbzide.vm.injections import Injection, InjectionError
from bbzide.vm.profiles import Profile
from bbzide.vm.robot import Robot
from bbzide.vm.tables import compare
from bbzide.vm.vm import VM, Error, State

#: mdata of an injected object: its type with the valid bit (the receiver forces valid on)
_VALID = 0x08
_VALUE_TYPES = {"nil": 0, "int": 1, "float": 2, "string": 3}

#: the rand kind's LCG (README §1: x = x * 1103515245 + 12345, 32-bit; returns bits 16-30)
_LCG_A, _LCG_C = 1103515245, 12345


@dataclass
class HarnessRun:
    """The dump text lines and the harness exit status (0 finished, 1 halt)."""

    lines: list[str]
    status: int
    robot: Robot


def kind_symbol(kind: HostKind) -> str:
    """The C symbol of the reference harness function implementing ``kind``."""
    if kind.name in ("print", "log"):
        return "h_print"
    if kind.name == "ret0":
        return "h_ret0" if kind.parameter is None else f"h_ret0_a{kind.parameter}"
    return f"h_{kind.name}"


def kind_function(kind: HostKind, events: list[str], strings: list[str],
                  seed: int, registered_as: str = "") -> Callable[[HostCall], None]:
    """A host function behaving like the harness kind (README §1 "--reg NAME=KIND");
    `registered_as`: the global name, which the ``trace`` kind prints."""
    name, param = kind.name, kind.parameter
    if name == "trace":
        def trace(call: HostCall) -> None:
            vm = call.vm
            args = [format_value(vm, call.arg_index(i), strings)
                    for i in range(1, call.arg_count + 1)]
            events.append(f"out {registered_as}({', '.join(args)})")
        return trace
    if name == "abs":
        def absolute(call: HostCall) -> None:
            if call.expect_args(1):
                call.ret(abs(call.vm.heap.int_value(call.arg_index(1))))
        return absolute
    if name in ("print", "log"):
        def print_(call: HostCall) -> None:
            vm = call.vm
            args = [format_value(vm, call.arg_index(i), strings)
                    for i in range(1, call.arg_count + 1)]
            events.append(" ".join(["out", *args]))
        return print_
    if name == "ret0":
        if param is None:
            return lambda call: None

        def ret0n(call: HostCall) -> None:
            call.expect_args(param)
        return ret0n
    if name == "retnil":
        return lambda call: call.ret(None)
    if name == "reti":
        value = param or 0
        return lambda call: call.ret(value)
    if name == "rand":
        state = {"x": seed & 0xFFFFFFFF}

        def rand(call: HostCall) -> None:
            state["x"] = (state["x"] * _LCG_A + _LCG_C) & 0xFFFFFFFF
            call.ret((state["x"] >> 16) & 0x7FFF)
        return rand
    if name == "min":
        def minimum(call: HostCall) -> None:
            if not call.expect_args(2):
                return
            a, b = call.arg_index(1), call.arg_index(2)
            call.ret_object(b if compare(call.vm.heap, b, a) < 0 else a)
        return minimum
    raise ValueError(f"unknown host kind {name!r}")


def _host_table(registrations: list[Registration], events: list[str], strings: list[str],
                seed: int) -> tuple[dict[str, Callable[[HostCall], None]], dict[str, str],
                                    list[tuple[str, HostKind]]]:
    functions: dict[str, Callable[[HostCall], None]] = {}
    symbols: dict[str, str] = {}
    flat: list[tuple[str, HostKind]] = []
    for reg in registrations:
        pairs = [(reg.name, reg.kind)] if reg.kind is not None else \
            [(f"{reg.name}.{f}", k) for f, k in reg.fields]
        for name, kind in pairs:
            functions[name] = kind_function(kind, events, strings, seed, name)
            symbols[name] = kind_symbol(kind)
            flat.append((name, kind))
    return functions, symbols, flat


def _kind_text(kind: HostKind) -> str:
    if kind.parameter is None:
        return kind.name
    return f"ret0/{kind.parameter}" if kind.name == "ret0" else f"{kind.name}:{kind.parameter}"


def _object_bytes(inj: Injection, program: BittyBuzzProgram) -> tuple[int, int]:
    """(mdata, u16 value) of an injected value."""
    assert inj.value is not None
    t = inj.value.type_name
    text = inj.value.text
    try:
        if t == "int":
            v = int(text) & 0xFFFF
        elif t == "float":
            v = bbzfloat.from_float(float(text))
        elif t == "string":
            sid = program.string_id(text)
            if sid is None:
                raise InjectionError(f"{inj.line}: string {text!r} is not in the string table")
            v = sid
        else:
            v = 0
    except ValueError:
        raise InjectionError(f"{inj.line}: bad {t} value {text!r}") from None
    return _VALUE_TYPES[t] | _VALID, v


def injection_payload(inj: Injection, program: BittyBuzzProgram) -> bytes | None:
    """The wire payload of a ``bc``/``vput``/``vquery`` injection (None for ``nb``)."""
    if inj.kind == "nb":
        return None
    name = inj.topic or ""
    sid = program.string_id(name)
    if sid is None:
        raise InjectionError(f"{inj.line}: {name!r} is not in the string table")
    mdata, value = _object_bytes(inj, program)
    rid = inj.robot & 0xFFFF
    head = bytes([0 if inj.kind == "bc" else (1 if inj.kind == "vput" else 2),
                  rid & 0xFF, rid >> 8, sid & 0xFF, sid >> 8, mdata, value & 0xFF, value >> 8])
    if inj.kind == "bc":
        return head
    return head + bytes([inj.lamport or 0])


def neighbor_entry(profile: Profile, rid: int, distance: float, azimuth: float,
                   elevation: float) -> neighbors.NeighborEntry:
    """The harness's element: bbzfloat on float builds, else the C cast to uint8 (wraps)."""
    def conv(x: float) -> int:
        return bbzfloat.from_float(x) if profile.neighbors_floats else int(x) & 0xFF

    return neighbors.NeighborEntry(rid & 0xFFFF, conv(distance), conv(azimuth),
                                   conv(elevation))


def apply_injection(robot: Robot, inj: Injection) -> None:
    vm = robot.vm
    payload = injection_payload(inj, robot.program)
    if inj.position is not None:
        p = inj.position
        neighbors.add(vm, neighbor_entry(robot.profile, inj.robot, p.distance, p.azimuth,
                                         p.elevation))
    if payload is not None:
        messages.inmsg_append(vm.queues, payload)


def run_harness(program: BittyBuzzProgram, profile: Profile, *, robot_id: int, steps: int,
                seed: int, loop: str, registrations: list[Registration],
                injections: list[Injection], bbo_name: str = "script.bbo",
                bo_name: str = "script.bo", instruction_budget: int | None = None,
                stress_gc: bool = False, avr_style: bool | None = None) -> HarnessRun:
    """Run one harness invocation; returns the dump lines and the exit status."""
    events: list[str] = []
    lines: list[str] = []
    functions, symbols, flat = _host_table(registrations, events, program.strings, seed)
    robot = Robot(program, profile, robot_id, functions, loop=loop,
                  instruction_budget=instruction_budget, host_symbols=symbols,
                  stress_gc=stress_gc)
    vm = robot.vm
    avr = (profile.ptr_size == 2) if avr_style is None else avr_style
    nstrings = int.from_bytes(program.bbo[:2], "little") if len(program.bbo) >= 2 else 0
    lines += header_lines(profile, bbo_name, len(program.bbo), bo_name, nstrings, robot_id,
                          steps, loop)
    mask = (1 << (8 * profile.ptr_size)) - 1
    for name, kind in flat:
        address = LIBRARY_ADDRESSES.get(kind_symbol(kind), 0) & mask
        shown = f"{address:04x}" if avr else f"{address:x}"
        lines.append(f"reg {name} {_kind_text(kind)} {shown}")

    def on_error(_vm: VM, code: Error) -> None:
        events.append(f"error {code.name} pc={_vm.pc}")

    vm.error_receiver = on_error
    counter = [0]

    def dump(label: str) -> None:
        counter[0] += 1
        lines.extend(events)
        events.clear()
        lines.extend(dump_block(vm, counter[0], label))

    def on_phase(label: str) -> None:
        if label == "init" and not robot.init_defined:
            events.append("note no init")
        dump(label)

    robot.on_phase = on_phase
    robot.boot()
    if _stopped(robot, lines):
        return HarnessRun(lines, 1, robot)
    by_step: dict[int, list[tuple[int, Injection]]] = {}
    for k, inj in enumerate(injections):
        by_step.setdefault(inj.step, []).append((k, inj))
    for s in range(1, steps + 1):
        for k, inj in by_step.get(s, []):
            events.append(f"inject {s} #{k}" if avr else f"inject {inj.line}")
            apply_injection(robot, inj)
        sent = robot.control_step()
        events.extend(f"outmsg {m.hex()}" for m in sent)
        dump(f"step {s}")
        if _stopped(robot, lines):
            return HarnessRun(lines, 1, robot)
    lines.extend(events)
    lines.append("finished")
    return HarnessRun(lines, 0, robot)


def _stopped(robot: Robot, lines: list[str]) -> bool:
    if robot.vm.state == State.ERROR or robot.failure is not None:
        if robot.failure is not None and robot.failure.reason == "HOST":
            lines.append(f"note {robot.failure.message}")
        lines.append("halt")
        return True
    return False


def run_command_line(argv: list[str], base: Path, profile: Profile,
                     stress_gc: bool = False) -> HarnessRun:
    """Run one harness command line (``bbzharness-pc``/``bbzavr.py`` arguments, without the
    program name and output redirection); relative paths are taken from ``base``. The
    ``.bbo`` needs its ``.bo`` beside it (string names) and uses its ``.bdb`` when present."""
    from bbzide.compiler import load_program
    from bbzide.vm.harness_options import parse_harness_arguments
    from bbzide.vm.injections import parse_injection_file

    options = parse_harness_arguments(argv, base)
    bbo = options.bytecode
    bo = bbo.with_suffix(".bo")
    bdb = bbo.with_suffix(".bdb")
    program = load_program(bbo, bo=bo if bo.exists() else None,
                           bdb=bdb if bdb.exists() else None)
    injections = parse_injection_file(options.inject) if options.inject else []
    return run_harness(program, profile, robot_id=options.robot, steps=options.steps,
                       seed=options.seed, loop=options.loop,
                       registrations=options.registrations, injections=injections,
                       bbo_name=bbo.name, bo_name=bo.name, stress_gc=stress_gc)
