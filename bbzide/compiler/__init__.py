"""The compiler room's facade: Buzz source -> `.basm` -> `.bo` + `.bdb` -> `.bbo`.

    compile_file(path)            bzzc: front end (bzzparse) then assembler (bzzasm)
    compile_source(text, name)    the same from text (the IDE's editor buffer)
    CompiledProgram.to_bbo()      bo2bbo
    load_program(bbo, bo, bdb)    a stored `.bbo` with strings and debug map from its neighbours
    bittybuzz_string_table(names) the 46 BittyBuzz base strings + host-function names

The front end lives in `frontend.py` (imported lazily so that reading bytecode never pays for
the parser). Errors are `CompileError` / `BytecodeError` (`bbzide.diagnostics`).
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from pathlib import Path

from bbzide.compiler.assembler import assemble
from bbzide.compiler.bo2bbo import bo_to_bbo
from bbzide.compiler.bytecode import read_bbo, read_bdb, read_bo
from bbzide.compiler.call_sites import ScriptSymbols, call_sites_by_offset
from bbzide.compiler.opcodes import Op
from bbzide.compiler.program import BittyBuzzProgram, CompiledProgram
from bbzide.compiler.string_table import base_strings_mismatch, bittybuzz_string_table
from bbzide.diagnostics import BytecodeError, SourceLocation, UserError

__all__ = [
    "BittyBuzzProgram",
    "CompiledProgram",
    "base_strings_mismatch",
    "bittybuzz_string_table",
    "compile_file",
    "compile_source",
    "load_program",
    "debug_map_from_records",
]


def debug_map_from_records(
    records: Sequence[tuple[int, SourceLocation]],
    instruction_offsets: Sequence[int],
    fallback: SourceLocation | None = None,
) -> dict[int, SourceLocation]:
    """offset -> SourceLocation for every instruction: its own `.bdb` record, else the previous
    instruction's location, else (the registration prologue, which bzzparse leaves unannotated)
    the first location that follows; `fallback` (start of the script) when there is none."""
    recorded = dict(records)
    debug_map: dict[int, SourceLocation] = {}
    pending: list[int] = []
    previous: SourceLocation | None = None
    for offset in instruction_offsets:
        location = recorded.get(offset, previous)
        if location is None:
            pending.append(offset)
            continue
        for waiting in pending:
            debug_map[waiting] = location
        pending.clear()
        debug_map[offset] = location
        previous = location
    if fallback is not None:
        for waiting in pending:
            debug_map[waiting] = fallback
    return debug_map


def _program_from_basm(
    basm: str, filename: str, warnings: list[str], source_file: str,
    code_lines: Sequence[str] = (), symbols: ScriptSymbols | None = None,
    source_text: str | None = None,
) -> CompiledProgram:
    assembly = assemble(basm, filename)
    bytecode = read_bo(assembly.bo, filename)
    records = [
        (
            record.offset,
            SourceLocation(record.file.decode("utf-8", "surrogateescape"), record.line, record.col),
        )
        for record in assembly.debug_records
    ]
    offsets = [i.offset for i in bytecode.instructions]
    debug_map = debug_map_from_records(records, offsets, SourceLocation(source_file, 1, 0))
    callc_offsets = [i.offset for i in bytecode.instructions if i.opcode == Op.CALLC]
    return CompiledProgram(
        basm=basm,
        bo=assembly.bo,
        bdb=assembly.bdb,
        strings=bytecode.strings,
        debug_map=debug_map,
        warnings=[*warnings, *assembly.warnings],
        filename=filename,
        call_sites=call_sites_by_offset(code_lines, callc_offsets),
        symbols=symbols or ScriptSymbols(),
        source_file=source_file,
        source_text=source_text,
    )


def compile_file(
    path: str | os.PathLike,
    include_path: Sequence[str] = (),
    string_table: Sequence[str] | None = None,
    reference_quirks: bool = False,
    *,
    source: str | None = None,
) -> CompiledProgram:
    """Compile a Buzz script like `bzzc` (bzzparse + bzzasm). Raises CompileError."""
    from bbzide.compiler.frontend import compile_to_basm

    result = compile_to_basm(
        path,
        source=source,
        include_path=tuple(include_path),
        string_table=None if string_table is None else list(string_table),
        reference_quirks=reference_quirks,
    )
    name = Path(os.fspath(path)).stem + ".bo"
    source_file = os.path.realpath(os.fspath(path))
    return _program_from_basm(result.basm, name, list(result.warnings), source_file,
                              result.code_lines, result.symbols, result.source_text)


def compile_source(
    text: str,
    filename: str,
    include_path: Sequence[str] = (),
    string_table: Sequence[str] | None = None,
    reference_quirks: bool = False,
) -> CompiledProgram:
    """Compile Buzz source text; `filename` names it in diagnostics and the debug map."""
    return compile_file(filename, include_path, string_table, reference_quirks, source=text)


def _read(path: Path, what: str) -> bytes:
    try:
        return path.read_bytes()
    except OSError as error:
        raise UserError(f"cannot read {what} {path}: {error.strerror}") from None


def load_program(
    bbo_path_or_bytes: str | os.PathLike | bytes,
    bo: str | os.PathLike | bytes | None = None,
    bdb: str | os.PathLike | bytes | None = None,
) -> BittyBuzzProgram:
    """A stored `.bbo` as a BittyBuzzProgram. Strings come from the `.bo` (given, or beside the
    `.bbo`), the debug map from the `.bdb` (remapped to `.bbo` offsets through the `.bo`)."""
    if isinstance(bbo_path_or_bytes, bytes):
        bbo, name, beside = bbo_path_or_bytes, "<bbo>", None
    else:
        path = Path(bbo_path_or_bytes)
        bbo, name, beside = _read(path, "bytecode"), path.name, path
    read_bbo(bbo, name)
    if bo is None and beside is not None and beside.with_suffix(".bo").is_file():
        bo = beside.with_suffix(".bo")
    if bdb is None and beside is not None and beside.with_suffix(".bdb").is_file():
        bdb = beside.with_suffix(".bdb")
    bo_bytes = bo if isinstance(bo, bytes) or bo is None else _read(Path(bo), "bytecode")
    bdb_bytes = bdb if isinstance(bdb, bytes) or bdb is None else _read(Path(bdb), "debug file")
    if bo_bytes is None:
        return BittyBuzzProgram(bbo, [], {}, {}, [])
    bo_name = Path(bo).name if bo is not None and not isinstance(bo, bytes) else "<bo>"
    decoded = read_bo(bo_bytes, bo_name)
    conversion = bo_to_bbo(bo_bytes, bo_name)
    if conversion.bbo != bbo:
        raise BytecodeError(
            f"{name}: does not match {bo_name} (the .bo converts to a different .bbo)"
        )
    debug_map: dict[int, SourceLocation] = {}
    if bdb_bytes is not None:
        records = read_bdb(bdb_bytes, "<bdb>" if isinstance(bdb, bytes) else Path(bdb).name)
        by_bo = debug_map_from_records(records, [i.offset for i in decoded.instructions])
        debug_map = {conversion.bo_to_bbo[offset]: loc for offset, loc in by_bo.items()}
    return BittyBuzzProgram(
        bbo, decoded.strings, debug_map, conversion.bo_to_bbo, conversion.warnings
    )
