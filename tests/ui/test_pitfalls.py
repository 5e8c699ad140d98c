"""pitfalls: each BittyBuzz quirk of notes §D.6 is flagged at its token, and only there."""

from __future__ import annotations

from bbzide.ui.pitfalls import find_pitfalls


def flagged(text: str, floats: bool = True) -> list[tuple[int, int, str]]:
    return [(d.line, d.col, d.message.split()[0]) for d in find_pitfalls(text, floats)]


def test_each_pitfall_at_its_position() -> None:
    text = (
        "x = not y\n"
        "if (v < 1.5) { }\n"
        "m = a & b\n"
        "s = a << 2\n"
        "big = 40000\n"
        "small = -32768\n"
        "# not & 1.5 < in a comment\n"
        't = "not & <<"\n'
    )
    assert flagged(text) == [
        (1, 4, "BittyBuzz"),
        (2, 6, "comparing"),
        (3, 6, "`&`"),
        (4, 6, "`<<`"),
        (5, 6, "40000"),
    ]


def test_float_arithmetic_only_where_floats_are_missing() -> None:
    assert flagged("v = w * 0.5\n", floats=True) == []
    assert flagged("v = w * 0.5\n", floats=False) == [(1, 8, "this")]
    assert flagged("c = 2 < 3\n") == []
