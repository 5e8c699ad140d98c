"""Full pipeline (front end + assembler + bo2bbo) against every corpus script."""

from __future__ import annotations

import os
import struct

from corpus import BBZ_DIR, COMPILER_DIR, report

from bbzide.compiler import compile_file, load_program
from bbzide.compiler.bytecode import read_bo
from bbzide.compiler.string_table import read_bst


def normalise_bdb(bdb: bytes, directory: str) -> bytes:
    """Replace the absolute folder by `$DIR` in every record (corpus README §2)."""
    out = bytearray()
    position = 0
    prefix = directory.encode()
    while position < len(bdb):
        offset, line, col, length = struct.unpack_from("<IQQH", bdb, position)
        position += 22
        name = bdb[position : position + length]
        position += length
        if name.startswith(prefix + b"/"):
            name = b"$DIR" + name[len(prefix) :]
        out += struct.pack("<IQQH", offset, line, col, len(name)) + name
    return bytes(out)


def _scripts(directory):
    return [p for p in sorted(directory.glob("*.bzz")) if p.with_suffix(".bo").exists()]


def test_compiler_corpus_bo_and_bdb_identical(monkeypatch) -> None:
    monkeypatch.chdir(COMPILER_DIR)  # the reference ran in the script's folder (README §1)
    scripts = _scripts(COMPILER_DIR)
    failures = []
    for script in scripts:
        program = compile_file(script, reference_quirks=True)
        real_dir = os.path.realpath(script.parent)
        if program.bo != script.with_suffix(".bo").read_bytes():
            failures.append(f"{script.name}: .bo differs")
        elif normalise_bdb(program.bdb, real_dir) != script.with_suffix(".bdb").read_bytes():
            failures.append(f"{script.name}: .bdb differs")
        offsets = [i.offset for i in read_bo(program.bo).instructions]
        assert set(offsets) <= set(program.debug_map), script.name
    report("compiler .bo+.bdb identical", len(scripts) - len(failures), len(scripts))
    assert len(scripts) >= 40
    assert not failures, failures


def test_bbz_corpus_bo_bdb_bbo_identical(monkeypatch) -> None:
    monkeypatch.chdir(BBZ_DIR)
    scripts = _scripts(BBZ_DIR)
    failures = []
    for script in scripts:
        strings = read_bst(script.with_suffix(".bst"))
        program = compile_file(script, string_table=strings, reference_quirks=True)
        bbo = program.to_bbo()
        real_dir = os.path.realpath(script.parent)
        if program.bo != script.with_suffix(".bo").read_bytes():
            failures.append(f"{script.name}: .bo differs")
        elif normalise_bdb(program.bdb, real_dir) != script.with_suffix(".bdb").read_bytes():
            failures.append(f"{script.name}: .bdb differs")
        elif bbo.bbo != script.with_suffix(".bbo").read_bytes():
            failures.append(f"{script.name}: .bbo differs")
        assert set(bbo.bo_to_bbo.values()) <= set(bbo.debug_map), script.name
        assert bbo.location_of(2) is not None
    report("bbz .bo+.bdb+.bbo identical", len(scripts) - len(failures), len(scripts))
    assert len(scripts) >= 30
    assert not failures, failures


def test_load_program_from_stored_bbo_uses_bo_strings_and_bdb() -> None:
    script = BBZ_DIR / "arith16.bzz"
    program = load_program(script.with_suffix(".bbo"))
    assert program.bbo == script.with_suffix(".bbo").read_bytes()
    assert program.string_id("id") == 0 and program.string_id("__INTERNAL_2_DO_NOT_USE__") == 45
    assert program.location_of(2) is not None
    assert any(loc.file == "$DIR/arith16.bzz" for loc in program.debug_map.values())
    assert len(program.warnings) == 4


def test_base_strings_match_every_corpus_bst() -> None:
    from bbzide.compiler.string_table import (
        BITTYBUZZ_BASE_STRINGS,
        bittybuzz_string_table,
        format_bst,
        parse_bst,
    )

    bst_files = sorted(BBZ_DIR.glob("*.bst"))
    for path in bst_files:
        strings = read_bst(path)
        assert strings[:46] == list(BITTYBUZZ_BASE_STRINGS), path.name
        assert bittybuzz_string_table(strings[46:]) == strings
        assert parse_bst(format_bst(strings)) == strings
    assert len(BITTYBUZZ_BASE_STRINGS) == 46 and BITTYBUZZ_BASE_STRINGS[32] == "stigmergy"
    print(f"string tables: {len(bst_files)} corpus .bst start with the 46 base strings")
