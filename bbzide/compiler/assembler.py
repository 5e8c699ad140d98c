"""The assembler: `.basm` text -> `.bo` bytecode + `.bdb` debug records, as the reference `bzzasm`.

Design: one pass over the lines builds the output bytes and remembers every label reference
(position, label name, line); a second pass patches those references with the label offsets
(spec §B.6). The input is handled as bytes so that string lines are copied exactly (the reference
works on raw `char`s). Quirks reproduced on purpose, because the `.bo` must be byte-identical:

* a string line (`'...`) loses its last character (assumed LF, even if it is not one);
* numeric operands follow C `strtoul(s, NULL, 10)` (sign accepted, wraps, low 32 bits) and
  `strtof` (longest numeric prefix); a number that consumes nothing is a label name;
* debug info belongs to the offset of the opcode byte, or for a label line to the next offset;
  a later record for the same offset replaces the earlier one.

The `.bdb` records are ordered like Buzz's 100-bucket hash table iterates: (offset % 100, offset)
(spec §B.8).
"""

from __future__ import annotations

import math
import re
import struct
from dataclasses import dataclass, field

from bbzide.compiler.opcodes import OPCODE_BY_MNEMONIC, Op, has_operand
from bbzide.diagnostics import CompileError, SourceLocation

#: Buzz's debug table has 100 buckets (`buzzdebug.c`): the `.bdb` record order depends on it.
DEBUG_HASH_BUCKETS = 100

_WHITESPACE = b" \t\n\v\f\r"
_SEPARATORS = re.compile(rb"[ \t\n]")
_INTEGER_PREFIX = re.compile(rb"[ \t\n\v\f\r]*([+-]?)([0-9]+)")
_FLOAT_PREFIX = re.compile(
    rb"[ \t\n\v\f\r]*([+-]?)("
    rb"0[xX](?:[0-9a-fA-F]+\.?[0-9a-fA-F]*|\.[0-9a-fA-F]+)(?:[pP][+-]?[0-9]+)?"
    rb"|(?:[0-9]+\.?[0-9]*|\.[0-9]+)(?:[eE][+-]?[0-9]+)?"
    rb"|[iI][nN][fF](?:[iI][nN][iI][tT][yY])?"
    rb"|[nN][aA][nN](?:\([0-9A-Za-z_]*\))?"
    rb")"
)
_JUMP_OPS = frozenset({Op.JUMP, Op.JUMPZ, Op.JUMPNZ})


@dataclass(frozen=True, slots=True)
class DebugRecord:
    """One `.bdb` record: a code offset and the source position it came from."""

    offset: int
    line: int
    col: int
    file: bytes


@dataclass(slots=True)
class Assembly:
    """What the assembler produces: the `.bo` bytes, the `.bdb` records and its warnings."""

    bo: bytes
    debug_records: list[DebugRecord]
    labels: dict[bytes, int]
    warnings: list[str] = field(default_factory=list)

    @property
    def bdb(self) -> bytes:
        return encode_bdb(self.debug_records)


def strtoul32(text: bytes) -> tuple[int, bool]:
    """C `strtoul(text, &end, 10)` truncated to 32 bits; returns (value, consumed anything)."""
    if text.isdigit() and len(text) < 20:  # fast path: the common plain decimal operand
        return int(text) & 0xFFFFFFFF, True
    match = _INTEGER_PREFIX.match(text)
    if match is None:
        return 0, False
    magnitude = int(match.group(2))
    if magnitude > 0xFFFFFFFFFFFFFFFF:  # strtoul saturates at ULONG_MAX (64-bit long)
        return 0xFFFFFFFF, True
    value = -magnitude if match.group(1) == b"-" else magnitude
    return value & 0xFFFFFFFF, True


def strtof32(text: bytes) -> tuple[bytes, bool]:
    """C `strtof(text, &end)` as float32 little-endian bytes; returns (bytes, consumed anything)."""
    match = _FLOAT_PREFIX.match(text)
    if match is None:
        return b"\0\0\0\0", False
    sign, body = match.group(1), match.group(2).lower()
    if body.startswith(b"inf"):
        value = math.inf
    elif body.startswith(b"nan"):
        value = math.nan
    elif body.startswith(b"0x"):
        mantissa, _, exponent = body[2:].partition(b"p")
        whole, _, fraction = mantissa.partition(b".")
        digits = (whole + fraction) or b"0"
        value = int(digits, 16) * 2.0 ** (int(exponent or b"0") - 4 * len(fraction))
    else:
        value = float(body)
    if sign == b"-":
        value = -value
    try:
        return struct.pack("<f", value), True
    except OverflowError:  # strtof returns HUGE_VALF beyond float32's range
        return struct.pack("<f", math.copysign(math.inf, value)), True


def _decode(text: bytes) -> str:
    return text.decode("utf-8", "surrogateescape")


def assemble(basm: bytes | str, filename: str = "<basm>") -> Assembly:
    """Assemble `.basm` text into `.bo` bytes and debug records (bzzasm). Raises CompileError."""
    if isinstance(basm, str):
        basm = basm.encode("utf-8", "surrogateescape")
    output = bytearray()
    labels: dict[bytes, int] = {}
    references: list[tuple[int, bytes, int]] = []  # (operand position, label, basm line)
    debug: dict[int, tuple[int, int, bytes]] = {}
    warnings: list[str] = []
    opcode_by_name = {name.encode(): number for name, number in OPCODE_BY_MNEMONIC.items()}

    def fail(line_number: int, message: str) -> CompileError:
        error = CompileError(message, SourceLocation(filename, line_number, 0))
        error.reference_message = f"ERROR: {filename}:{line_number} {message}"  # type: ignore[attr-defined]
        return error

    def record_debug(offset: int, info: bytes) -> None:
        fields = info.split(b",")
        if len(fields) < 3:
            return
        line_text, col_text = fields[0], fields[1]
        line_value = int(line_text) if line_text.isdigit() else strtoul32(line_text)[0]
        col_value = int(col_text) if col_text.isdigit() else strtoul32(col_text)[0]
        debug[offset] = (line_value, col_value, fields[2])

    lines = basm.split(b"\n")
    if lines and lines[-1] == b"":
        lines.pop()
        ends_with_newline = True
    else:
        ends_with_newline = False
    last_index = len(lines) - 1
    for index, raw in enumerate(lines):
        line_number = index + 1
        line = raw.lstrip(_WHITESPACE)
        if not line or line[:1] == b"#":
            continue
        first = line[:1]
        if first == b"'":
            # The reference drops the last character of the line as read by getline (with LF).
            if index == last_index and not ends_with_newline:
                output += line[1:-1] + b"\0"
            else:
                output += line[1:] + b"\0"
            continue
        line = line.rstrip(_WHITESPACE)
        if first == b"!":
            count, _ = strtoul32(line[1:])
            output += struct.pack("<H", count & 0xFFFF)
            continue
        code, bar, info = line.partition(b"|")
        if first == b"@":
            labels[code.rstrip(b" \t")] = len(output)
            if bar:
                record_debug(len(output), info)
            continue
        fields = _SEPARATORS.split(code)
        name = fields[0]
        argument = fields[1] if len(fields) > 1 else None
        opcode = opcode_by_name.get(name)
        if opcode is None:
            raise fail(line_number, f'unknown instruction "{_decode(name)}"')
        if bar:
            record_debug(len(output), info)
        output.append(opcode)
        if not has_operand(opcode):
            if argument:
                warnings.append(
                    f'WARNING: {filename}:{line_number} ignored argument "{_decode(argument)}"'
                )
            continue
        if not argument:
            raise fail(line_number, "missing argument")
        if opcode in _JUMP_OPS:
            references.append((len(output), argument, line_number))
            output += b"\0\0\0\0"
        elif opcode == Op.PUSHF:
            encoded, consumed = strtof32(argument)
            if not consumed:
                references.append((len(output), argument, line_number))
            output += encoded
        else:
            value, consumed = strtoul32(argument)
            if not consumed:
                references.append((len(output), argument, line_number))
            output += struct.pack("<I", value)
    size = len(output)
    for position, label, line_number in references:
        target = labels.get(label)
        if target is None:
            raise _pass2_error(filename, line_number, f'unknown label "{_decode(label)}"')
        if target >= size:
            raise _pass2_error(
                filename, line_number, f'label "{_decode(label)}" is beyond the bytecode size'
            )
        output[position : position + 4] = struct.pack("<I", target)
    records = [DebugRecord(offset, line, col, file) for offset, (line, col, file) in debug.items()]
    records.sort(key=lambda record: (record.offset % DEBUG_HASH_BUCKETS, record.offset))
    return Assembly(bytes(output), records, labels, warnings)


def _pass2_error(filename: str, line_number: int, message: str) -> CompileError:
    """Pass-2 errors: the reference names only the file (`ERROR: F: ...`); we add the line."""
    error = CompileError(message, SourceLocation(filename, line_number, 0))
    error.reference_message = f"ERROR: {filename}: {message}"  # type: ignore[attr-defined]
    return error


def encode_bdb(records: list[DebugRecord]) -> bytes:
    """`.bdb` bytes: u32 offset, u64 line, u64 col, u16 length, file name (in the given order)."""
    parts = []
    for record in records:
        parts.append(
            struct.pack("<IQQH", record.offset, record.line, record.col, len(record.file))
            + record.file
        )
    return b"".join(parts)
