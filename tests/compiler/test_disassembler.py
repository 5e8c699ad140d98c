"""Disassembler listings: offsets, mnemonics, decoded operands and source lines."""

from __future__ import annotations

import struct

from corpus import BBZ_DIR

from bbzide.compiler import compile_file
from bbzide.compiler.bytecode import read_bbo, read_bo
from bbzide.compiler.disassembler import disassemble


def test_bo_listing_decodes_floats_strings_and_targets() -> None:
    bo = (
        b"\x01\x00hello\x00"
        + bytes([35])
        + struct.pack("<f", 2.5)
        + bytes([37])
        + struct.pack("<I", 0)
        + bytes([44])
        + struct.pack("<I", 23)
        + b"\x01"
    )
    listing = disassemble(read_bo(bo))
    assert "     8: pushf    2.5" in listing
    assert "    13: pushs    0  ; 'hello'" in listing
    assert "    23: done" in listing and "    18: jump     -> 23" in listing


def test_bbo_listing_uses_bbzfloat_values() -> None:
    bbo = b"\x00\x00" + bytes([35]) + b"\x33\x37" + bytes([36]) + b"\xff\xff" + b"\x01"
    listing = disassemble(read_bbo(bbo))
    assert "pushf    0.0999756" in listing  # 0x3733 = 0.0999756 (spec §D.4)
    assert "pushi    -1" in listing


def test_listing_shows_the_source_line_of_each_instruction(monkeypatch) -> None:
    monkeypatch.chdir(BBZ_DIR)
    program = compile_file(BBZ_DIR / "arith16.bzz")
    listing = disassemble(read_bo(program.bo), program.strings, program.debug_map, show_source=True)
    source = (BBZ_DIR / "arith16.bzz").read_text().splitlines()
    location = program.debug_map[max(program.debug_map)]
    shown = [line for line in listing.splitlines() if line.startswith("        ; ")]
    assert shown, listing[:500]
    for line in shown:
        number, _, text = line.removeprefix("        ; ").partition(": ")
        assert source[int(number) - 1].strip() == text
    assert location.file.endswith("arith16.bzz") or location.file == "(null)"
