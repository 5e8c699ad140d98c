"""The Buzz instruction set, shared by the assembler, `bo2bbo`, the disassembler and the VM.

Buzz (`.bo`) and BittyBuzz (`.bbo`) use the same opcode numbers 0..46; they differ only in
operand width: an opcode >= 35 carries a 4-byte little-endian operand in a `.bo` and a 2-byte
one in a `.bbo` (spec §B.7, §D.3, §D.5). This module is the one place that lists them.
"""

from __future__ import annotations

from enum import IntEnum


class Op(IntEnum):
    """Opcode numbers, as in the reference `buzzvm.h` / `bbzenums.h`."""

    NOP = 0
    DONE = 1
    PUSHNIL = 2
    DUP = 3
    POP = 4
    RET0 = 5
    RET1 = 6
    ADD = 7
    SUB = 8
    MUL = 9
    DIV = 10
    MOD = 11
    POW = 12
    UNM = 13
    LAND = 14
    LOR = 15
    LNOT = 16
    BAND = 17
    BOR = 18
    BNOT = 19
    LSHIFT = 20
    RSHIFT = 21
    EQ = 22
    NEQ = 23
    GT = 24
    GTE = 25
    LT = 26
    LTE = 27
    GLOAD = 28
    GSTORE = 29
    PUSHT = 30
    TPUT = 31
    TGET = 32
    CALLC = 33
    CALLS = 34
    PUSHF = 35
    PUSHI = 36
    PUSHS = 37
    PUSHCN = 38
    PUSHCC = 39
    PUSHL = 40
    LLOAD = 41
    LSTORE = 42
    LREMOVE = 43
    JUMP = 44
    JUMPZ = 45
    JUMPNZ = 46


#: Opcodes from this number on carry an operand (4 bytes in `.bo`, 2 bytes in `.bbo`).
FIRST_OP_WITH_OPERAND = 35
#: One past the last defined opcode.
OPCODE_COUNT = 47

#: Assembly mnemonic of every opcode, indexed by number (`.basm` spelling, lower case).
MNEMONICS: tuple[str, ...] = tuple(op.name.lower() for op in Op)
#: Mnemonic -> opcode number.
OPCODE_BY_MNEMONIC: dict[str, int] = {name: number for number, name in enumerate(MNEMONICS)}

#: Operand width in a `.bo` file (int32 or float32) and in a `.bbo` file (int16 or bbzfloat).
BO_OPERAND_SIZE = 4
BBO_OPERAND_SIZE = 2

#: Operands that are code addresses (remapped by `bo2bbo`, labels in `.basm`).
ADDRESS_OPERAND_OPS = frozenset({Op.PUSHCN, Op.PUSHCC, Op.PUSHL, Op.JUMP, Op.JUMPZ, Op.JUMPNZ})
#: Operands that `bo2bbo` truncates to their low 16 bits (warning outside int16).
INTEGER_OPERAND_OPS = frozenset({Op.PUSHI, Op.PUSHS, Op.LLOAD, Op.LSTORE, Op.LREMOVE})


def has_operand(opcode: int) -> bool:
    """True when `opcode` is followed by an operand."""
    return opcode >= FIRST_OP_WITH_OPERAND
