"""Disassembler: a `.bo` or `.bbo` as a readable listing.

One line per instruction: offset, mnemonic, decoded operand (floats as numbers — bbzfloat for a
`.bbo` —, string ids with their text when the string table is known, jump and closure targets),
then the source position and, when the source file is readable, the source line itself. The
format follows `bzzdeasm` (`OFFSET: mnemonic arg | line,col,file`, spec §B.8) with more decoding.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path

from bbzide.compiler.bytecode import Bytecode, Instruction
from bbzide.compiler.opcodes import ADDRESS_OPERAND_OPS, Op
from bbzide.diagnostics import SourceLocation


def _operand_text(code: Bytecode, instruction: Instruction, strings: Sequence[str]) -> str:
    value = code.operand_value(instruction)
    if value is None:
        return ""
    if instruction.opcode == Op.PUSHF:
        return f"{value:g}"
    if instruction.opcode == Op.PUSHS:
        if 0 <= int(value) < len(strings):
            return f"{value}  ; {strings[int(value)]!r}"
        return str(value)
    if instruction.opcode in ADDRESS_OPERAND_OPS:
        return f"-> {value}"
    return str(value)


class _SourceCache:
    def __init__(self) -> None:
        self.files: dict[str, list[str] | None] = {}

    def line(self, location: SourceLocation) -> str | None:
        if location.file not in self.files:
            try:
                self.files[location.file] = (
                    Path(location.file).read_text(errors="replace").splitlines()
                )
            except OSError:
                self.files[location.file] = None
        lines = self.files[location.file]
        if lines is None or not 1 <= location.line <= len(lines):
            return None
        return lines[location.line - 1].strip()


def disassemble(
    code: Bytecode,
    strings: Sequence[str] = (),
    debug_map: Mapping[int, SourceLocation] | None = None,
    show_source: bool = False,
) -> str:
    """The listing of a decoded `.bo`/`.bbo` (see the module docstring)."""
    strings = strings or code.strings
    out = [f"; {code.kind} file, {code.string_count} strings, code at offset {code.code_start}"]
    for index, text in enumerate(code.strings):
        out.append(f"; string {index}: {text!r}")
    sources = _SourceCache()
    previous_line: tuple[str, int] | None = None
    for instruction in code.instructions:
        operand = _operand_text(code, instruction, strings)
        text = f"{instruction.offset:6d}: {instruction.mnemonic:8s} {operand}"
        location = debug_map.get(instruction.offset) if debug_map else None
        if location is not None:
            text = f"{text:40s} | {location.line},{location.col},{location.file}"
            if show_source and (location.file, location.line) != previous_line:
                source = sources.line(location)
                if source is not None:
                    out.append(f"        ; {location.line}: {source}")
                previous_line = (location.file, location.line)
        out.append(text.rstrip())
    return "\n".join(out) + "\n"


def function_names(code: Bytecode, strings: Sequence[str] = ()) -> dict[int, str]:
    """The program's named functions by the pc of their code: the prologue registers each one
    as `pushs NAME / pushcn PC / gstore`, which is what a closure's payload then holds."""
    strings = strings or code.strings
    names: dict[int, str] = {}
    steps = code.instructions
    for first, second, third in zip(steps, steps[1:], steps[2:], strict=False):
        if (first.opcode, second.opcode, third.opcode) != (Op.PUSHS, Op.PUSHCN, Op.GSTORE):
            continue
        string_id, pc = code.operand_value(first), code.operand_value(second)
        if isinstance(string_id, int) and isinstance(pc, int) and 0 <= string_id < len(strings):
            names.setdefault(pc, strings[string_id])
    return names
