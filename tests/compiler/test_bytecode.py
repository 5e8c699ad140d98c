"""Bytecode readers: the corpus decodes, bad input is a one-line BytecodeError, never a crash."""

from __future__ import annotations

import struct
import subprocess
import sys

import pytest
from corpus import BBZ_DIR, BBZCONF, COMPILER_DIR
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from bbzide.compiler.bo2bbo import bo_to_bbo
from bbzide.compiler.bytecode import read_bbo, read_bdb, read_bo
from bbzide.diagnostics import BytecodeError

CORPUS_BO = sorted(COMPILER_DIR.glob("*.bo")) + sorted(BBZ_DIR.glob("*.bo"))
CORPUS_BBO = sorted(BBZ_DIR.glob("*.bbo"))


def test_every_corpus_file_decodes_and_matches_bbzconf_listing() -> None:
    for path in CORPUS_BO:
        code = read_bo(path.read_bytes(), path.name)
        assert code.instructions and code.instructions[-1].offset < len(path.read_bytes())
        read_bdb(path.with_suffix(".bdb").read_bytes(), path.name)
    for path in CORPUS_BBO:
        read_bbo(path.read_bytes(), path.name)
    # bbzconf (independent oracle) lists one line per instruction: compare the counts on one file.
    sample = BBZ_DIR / "arith16.bbo"
    listing = subprocess.run(
        [sys.executable, str(BBZCONF), "bbo", str(sample)],
        capture_output=True,
        text=True,
        check=True,
    ).stdout
    mnemonics = [i.mnemonic for i in read_bbo(sample.read_bytes()).instructions]
    assert sum(1 for line in listing.splitlines() if any(f" {m}" in line for m in ("gstore",))) >= 1
    assert mnemonics.count("gstore") == sum(line.count("gstore") for line in listing.splitlines())
    print(f"bytecode readers: {len(CORPUS_BO)} .bo, {len(CORPUS_BBO)} .bbo decoded")


def _one_line_error(call, *args) -> str:
    with pytest.raises(BytecodeError) as caught:
        call(*args)
    message = caught.value.render()
    assert "\n" not in message
    return message


def test_specific_malformations_are_named() -> None:
    good = (BBZ_DIR / "arith16.bo").read_bytes()
    assert "truncated" in _one_line_error(read_bo, b"\x01", "x.bo")
    assert "string count" in _one_line_error(read_bo, b"\xff\xff" + b"a\0", "x.bo")
    assert "x.bo: offset" in _one_line_error(read_bo, b"\x00\x00\x99", "x.bo")
    assert "unknown opcode 153" in _one_line_error(read_bo, b"\x00\x00\x99", "x.bo")
    assert "truncated operand of pushi" in _one_line_error(
        read_bo, b"\x00\x00" + bytes([36, 1, 2]), "x.bo"
    )
    assert "no string count" in _one_line_error(read_bo, good[:1], "x.bo")
    jump_out = b"\x00\x00" + bytes([44]) + struct.pack("<I", 5000) + b"\x01"
    assert "not an instruction" in _one_line_error(read_bo, jump_out, "x.bo")
    assert "truncated operand" in _one_line_error(read_bbo, b"\x00\x00" + bytes([36, 1]), "x.bbo")
    assert "truncated" in _one_line_error(read_bdb, b"\x01\x00\x00", "x.bdb")
    assert "file name" in _one_line_error(
        read_bdb, struct.pack("<IQQH", 2, 1, 0, 50) + b"ab", "x.bdb"
    )
    assert "truncated operand" in _one_line_error(bo_to_bbo, b"\x00\x00" + bytes([36, 1]), "x.bo")


_SAMPLES = [p.read_bytes() for p in CORPUS_BO[:6]] + [p.read_bytes() for p in CORPUS_BBO[:6]]


@st.composite
def mutated(draw) -> tuple[bytes, int]:
    data = bytearray(draw(st.sampled_from(_SAMPLES)))
    for _ in range(draw(st.integers(1, 4))):
        kind = draw(st.sampled_from(["flip", "cut", "insert"]))
        at = draw(st.integers(0, max(0, len(data) - 1)))
        if kind == "flip" and data:
            data[at] = draw(st.integers(0, 255))
        elif kind == "cut":
            del data[at:]
        else:
            data[at:at] = draw(st.binary(min_size=1, max_size=4))
    return bytes(data), 0


def _only_bytecode_errors(data: bytes) -> None:
    for call in (read_bo, read_bbo, read_bdb, bo_to_bbo):
        try:
            call(data, "fuzz")
        except BytecodeError as error:
            assert "\n" not in error.render()


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(mutated())
def test_mutated_corpus_bytes_give_only_bytecode_errors(sample: tuple[bytes, int]) -> None:
    _only_bytecode_errors(sample[0])


@settings(max_examples=300, deadline=None)
@given(st.binary(max_size=300))
def test_random_bytes_give_only_bytecode_errors(data: bytes) -> None:
    _only_bytecode_errors(data)
