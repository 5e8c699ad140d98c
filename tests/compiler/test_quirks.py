"""One test per quirk decision of the table in `bbzide/compiler/frontend.py`."""

from __future__ import annotations

import pytest

from bbzide.compiler.frontend import compile_to_basm
from bbzide.diagnostics import CompileError


def strings_of(basm: str) -> list[str]:
    count = int(basm.split("\n", 1)[0][1:])
    return [line[1:] for line in basm.split("\n")[1:1 + count]]


def compile_text(tmp_path, text: str, **options):
    script = tmp_path / "q.bzz"
    script.write_text(text)
    return compile_to_basm(script, **options)


def test_escape_over_read(tmp_path):
    source = 'log("tab\\there")\n'
    default = compile_text(tmp_path, source)
    assert "tab\there" in strings_of(default.basm)
    assert any("bzzc would compile this string as" in w for w in default.warnings)
    quirky = compile_text(tmp_path, source, reference_quirks=True)
    assert 'tab\there"' in strings_of(quirky.basm)  # the closing quote is read in


def test_include_prefix_identifier(tmp_path):
    source = "included_count = 1\nlog(included_count)\n"
    default = compile_text(tmp_path, source)
    assert "included_count" in strings_of(default.basm)
    assert any("include" in w for w in default.warnings)
    with pytest.raises(CompileError, match="expected string after include"):
        compile_text(tmp_path, source, reference_quirks=True)


def test_include_next_to_including_file(tmp_path, monkeypatch):
    (tmp_path / "lib").mkdir()
    (tmp_path / "lib" / "main.bzz").write_text('include "helper.bzz"\nlog(H)\n')
    (tmp_path / "lib" / "helper.bzz").write_text("H = 3\n")
    monkeypatch.chdir(tmp_path)
    result = compile_to_basm("lib/main.bzz")
    assert result.included_files == [str((tmp_path / "lib" / "helper.bzz").resolve())]
    assert any("next to the including file" in w for w in result.warnings)
    with pytest.raises(CompileError, match="Can't read 'helper.bzz'"):
        compile_to_basm("lib/main.bzz", reference_quirks=True)


@pytest.mark.parametrize("quirks", [False, True])
def test_underscore_first_is_rejected(tmp_path, quirks):
    with pytest.raises(CompileError, match="unknown character '_'") as info:
        compile_text(tmp_path, "_x = 1\n", reference_quirks=quirks)
    assert (info.value.location.line, info.value.location.col) == (1, 0)  # not -1


@pytest.mark.parametrize("quirks", [False, True])
def test_not_negates_the_rest_of_the_condition(tmp_path, quirks):
    basm = compile_text(tmp_path, "if (not a and b) { f() }\n", reference_quirks=quirks).basm
    code = [line for line in basm.split("\n") if line.startswith("\t") and "|" in line]
    ops = [line.split("\t")[1] for line in code]
    assert ops.index("land") < ops.index("lnot")  # not (a and b)


@pytest.mark.parametrize("quirks", [False, True])
def test_no_short_circuit(tmp_path, quirks):
    basm = compile_text(tmp_path, "if (f() or g()) { h() }\n", reference_quirks=quirks).basm
    code = basm.split("@__label_0")[1]
    assert code.count("callc") == 3 and "jumpnz" not in code and "lor" in code


def test_var_in_toplevel_block(tmp_path):
    source = "if (1) {\n  var inside = 5\n  log(inside)\n}\n"
    default = compile_text(tmp_path, source)
    quirky = compile_text(tmp_path, source, reference_quirks=True)
    assert default.basm == quirky.basm and "lstore 0" in default.basm
    assert any("top-level block" in w for w in default.warnings)
    assert not quirky.warnings


def test_stray_closing_brace(tmp_path):
    source = "log(1)\n}\nlog(2)\n"
    with pytest.raises(CompileError, match="unmatched }") as info:
        compile_text(tmp_path, source)
    assert (info.value.location.line, info.value.location.col) == (2, 0)
    quirky = compile_text(tmp_path, source, reference_quirks=True)
    assert "pushi 2" not in quirky.basm


@pytest.mark.parametrize("quirks", [False, True])
def test_bare_identifier_at_end_of_file(tmp_path, quirks):
    with pytest.raises(CompileError, match="expected function call or assignment"):
        compile_text(tmp_path, "x = 1\nx\n", reference_quirks=quirks)


@pytest.mark.parametrize("quirks", [False, True])
def test_end_of_file_error_has_a_position(tmp_path, quirks):
    with pytest.raises(CompileError, match="found end of file") as info:
        compile_text(tmp_path, "x = 1 +\n", reference_quirks=quirks)
    assert (info.value.location.line, info.value.location.col) == (1, 6)


def test_newline_escape_is_an_error_by_default_and_kept_with_a_warning_as_the_reference(
        tmp_path):
    with pytest.raises(CompileError, match="a string cannot hold a line break") as info:
        compile_text(tmp_path, 'log("a\\nb")\n')
    assert (info.value.location.line, info.value.location.col) == (1, 4)
    result = compile_text(tmp_path, 'log("a\\nb")\n', reference_quirks=True)
    assert "a\nb" in result.basm and any("newline" in w for w in result.warnings)


def test_source_overrides_file_and_keeps_utf8(tmp_path):
    script = tmp_path / "u.bzz"
    script.write_text("ignored = 1\n")
    result = compile_to_basm(script, source='log("héllo")\n')
    assert strings_of(result.basm) == ["log", "héllo"]


def test_include_cycle_is_skipped_with_a_warning(tmp_path, monkeypatch):
    """The reference skips an include of a file still being read (corpus include_cycle.bzz);
    we produce the same code and name the cycle with its position."""
    (tmp_path / "a.bzz").write_text('include "b.bzz"\nA = 1\n')
    (tmp_path / "b.bzz").write_text('B = 2\ninclude "a.bzz"\n')
    monkeypatch.chdir(tmp_path)
    default = compile_to_basm("a.bzz")
    quirky = compile_to_basm("a.bzz", reference_quirks=True)
    assert default.basm == quirky.basm
    assert not quirky.warnings
    [warning] = [w for w in default.warnings if "include cycle" in w]
    assert warning.startswith(f"{tmp_path / 'b.bzz'}:2:")
    assert "a.bzz -> b.bzz -> a.bzz" in warning


@pytest.mark.parametrize("source", ["", "# only a comment\n\n"])
def test_a_script_without_statements_warns_that_it_has_no_done(tmp_path, source):
    # bzzc compiles it to a lone nop (corpus: empty_file), so a robot runs past the end and
    # stops with a PC error; the bytes are kept, the default mode says why.
    result = compile_text(tmp_path, source)
    assert "done" not in result.basm
    assert any("no statements" in w and "PC error" in w for w in result.warnings)
    assert compile_text(tmp_path, source, reference_quirks=True).warnings == []
