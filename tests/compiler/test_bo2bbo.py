"""bo2bbo against the reference BittyBuzz tool on the whole bbz corpus."""

from __future__ import annotations

import struct

from corpus import BBZ_DIR, report

from bbzide.compiler.bo2bbo import bo_to_bbo


def test_every_bbz_bo_converts_byte_identical() -> None:
    files = sorted(BBZ_DIR.glob("*.bo"))
    failures = [
        p.name
        for p in files
        if bo_to_bbo(p.read_bytes(), p.name).bbo != p.with_suffix(".bbo").read_bytes()
    ]
    report("bo2bbo .bo -> .bbo identical", len(files) - len(failures), len(files))
    assert len(files) == 33
    assert not failures, failures


def test_int16_warnings_worded_like_the_reference() -> None:
    path = BBZ_DIR / "arith16.bo"
    conversion = bo_to_bbo(path.read_bytes(), path.name)
    expected = (BBZ_DIR / "arith16.bo2bbo.txt").read_text().splitlines()
    assert conversion.warnings == expected


def test_address_to_a_non_instruction_becomes_zero() -> None:
    # jump to offset 3 (inside the jump's own operand): not an instruction start -> 0.
    bo = b"\x00\x00" + bytes([44]) + struct.pack("<I", 3) + b"\x01"
    conversion = bo_to_bbo(bo)
    assert conversion.bbo == b"\x00\x00" + bytes([44]) + b"\x00\x00" + b"\x01"
    assert conversion.bo_to_bbo == {2: 2, 7: 5}


def test_spec_vector_section_d3() -> None:
    bo = (
        b"\x00\x00"
        + bytes([36])
        + struct.pack("<i", 5)
        + bytes([35])
        + struct.pack("<f", 2.5)
        + b"\x07\x01"
    )
    assert (
        bo_to_bbo(bo).bbo
        == b"\x00\x00" + bytes([36]) + b"\x05\x00" + bytes([35]) + b"\x80\x40" + b"\x07\x01"
    )
