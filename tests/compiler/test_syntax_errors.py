"""Every corpus error script: CompileError at the reference's line:col, and a readable render()."""

from __future__ import annotations

import os
import re

import pytest
from corpus import COMPILER_ERRORS_DIR

from bbzide.compiler.frontend import compile_to_basm
from bbzide.diagnostics import CompileError

ERROR_SCRIPTS = sorted(COMPILER_ERRORS_DIR.glob("*.bzz"))
POSITIONED = re.compile(r"^\$DIR/(?P<file>[^:]+):(?P<line>\d+):(?P<col>\d+): (?P<msg>.*)$")
AT_EOF = re.compile(r"^(?P<file>[^:]+): Syntax error: (?P<msg>.*found end of file)$")
#: the error scripts checked by a test of their own below rather than by the parametrised ones
OWN_TESTS = {"unclosed_string", "asm_newline_escape", "bare_identifier_at_eof"}


def first_err_line(script) -> str:
    return script.with_suffix(".err").read_text().split("\n")[0]


def compile_error(script, monkeypatch) -> CompileError:
    monkeypatch.chdir(script.parent)
    with pytest.raises(CompileError) as info:
        compile_to_basm(script.name, reference_quirks=True)
    return info.value


@pytest.mark.parametrize("script", [s for s in ERROR_SCRIPTS
                                    if POSITIONED.match(first_err_line(s))], ids=lambda p: p.stem)
def test_error_position_and_message(script, monkeypatch):
    expected = POSITIONED.match(first_err_line(script))
    error = compile_error(script, monkeypatch)
    assert error.location is not None
    expected_position = (int(expected["line"]), int(expected["col"]))
    assert (error.location.line, error.location.col) == expected_position
    assert os.path.basename(error.location.file) == expected["file"]
    assert error.message.startswith(expected["msg"])  # reference wording, maybe plus a hint
    rendered = error.render()
    assert f"{expected['file']}:{expected['line']}:{expected['col']}" in rendered
    assert rendered.rstrip().endswith("^")


@pytest.mark.parametrize("script", [s for s in ERROR_SCRIPTS
                                    if AT_EOF.match(first_err_line(s))], ids=lambda p: p.stem)
def test_error_at_end_of_file(script, monkeypatch):
    expected = AT_EOF.match(first_err_line(script))
    error = compile_error(script, monkeypatch)
    assert error.message.startswith("Syntax error: " + expected["msg"])
    assert error.location is not None  # we point at the last token instead of nothing
    lines = script.read_text().splitlines()
    last_code_line = max(i for i, text in enumerate(lines, 1) if text.strip())
    assert error.location.line == last_code_line


def test_unclosed_string_reports_the_lexer_error(monkeypatch):
    script = COMPILER_ERRORS_DIR / "unclosed_string.bzz"
    error = compile_error(script, monkeypatch)
    assert (error.location.line, error.location.col) == (2, 3)


def test_asm_newline_escape_compiles_like_the_reference(monkeypatch):
    script = COMPILER_ERRORS_DIR / "asm_newline_escape.bzz"
    monkeypatch.chdir(script.parent)
    result = compile_to_basm(script.name, reference_quirks=True)
    expected = script.with_suffix(".basm").read_text()
    assert result.basm.replace(os.path.realpath(script.parent), "$DIR") == expected
    assert any("newline" in w for w in result.warnings)


def test_bare_identifier_at_eof_is_a_proper_error(monkeypatch):
    # the reference crashes (SIGSEGV, empty .err); we report the statement
    script = COMPILER_ERRORS_DIR / "bare_identifier_at_eof.bzz"
    assert script.with_suffix(".rc").read_text().strip() == "139"
    error = compile_error(script, monkeypatch)
    assert "expected function call or assignment" in error.message
    assert error.location is not None


def test_every_error_script_has_a_test():
    # each corpus error script is checked by a parametrised case (its first .err line gives the
    # position) or by a test of its own; a new script with neither fails here
    positioned = {s.stem for s in ERROR_SCRIPTS if POSITIONED.match(first_err_line(s))}
    at_eof = {s.stem for s in ERROR_SCRIPTS if AT_EOF.match(first_err_line(s))}
    assert positioned | at_eof | OWN_TESTS == {s.stem for s in ERROR_SCRIPTS}
    assert len(ERROR_SCRIPTS) == 21


def test_error_in_editor_buffer_shows_the_buffer_line(tmp_path):
    script = tmp_path / "buffer.bzz"
    script.write_text("x = 1\n")  # the saved file differs from the editor buffer
    with pytest.raises(CompileError) as info:
        compile_to_basm(script, source="x = 1\ny = (2\n")
    rendered = info.value.render()
    assert f"{script.resolve()}:2:5: error: Syntax error: expected ), found end of file" in rendered
    assert rendered.splitlines()[1:] == ["  y = (2", "       ^"]


def test_deep_nesting_is_a_compile_error(tmp_path):
    with pytest.raises(CompileError, match="nested too deeply"):
        compile_to_basm(tmp_path / "deep.bzz", source="x = " + "(" * 3000 + "1\n")
