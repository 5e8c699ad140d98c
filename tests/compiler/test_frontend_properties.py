"""Property: any source (random or a mutated corpus script) compiles or raises CompileError."""

from __future__ import annotations

from corpus import COMPILER_DIR
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from bbzide.compiler.frontend import compile_to_basm
from bbzide.diagnostics import CompileError

SCRIPTS = sorted(p for p in COMPILER_DIR.glob("*.bzz") if not p.name.startswith("inc_"))
SOURCES = [p.read_text(encoding="utf-8", errors="replace") for p in SCRIPTS]
PIECES = ["(", ")", "{", "}", "[", "]", ",", ".", "=", "==", "+", "-", "not", "and", "function",
          "var", "if", "else", "return", "while", "for", "nil", "x", "1", "2.5", '"s"', "\n",
          "include", "'", '"', "\\", "#", "$", "_", "!", "^", "%"]
SETTINGS = settings(max_examples=150, deadline=None,
                    suppress_health_check=[HealthCheck.function_scoped_fixture])


def compiles_or_compile_error(path, source: str) -> None:
    try:
        compile_to_basm(path, source=source)
    except CompileError as error:
        assert error.message
        error.render()


@SETTINGS
@given(st.text(max_size=40), st.data())
def test_random_sources(tmp_path, text, data):
    tokens = data.draw(st.lists(st.sampled_from(PIECES), max_size=40))
    compiles_or_compile_error(tmp_path / "r.bzz", text + " ".join(tokens))


@SETTINGS
@given(st.sampled_from(range(len(SOURCES))), st.data())
def test_mutated_corpus_scripts(tmp_path, index, data):
    source = SOURCES[index]
    for _ in range(data.draw(st.integers(1, 4))):
        position = data.draw(st.integers(0, len(source)))
        action = data.draw(st.sampled_from(["delete", "insert", "swap"]))
        if action == "delete":
            source = source[:position] + source[position + 1:]
        elif action == "insert":
            source = source[:position] + data.draw(st.sampled_from(PIECES)) + source[position:]
        elif position + 1 < len(source):
            source = (source[:position] + source[position + 1] + source[position]
                      + source[position + 2:])
    compiles_or_compile_error(COMPILER_DIR / SCRIPTS[index].name, source)
