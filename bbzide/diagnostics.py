"""User-facing errors: one exception type per room, each rendered as a one-screen message.

Every error a user can cause (a syntax error, a malformed `.bo`/`.bbo`/`.rrd`, bad command-line
parameters) is raised as a `UserError` subclass carrying where it happened. The CLI catches
`UserError`, prints `render()` and exits 1; nothing else may reach the user as a traceback.

`SourceLocation` is the one position type of the project: compiler diagnostics, debug maps and
VM errors (pc -> source) all use it.
"""

from __future__ import annotations

import unicodedata
from dataclasses import dataclass
from pathlib import Path


@dataclass(frozen=True, slots=True)
class SourceLocation:
    """A position in a source file: 1-based line, 0-based column (the reference's convention)."""

    file: str
    line: int
    col: int

    def __str__(self) -> str:
        return f"{self.file}:{self.line}:{self.col}"


class UserError(Exception):
    """An error caused by the user's input, shown without a traceback.

    `location` (optional) points into a source file; `source_line` is that line's text when known,
    so `render()` can show it with a caret under the column; `hint` (optional) is shown last,
    after the line: what the user can do about it.
    """

    def __init__(
        self,
        message: str,
        location: SourceLocation | None = None,
        source_line: str | None = None,
        hint: str | None = None,
    ) -> None:
        super().__init__(message)
        self.message = message
        self.location = location
        self.source_line = source_line
        self.hint = hint

    def render(self) -> str:
        """The error as the CLI prints it: `file:line:col: message`, the line, a caret."""
        hint = f"\n  hint: {self.hint}" if self.hint else ""
        if self.location is None:
            return f"error: {self.message}{hint}"
        text = f"{self.location}: error: {self.message}"
        line = self.source_line
        if line is None:
            line = _read_line(self.location.file, self.location.line)
        if line is not None and not _shows_as_text(line):
            line = None  # control bytes or undecodable ones (a binary file): the position is enough
        if line is not None:
            line = line.rstrip("\r\n").replace("\t", " ")
            caret_col = max(0, min(self.location.col, len(line)))
            text += f"\n  {line}\n  {' ' * caret_col}^"
        return text + hint


class CompileError(UserError):
    """A Buzz source that cannot be compiled (lexer, parser, include, assembler errors)."""


class BytecodeError(UserError):
    """A `.bo`, `.bbo` or `.bdb` file that is truncated or malformed."""


def _shows_as_text(line: str) -> bool:
    """Whether a source line can be printed as it is: no control character but tab and line
    ends (a NUL or an escape sequence would reach the terminal raw), no byte that did not
    decode (shown as U+FFFD)."""
    return not any(
        (unicodedata.category(ch) == "Cc" and ch not in "\t\r\n") or ch == "\ufffd"
        for ch in line)


def _read_line(file: str, line: int) -> str | None:
    try:
        lines = Path(file).read_text(encoding="utf-8", errors="replace").splitlines()
    except OSError:
        return None
    if 1 <= line <= len(lines):
        return lines[line - 1]
    return None
