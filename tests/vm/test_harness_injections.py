"""The --inject parser reads every corpus injection file and rejects malformed lines cleanly."""

from __future__ import annotations

import pytest
from corpus import BBZ_DIR
from hypothesis import given
from hypothesis import strategies as st

from bbzide.harness.injections import InjectionError, parse_injection_file, parse_injection_line

INJECTION_FILES = sorted(BBZ_DIR.glob("*.inj"))


def test_corpus_has_injection_files() -> None:
    assert len(INJECTION_FILES) >= 10


@pytest.mark.parametrize("path", INJECTION_FILES, ids=lambda p: p.stem)
def test_every_corpus_line_parses(path) -> None:
    lines = [t for t in path.read_text().splitlines() if t.split("#", 1)[0].strip()]
    injections = parse_injection_file(path)
    assert len(injections) == len(lines)
    for injection in injections:
        assert injection.step >= 1
        assert injection.kind in ("bc", "vput", "vquery", "nb")
        if injection.kind == "nb":
            assert injection.position is not None and injection.value is None
        else:
            assert injection.topic and injection.value is not None


def test_broadcast_with_position() -> None:
    inj = parse_injection_line('3 bc 2 "hello" int 7 90 30 0')
    assert inj is not None and inj.topic == "hello" and inj.value.text == "7"
    assert inj.position.distance == 90 and inj.position.azimuth == 30


def test_comment_and_blank() -> None:
    assert parse_injection_line("# STEP bc ...") is None
    assert parse_injection_line("   ") is None


MALFORMED = [
    "x bc 1 t int 1", "1 zz 1 2 3 4", "1 vput 1 k int 3 300", "1 nb 1 2", "1 bc 1 t blob 1",
]


@pytest.mark.parametrize("line", MALFORMED)
def test_malformed_lines_raise_user_error(line: str) -> None:
    with pytest.raises(InjectionError):
        parse_injection_line(line)


@given(st.text(max_size=60))
def test_garbage_never_crashes(text: str) -> None:
    try:
        parse_injection_line(text)
    except InjectionError:
        pass
