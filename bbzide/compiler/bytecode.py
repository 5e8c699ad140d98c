"""Reading and validating bytecode files: `.bo` (Buzz), `.bbo` (BittyBuzz) and `.bdb` (debug).

Every reader here works on bytes, checks every length before it reads, and raises
`BytecodeError` with a one-line message naming the file and the byte offset when the input is
truncated or malformed (unknown opcode, a jump outside the code, more strings than bytes). The
writers (`assembler`, `bo2bbo`) produce files these readers accept; the disassembler, the VM
loader and `load_program` read through them.
"""

from __future__ import annotations

import struct
from dataclasses import dataclass

import bbzide.compiler.bbzfloat as bbzfloat
from bbzide.compiler.opcodes import ADDRESS_OPERAND_OPS, MNEMONICS, OPCODE_COUNT, Op, has_operand
from bbzide.diagnostics import BytecodeError, SourceLocation

#: `.bdb` record header: u32 offset, u64 line, u64 col, u16 file-name length (spec §B.8).
BDB_HEADER = struct.Struct("<IQQH")


@dataclass(frozen=True, slots=True)
class Instruction:
    """One decoded instruction: its file offset, opcode and raw operand (None when it has none)."""

    offset: int
    opcode: int
    operand: int | None
    size: int

    @property
    def mnemonic(self) -> str:
        return MNEMONICS[self.opcode]


@dataclass(frozen=True, slots=True)
class Bytecode:
    """A decoded `.bo` or `.bbo` file."""

    kind: str  # "bo" or "bbo"
    string_count: int
    strings: list[str]  # empty for a .bbo (it carries only the count)
    code_start: int
    instructions: list[Instruction]

    def by_offset(self) -> dict[int, Instruction]:
        return {instruction.offset: instruction for instruction in self.instructions}

    def operand_value(self, instruction: Instruction) -> int | float | None:
        """The operand as the VM reads it: signed ints, floats (float32 or bbzfloat), addresses."""
        operand = instruction.operand
        if operand is None:
            return None
        if self.kind == "bo":
            if instruction.opcode == Op.PUSHF:
                return struct.unpack("<f", struct.pack("<I", operand))[0]
            if instruction.opcode == Op.PUSHI:
                return operand - (1 << 32) if operand & 0x80000000 else operand
            return operand
        if instruction.opcode == Op.PUSHF:
            return bbzfloat.to_float(operand)
        if instruction.opcode == Op.PUSHI:
            return operand - (1 << 16) if operand & 0x8000 else operand
        return operand


def _error(name: str, offset: int, message: str) -> BytecodeError:
    return BytecodeError(f"{name}: offset {offset}: {message}")


def read_strings(data: bytes, name: str) -> tuple[int, list[str], int]:
    """The `.bo` string section: (count, strings, offset of the first instruction)."""
    if len(data) < 2:
        raise _error(name, 0, f"truncated: {len(data)} bytes, no string count")
    (count,) = struct.unpack_from("<H", data, 0)
    position = 2
    strings: list[str] = []
    for index in range(count):
        end = data.find(b"\0", position)
        if end < 0:
            raise _error(
                name,
                position,
                f"string count {count} larger than the file (string {index} has no end)",
            )
        strings.append(data[position:end].decode("utf-8", "surrogateescape"))
        position = end + 1
    return count, strings, position


def decode_instructions(data: bytes, start: int, operand_size: int, name: str) -> list[Instruction]:
    """Decode the code section from `start` to the end; checks opcodes and operand lengths."""
    instructions: list[Instruction] = []
    position = start
    size = len(data)
    fmt = "<I" if operand_size == 4 else "<H"
    while position < size:
        opcode = data[position]
        if opcode >= OPCODE_COUNT:
            raise _error(name, position, f"unknown opcode {opcode}")
        if has_operand(opcode):
            if position + 1 + operand_size > size:
                raise _error(name, position, f"truncated operand of {MNEMONICS[opcode]}")
            (operand,) = struct.unpack_from(fmt, data, position + 1)
            instructions.append(Instruction(position, opcode, operand, 1 + operand_size))
            position += 1 + operand_size
        else:
            instructions.append(Instruction(position, opcode, None, 1))
            position += 1
    starts = {instruction.offset for instruction in instructions}
    for instruction in instructions:
        if instruction.opcode in ADDRESS_OPERAND_OPS and instruction.opcode != Op.PUSHCC:
            if instruction.operand not in starts:
                raise _error(
                    name,
                    instruction.offset,
                    f"{instruction.mnemonic} target {instruction.operand} "
                    "is not an instruction in the code",
                )
    return instructions


def read_bo(data: bytes, name: str = "<bo>") -> Bytecode:
    """Decode and validate a `.bo` file (strings + code with 4-byte operands)."""
    count, strings, start = read_strings(data, name)
    instructions = decode_instructions(data, start, 4, name)
    return Bytecode("bo", count, strings, start, instructions)


def read_bbo(data: bytes, name: str = "<bbo>") -> Bytecode:
    """Decode and validate a `.bbo` file (string count + code with 2-byte operands, code at 2)."""
    if len(data) < 2:
        raise _error(name, 0, f"truncated: {len(data)} bytes, no string count")
    (count,) = struct.unpack_from("<H", data, 0)
    instructions = decode_instructions(data, 2, 2, name)
    return Bytecode("bbo", count, [], 2, instructions)


def read_bdb(data: bytes, name: str = "<bdb>") -> list[tuple[int, SourceLocation]]:
    """`.bdb` records in file order as (offset, SourceLocation); a truncated record is an error."""
    records: list[tuple[int, SourceLocation]] = []
    position = 0
    while position < len(data):
        if position + BDB_HEADER.size > len(data):
            raise _error(name, position, "truncated debug record header")
        offset, line, col, length = BDB_HEADER.unpack_from(data, position)
        position += BDB_HEADER.size
        if position + length > len(data):
            raise _error(name, position, f"truncated file name ({length} bytes announced)")
        file = data[position : position + length].decode("utf-8", "surrogateescape")
        position += length
        records.append((offset, SourceLocation(file, line, col)))
    return records
