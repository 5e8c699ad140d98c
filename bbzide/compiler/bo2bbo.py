"""`bo2bbo`: Buzz `.bo` bytecode -> BittyBuzz `.bbo` bytecode (spec §D.3).

The string section is dropped (only its count is kept), 4-byte operands shrink to 2 bytes:
`pushf` becomes a bbzfloat, integers keep their low 16 bits (a warning when the value is outside
int16, worded as the reference), code addresses are remapped to `.bbo` offsets (0 when the target
is not an instruction start, as the reference does). The result is byte-identical to the
reference tool.
"""

from __future__ import annotations

import struct
from dataclasses import dataclass

import bbzide.compiler.bbzfloat as bbzfloat
from bbzide.compiler.bytecode import read_strings
from bbzide.compiler.opcodes import OPCODE_COUNT, Op
from bbzide.diagnostics import BytecodeError

_INT16_OPS = frozenset({Op.PUSHI, Op.PUSHS, Op.LLOAD, Op.LSTORE, Op.LREMOVE})
_ADDRESS_OPS = frozenset({Op.PUSHCN, Op.PUSHCC, Op.PUSHL, Op.JUMP, Op.JUMPZ, Op.JUMPNZ})


@dataclass(slots=True)
class Conversion:
    """The `.bbo` bytes, the instruction offset map `.bo` -> `.bbo`, and bo2bbo's warnings."""

    bbo: bytes
    bo_to_bbo: dict[int, int]
    warnings: list[str]


def bo_to_bbo(bo: bytes, name: str = "<bo>") -> Conversion:
    """Convert `.bo` bytes; raises BytecodeError on a truncated or malformed `.bo`."""
    count, _strings, position = read_strings(bo, name)
    output = bytearray(struct.pack("<H", count))
    offsets: dict[int, int] = {}
    patches: list[tuple[int, int]] = []
    warnings: list[str] = []
    size = len(bo)
    while position < size:
        opcode = bo[position]
        offsets[position] = len(output)
        output.append(opcode)
        if opcode >= OPCODE_COUNT:
            raise BytecodeError(f"{name}: offset {position}: unknown opcode {opcode}")
        position += 1
        if opcode < Op.PUSHF:
            continue
        if position + 4 > size:
            raise BytecodeError(f"{name}: offset {position - 1}: truncated operand")
        raw = bo[position : position + 4]
        if opcode == Op.PUSHF:
            (bits,) = struct.unpack("<I", raw)
            output += struct.pack("<H", bbzfloat.from_float32_bits(bits))
        elif opcode in _INT16_OPS:
            (value,) = struct.unpack("<i", raw)
            if not -32768 <= value <= 32767:
                warnings.append(
                    f"Warning [{name}:{position}]: Integer (0x{value & 0xFFFFFFFF:08X}) "
                    f"at position "
                    f"{position} is out of 16 bit integer range. A part of the data will be lost."
                )
            output += struct.pack("<H", value & 0xFFFF)
        else:
            (address,) = struct.unpack("<I", raw)
            patches.append((len(output), address))
            output += struct.pack("<H", address & 0xFFFF)
        position += 4
    if len(output) > 0xFFFF:
        # Not a reference warning: bo2bbo silently wraps addresses beyond 16 bits.
        warnings.append(
            f"Warning [{name}]: the .bbo is {len(output)} bytes; "
            "BittyBuzz code addresses are 16-bit, "
            "so jumps beyond offset 65535 wrap and the program cannot run"
        )
    for at, address in patches:
        output[at : at + 2] = struct.pack("<H", offsets.get(address, 0) & 0xFFFF)
    return Conversion(bytes(output), offsets, warnings)
