"""Every corpus script compiles to the stored `.basm`, byte for byte (reference_quirks=True).

Scripts compile with the CWD set to their folder (includes are CWD-relative in the reference) and
the absolute folder is normalised to `$DIR` as in corpus README §2. `bbz/` scripts use their `.bst`.
"""

from __future__ import annotations

import os

import pytest
from corpus import BBZ_DIR, COMPILER_DIR

from bbzide.compiler.frontend import compile_to_basm

COMPILER_SCRIPTS = sorted(p for p in COMPILER_DIR.glob("*.bzz") if not p.name.startswith("inc_"))
BBZ_SCRIPTS = sorted(BBZ_DIR.glob("*.bzz"))


def read_bst(path) -> list[str]:
    return path.read_bytes().decode("utf-8", errors="surrogateescape").split("\n")[:-1]


def compile_normalised(script, monkeypatch, string_table=None) -> str:
    monkeypatch.chdir(script.parent)
    result = compile_to_basm(script.name, string_table=string_table, reference_quirks=True)
    return result.basm.replace(os.path.realpath(script.parent), "$DIR")


def expected_basm(script) -> str:
    return script.with_suffix(".basm").read_bytes().decode("utf-8", errors="surrogateescape")


def test_corpus_is_complete():
    assert len(COMPILER_SCRIPTS) == 48
    assert len(BBZ_SCRIPTS) == 33


@pytest.mark.parametrize("script", COMPILER_SCRIPTS, ids=lambda p: p.stem)
def test_compiler_script_basm(script, monkeypatch):
    assert compile_normalised(script, monkeypatch) == expected_basm(script)


@pytest.mark.parametrize("script", BBZ_SCRIPTS, ids=lambda p: p.stem)
def test_bbz_script_basm(script, monkeypatch):
    table = read_bst(script.with_suffix(".bst"))
    assert compile_normalised(script, monkeypatch, table) == expected_basm(script)
