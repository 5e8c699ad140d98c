"""Semantic quirks of the BittyBuzz instruction set (spec §D.6), on hand-assembled code."""

from __future__ import annotations

import struct

from bbzide.compiler.opcodes import Op
from bbzide.vm import inspector
from bbzide.vm.profiles import KILOBOT, PC
from bbzide.vm.vm import VM, State


def _asm(*items: tuple[int, int] | int) -> bytes:
    """2-byte header, nop (end of preamble), then the instructions, then done."""
    out = bytearray(b"\x00\x00") + bytes([Op.NOP])
    for it in items:
        if isinstance(it, tuple):
            out += bytes([it[0]]) + struct.pack("<H", it[1] & 0xFFFF)
        else:
            out.append(it)
    out.append(Op.DONE)
    return bytes(out)


def _top_int(vm: VM) -> int:
    return vm.heap.int_value(vm.stack[vm.stackptr])


def _run(code: bytes, profile=PC) -> VM:  # noqa: ANN001
    vm = VM(profile)
    vm.construct()
    vm.set_bcode(code)
    vm.run(max_instructions=1000)
    return vm


def test_int16_wraps() -> None:
    vm = _run(_asm((Op.PUSHI, 32767), (Op.PUSHI, 1), Op.ADD))
    assert vm.state == State.DONE and _top_int(vm) == -32768


def test_lnot_returns_truth_value() -> None:
    assert _top_int(_run(_asm((Op.PUSHI, 5), Op.LNOT))) == 1
    assert _top_int(_run(_asm((Op.PUSHI, 0), Op.LNOT))) == 0


def test_band_bor_are_logical() -> None:
    assert _top_int(_run(_asm((Op.PUSHI, 6), (Op.PUSHI, 3), Op.BAND))) == 1
    assert _top_int(_run(_asm((Op.PUSHI, 4), (Op.PUSHI, 1), Op.BOR))) == 1


def test_c_remainder_and_truncating_division() -> None:
    assert _top_int(_run(_asm((Op.PUSHI, -7), (Op.PUSHI, 3), Op.MOD))) == -1
    assert _top_int(_run(_asm((Op.PUSHI, -7), (Op.PUSHI, 2), Op.DIV))) == -3


def test_float_arith_is_type_error_on_kilobot_at_the_failing_pc() -> None:
    vm = _run(_asm((Op.PUSHF, 0x3E00), (Op.PUSHI, 1), Op.ADD), KILOBOT)
    assert vm.state == State.ERROR and vm.error.name == "TYPE" and vm.pc == 9


def test_shift_is_instr_error() -> None:
    vm = _run(_asm((Op.PUSHI, 1), (Op.PUSHI, 1), Op.LSHIFT))
    assert vm.error.name == "INSTR" and vm.pc == 9


def test_jumpz_on_string_is_type_error() -> None:
    vm = _run(_asm((Op.PUSHS, 3), (Op.JUMPZ, 3)))
    assert vm.error.name == "TYPE"


def test_truncated_operand_is_pc_error() -> None:
    vm = VM(PC)
    vm.construct()
    vm.set_bcode(b"\x00\x00\x00" + bytes([Op.PUSHI, 1]))
    vm.run(max_instructions=10)
    assert vm.state == State.ERROR and vm.error.name == "PC" and vm.pc == 3


def test_instruction_budget_stops_infinite_loop() -> None:
    vm = _run(_asm((Op.JUMP, 3)))
    assert vm.state == State.ERROR and vm.error.name == "BUDGET"


def test_inspector_views_after_construct() -> None:
    vm = VM(PC)
    vm.construct()
    mem = inspector.memory(vm)
    assert mem.rightmost_object_ptr == 666 and mem.leftmost_segment_ptr == 3000  # spec §E.11
    assert mem.objects[28].type == "nil" and mem.objects[28].permanent
    names = (["id", "swarm", "create"] + [f"s{i}" for i in range(3, 46)])
    names[17], names[32], names[18], names[35] = "neighbors", "stigmergy", "foreach", "size"
    names[28], names[19], names[20] = "filter", "map", "reduce"
    assert set(inspector.globals_by_name(vm, names)) == {
        "id", "stigmergy", "swarm", "neighbors", "foreach", "filter", "map", "reduce", "size"}
    assert inspector.last_error(vm) is None
