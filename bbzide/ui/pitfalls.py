"""BittyBuzz pitfalls visible in the source text, as editor warnings with line and column.

Buzz code that is fine on the desktop Buzz VM can mean something else on BittyBuzz (notes §D.6,
verified against the reference VM). These checks read tokens only, so they are cheap enough to
run on every keystroke's compile and they never block a program: they are warnings.

* `not x` pushes the *truth value* of x on BittyBuzz (`not 0` is 0, `not 5` is 1).
* A comparison with a float literal compares raw 16-bit payloads, unsigned (`1.5 < 2` is false).
* `&` and `|` are logical, not bitwise (`6 & 3` is 1).
* `<<` and `>>` are not implemented (the robot stops with an INSTR error).
* Integers are int16: literals outside -32768..32767 are truncated by bo2bbo.
* On platforms without float operations (Kilobot) arithmetic on a float is a TYPE error.
"""

from __future__ import annotations

import re
from dataclasses import dataclass

from bbzide.ui.program_session import Diagnostic

#: Buzz tokens that matter here: comments and strings are skipped whole (same rules as the lexer).
_TOKEN = re.compile(
    r"(?P<comment>#[^\n]*)|(?P<string>\"(?:\\.|[^\"\\])*\"|'(?:\\.|[^'\\])*')"
    r"|(?P<number>\d[\d.]*)|(?P<word>[A-Za-z][A-Za-z0-9_]*)"
    r"|(?P<op><<|>>|==|!=|<=|>=|[<>&|+\-*/%^])|(?P<newline>\n)|(?P<other>\S)"
)
INT16_MIN, INT16_MAX = -32768, 32767
COMPARISONS = {"==", "!=", "<", "<=", ">", ">="}
ARITHMETIC = {"+", "-", "*", "/", "%", "^"}


@dataclass(frozen=True)
class _Token:
    kind: str
    text: str
    line: int
    col: int


def _tokens(text: str) -> list[_Token]:
    tokens: list[_Token] = []
    line, line_start = 1, 0
    for match in _TOKEN.finditer(text):
        kind = match.lastgroup or "other"
        start = match.start()
        if kind == "newline":
            line, line_start = line + 1, match.end()
            continue
        if kind in ("comment",):
            continue
        tokens.append(_Token(kind, match.group(), line, start - line_start))
        if kind == "string":
            newlines = match.group().count("\n")
            if newlines:
                line += newlines
                line_start = start + match.group().rfind("\n") + 1
    return tokens


def find_pitfalls(text: str, floats_supported: bool = True) -> list[Diagnostic]:
    tokens = _tokens(text)
    found: list[Diagnostic] = []

    def warn(token: _Token, message: str) -> None:
        found.append(Diagnostic(token.line, token.col, message, "warning"))

    for position, token in enumerate(tokens):
        before = tokens[position - 1] if position else None
        after = tokens[position + 1] if position + 1 < len(tokens) else None
        neighbours = [t for t in (before, after) if t is not None]
        if token.kind == "word" and token.text == "not":
            warn(token, "BittyBuzz `not x` gives the truth value of x (not 0 is 0): write `x == 0`")
        elif token.kind == "op" and token.text in COMPARISONS:
            if any(t.kind == "number" and "." in t.text for t in neighbours):
                warn(
                    token,
                    "comparing with a float compares raw 16-bit payloads unsigned on "
                    "BittyBuzz (1.5 < 2 is false)",
                )
        elif token.kind == "op" and token.text in ("&", "|"):
            warn(token, f"`{token.text}` is logical on BittyBuzz (6 & 3 is 1), not bitwise")
        elif token.kind == "op" and token.text in ("<<", ">>"):
            warn(token, f"`{token.text}` is not implemented on BittyBuzz: the robot stops (INSTR)")
        elif token.kind == "number" and "." not in token.text:
            value = int(token.text)
            negative = before is not None and before.text == "-"
            if value > (-INT16_MIN if negative else INT16_MAX):
                warn(
                    token,
                    f"{'-' if negative else ''}{value} does not fit in BittyBuzz's int16: "
                    "it is truncated",
                )
        elif token.kind == "number" and not floats_supported:
            if any(t.kind == "op" and t.text in ARITHMETIC for t in neighbours):
                warn(
                    token,
                    "this platform has no float operations: arithmetic on a float "
                    "stops the robot (TYPE error)",
                )
    return found
