"""The compiler room's subcommands: `compile`, `disasm`, `bo2bbo` (routed by `bbzide/cli.py`).

    bbzide compile X.bzz [-I DIR]... [--bst F | --platform P [--host NAME]...] [-o X.bo]
                   [--bbo X.bbo] [--basm X.basm] [--bdb X.bdb] [--reference-quirks]
    bbzide disasm X.bo|X.bbo [--bdb F] [--source]
    bbzide bo2bbo X.bo [-o X.bbo]

`--bst` gives the string table as it is (with `--platform` it must start with BittyBuzz's base
strings; `--host` then has nothing to add and is refused). `--platform` without `--bst` compiles
for BittyBuzz: the 46 base strings, then the host-function
names (`--host`, repeatable; for `kilobot` the Kilobot firmware's `led set_motor delay abs` when
no `--host` is given), so that string ids match what the firmware expects. Every error is a
`UserError` (the router prints it and exits 1).

Outputs are build products and are rewritten on every run, with two exceptions that would lose
work (`check_outputs`, before anything is written): an output that is one of the inputs (the
script, the `.bst`, the `.bo`) is always refused, and an existing `.bzz` (someone's source) is
overwritten only with `--force`. Two outputs naming one file are refused too.
"""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

from bbzide.compiler import compile_file, load_program
from bbzide.compiler.bo2bbo import bo_to_bbo
from bbzide.compiler.bytecode import read_bbo, read_bdb, read_bo
from bbzide.compiler.footprint import FLASH_BUDGETS, measure
from bbzide.compiler.string_table import (
    BITTYBUZZ_BASE_STRINGS,
    KILOBOT_HOST_NAMES,
    base_strings_mismatch,
    bittybuzz_string_table,
    read_bst,
)
from bbzide.diagnostics import UserError

PLATFORMS = tuple(FLASH_BUDGETS)


def register(subparsers: argparse._SubParsersAction) -> None:
    compile_parser = subparsers.add_parser(
        "compile", help="compile a Buzz script (.bo, .bdb, .bbo)"
    )
    compile_parser.add_argument("script", help="the .bzz file")
    compile_parser.add_argument(
        "-I", dest="include", action="append", default=[], help="include folder"
    )
    compile_parser.add_argument("--bst", help="string table file (one string per line)")
    compile_parser.add_argument("-o", dest="bo", help="output .bo (default: beside the script)")
    compile_parser.add_argument("--bbo", help="also write the BittyBuzz .bbo here")
    compile_parser.add_argument("--basm", help="also write the .basm assembly here")
    compile_parser.add_argument("--bdb", help="output .bdb (default: beside the .bo)")
    compile_parser.add_argument(
        "--platform", choices=PLATFORMS, help="compile for this BittyBuzz platform"
    )
    compile_parser.add_argument(
        "--host", action="append", default=[], help="host function name (repeatable)"
    )
    compile_parser.add_argument(
        "--reference-quirks", action="store_true", help="reproduce bzzparse's quirks"
    )
    compile_parser.add_argument(
        "--force", action="store_true", help="overwrite an existing .bzz named as an output"
    )
    compile_parser.set_defaults(handler=run_compile)

    disasm_parser = subparsers.add_parser("disasm", help="list the instructions of a .bo or .bbo")
    disasm_parser.add_argument("bytecode", help="the .bo or .bbo file")
    disasm_parser.add_argument("--bdb", help="debug file (default: beside the bytecode)")
    disasm_parser.add_argument("--source", action="store_true", help="show the source lines")
    disasm_parser.set_defaults(handler=run_disasm)

    convert_parser = subparsers.add_parser(
        "bo2bbo", help="convert a Buzz .bo into a BittyBuzz .bbo"
    )
    convert_parser.add_argument("bo", help="the .bo file")
    convert_parser.add_argument("-o", dest="bbo", help="output .bbo (default: beside the .bo)")
    convert_parser.add_argument(
        "--force", action="store_true", help="overwrite an existing .bzz named as the output"
    )
    convert_parser.set_defaults(handler=run_bo2bbo)


def _read(path: Path) -> bytes:
    try:
        return path.read_bytes()
    except OSError as error:
        raise UserError(f"cannot read {path}: {error.strerror}") from None


def _write(path: Path, data: bytes) -> None:
    try:
        path.write_bytes(data)
    except OSError as error:
        raise UserError(f"cannot write {path}: {error.strerror}") from None


def _same_file(a: Path, b: Path) -> bool:
    try:
        return a.resolve() == b.resolve() or (a.exists() and b.exists() and a.samefile(b))
    except OSError:
        return False


def check_outputs(inputs: list[Path], outputs: list[Path], force: bool) -> None:
    """Refuse, before anything is written, outputs that would destroy an input or a source."""
    for index, output in enumerate(outputs):
        for source in inputs:
            if _same_file(output, source):
                raise UserError(f"{output} is the input {source}: "
                                "name another file for this output")
        for other in outputs[:index]:
            if _same_file(output, other):
                raise UserError(f"two outputs both name {output}")
        if output.is_dir():
            raise UserError(f"cannot write {output}: it is a folder")
        if output.suffix == ".bzz" and output.exists() and not force:
            raise UserError(f"{output} is an existing Buzz source; "
                            "give --force to overwrite it")


def include_path_from_environment() -> list[str]:
    """The folders of `$BUZZ_INCLUDE_PATH` (colon-separated, as bzzparse reads it): searched
    after the `-I` folders by `compile` and by `run` (one robot or a world)."""
    folders = os.environ.get("BUZZ_INCLUDE_PATH", "").split(os.pathsep)
    return [folder for folder in folders if folder]


def run_compile(args: argparse.Namespace) -> int:
    script = Path(args.script)
    if script.is_dir():
        raise UserError(f"{script} is a folder, not a Buzz script")
    if not script.is_file():
        raise UserError(f"no such script: {script}")
    if args.bst and args.host:
        raise UserError("--bst gives the whole string table, host names included: "
                        "--host would have no effect (give one or the other)")
    if args.bst:
        strings = read_bst(args.bst)
        # With --platform the .bst must be a BittyBuzz table: the firmware's built-ins use the
        # fixed ids of its base strings (a .bst without them compiles, but runs wrong).
        why = base_strings_mismatch(strings) if args.platform else None
        if why is not None:
            why = why.replace("it was compiled without", "it is not").replace(
                "its neighbors", "the script's neighbors")
            raise UserError(f"--bst {args.bst} with --platform {args.platform}: {why}")
    elif args.platform or args.host:
        hosts = args.host or (list(KILOBOT_HOST_NAMES) if args.platform == "kilobot" else [])
        strings = bittybuzz_string_table(hosts)
    else:
        strings = None
    program = compile_file(script, [*args.include, *include_path_from_environment()], strings,
                           args.reference_quirks)
    bo_path = Path(args.bo) if args.bo else script.with_suffix(".bo")
    bdb_path = Path(args.bdb) if args.bdb else bo_path.with_suffix(".bdb")
    outputs = [bo_path, bdb_path, *(Path(p) for p in (args.basm, args.bbo) if p)]
    check_outputs([script, *([Path(args.bst)] if args.bst else [])], outputs, args.force)
    bbo = program.to_bbo()
    _write(bo_path, program.bo)
    _write(bdb_path, program.bdb)
    if args.basm:
        _write(Path(args.basm), program.basm.encode("utf-8", "surrogateescape"))
    if args.bbo:
        _write(Path(args.bbo), bbo.bbo)
    for warning in [*program.warnings, *bbo.warnings]:
        print(warning, file=sys.stderr)
    print(measure(program, bbo).table())
    if args.platform and not measure(program, bbo).fits(args.platform):
        raise UserError(
            f"the .bbo ({len(bbo.bbo)} bytes) does not fit {args.platform}'s "
            f"{FLASH_BUDGETS[args.platform].bytes_for_bytecode}-byte bytecode budget"
        )
    return 0


def run_disasm(args: argparse.Namespace) -> int:
    from bbzide.compiler.disassembler import disassemble

    path = Path(args.bytecode)
    data = _read(path)
    bdb_path = Path(args.bdb) if args.bdb else path.with_suffix(".bdb")
    if path.suffix == ".bbo":
        code = read_bbo(data, path.name)
        bo_path = path.with_suffix(".bo")
        program = load_program(
            data,
            bo=bo_path if bo_path.is_file() else None,
            bdb=bdb_path if bdb_path.is_file() and bo_path.is_file() else None,
        )
        # Without the .bo, ids 0..45 are still known: BittyBuzz fixes them (spec §D.2).
        strings = program.strings or list(BITTYBUZZ_BASE_STRINGS)
        print(disassemble(code, strings, program.debug_map, args.source), end="")
        return 0
    code = read_bo(data, path.name)
    debug_map = {}
    if bdb_path.is_file():
        from bbzide.compiler import debug_map_from_records

        records = read_bdb(_read(bdb_path), bdb_path.name)
        debug_map = debug_map_from_records(records, [i.offset for i in code.instructions])
    print(disassemble(code, code.strings, debug_map, args.source), end="")
    return 0


def run_bo2bbo(args: argparse.Namespace) -> int:
    path = Path(args.bo)
    conversion = bo_to_bbo(_read(path), path.name)
    output = Path(args.bbo) if args.bbo else path.with_suffix(".bbo")
    check_outputs([path], [output], args.force)
    for warning in conversion.warnings:
        print(warning, file=sys.stderr)
    _write(output, conversion.bbo)
    return 0
