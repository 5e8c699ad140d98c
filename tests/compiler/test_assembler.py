"""Assembler against the reference bzzasm outputs of the whole corpus."""

from __future__ import annotations

import struct

import pytest
from corpus import BBZ_DIR, COMPILER_DIR, COMPILER_ERRORS_DIR, report
from hypothesis import given, settings
from hypothesis import strategies as st

from bbzide.compiler.assembler import assemble, strtof32, strtoul32
from bbzide.diagnostics import CompileError


def _corpus_basm():
    return sorted(COMPILER_DIR.glob("*.basm")) + sorted(BBZ_DIR.glob("*.basm"))


def test_every_corpus_basm_assembles_byte_identical() -> None:
    files = _corpus_basm()
    failures = []
    for path in files:
        assembly = assemble(path.read_bytes(), path.name)
        if assembly.bo != path.with_suffix(".bo").read_bytes():
            failures.append(f"{path.name}: .bo")
        # The stored .basm already carries `$DIR` paths, so the .bdb must match as stored.
        elif assembly.bdb != path.with_suffix(".bdb").read_bytes():
            failures.append(f"{path.name}: .bdb")
        assert all(b"$DIR" in r.file or r.file == b"(null)" for r in assembly.debug_records)
    report("assembler .basm -> .bo+.bdb identical", len(files) - len(failures), len(files))
    assert len(files) == 81
    assert not failures, failures


def test_newline_in_string_is_unknown_instruction_at_line_4() -> None:
    path = COMPILER_ERRORS_DIR / "asm_newline_escape.basm"
    with pytest.raises(CompileError) as caught:
        assemble(path.read_bytes(), path.name)
    expected = (COMPILER_ERRORS_DIR / "asm_newline_escape.err").read_text().strip()
    assert caught.value.reference_message == expected
    assert caught.value.location.line == 4


def test_string_line_loses_its_last_character_even_without_newline() -> None:
    assembly = assemble(b"!1\n'abc", "x.basm")
    assert assembly.bo == b"\x01\x00ab\x00"


def test_missing_argument_unknown_label_and_label_at_end() -> None:
    with pytest.raises(CompileError, match="missing argument"):
        assemble(b"!0\n\tpushi\n", "x.basm")
    with pytest.raises(CompileError, match='unknown label "@nowhere"'):
        assemble(b"!0\n\tjump @nowhere\n\tnop\n", "x.basm")
    with pytest.raises(CompileError, match="beyond the bytecode size"):
        assemble(b"!0\n\tjump @end\n@end\n", "x.basm")


def test_strtoul_and_strtof_semantics() -> None:
    assert strtoul32(b"-1") == (0xFFFFFFFF, True)
    assert strtoul32(b"4294967296") == (0, True)
    assert strtoul32(b"007x") == (7, True)
    assert strtoul32(b"@__label_1") == (0, False)
    assert strtof32(b"3.")[0] == struct.pack("<f", 3.0)
    assert strtof32(b"1.2.3")[0] == struct.pack("<f", 1.2)
    assert strtof32(b"1e999")[0] == struct.pack("<f", float("inf"))


def test_ignored_argument_warns_like_the_reference() -> None:
    assembly = assemble(b"!0\n\tnop 3\t|1,0,f\n", "x.basm")
    assert assembly.warnings == ['WARNING: x.basm:2 ignored argument "3"']
    assert assembly.bo == b"\x00\x00\x00"


@settings(max_examples=200, deadline=None)
@given(
    st.lists(
        st.one_of(
            st.sampled_from(
                [
                    b"!2",
                    b"'a",
                    b"'",
                    b"\tnop",
                    b"\tpushi 3",
                    b"\tpushf x",
                    b"\tjump @l",
                    b"@l",
                    b"\tpushl @l\t|1,2,f",
                    b"\tfoo",
                    b"\tpushi",
                    b"#c",
                    b"",
                    b"\tdone 1",
                ]
            ),
            st.binary(max_size=12),
        ),
        max_size=12,
    )
)
def test_any_basm_assembles_or_raises_compile_error(lines: list[bytes]) -> None:
    try:
        assembly = assemble(b"\n".join(lines) + b"\n", "fuzz.basm")
    except CompileError as error:
        assert "\n" not in error.message
    else:
        assert isinstance(assembly.bo, bytes)
