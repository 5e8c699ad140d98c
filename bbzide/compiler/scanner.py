"""The Buzz lexer: source text -> tokens, `include` handled inside the lexer (as bzzparse does).

Design: a pull scanner. The parser asks for one token at a time (`next_token`), so lexer errors
surface in the same order as in the reference (a syntax error earlier in the file wins over an
unknown character later). Newlines and `;` (STATEND) are never handed to the parser: the
reference parser's token fetch skips them everywhere, so the scanner drops them here.

Text model: the reference works on bytes and its columns are byte offsets (a TAB counts 1). We
decode files as latin-1 so that one character = one byte; `frontend.py` converts the final
`.basm` text back. Every file gets one extra newline appended, as the reference does.

`include "file"` is a *prefix* test at every token start (the reference's quirk: `included_x`
is taken as a directive). Files are found relative to the process CWD, then each include-path
directory, then (our extension, off in reference mode) the including file's directory. A file is
skipped while it is still open on the include stack (a cycle: skipped with a warning, as the
reference skips it silently); included again later, it is re-read.

Positions: `line` 1-based, `col` 0-based byte offset in the line. Lexer-error columns are one
less than the character's column, exactly as the reference prints them (corpus README §6).
The end-of-file token has line 0, col 1 and no file, printed `(null)` in debug annotations.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Sequence
from dataclasses import dataclass

from bbzide.diagnostics import CompileError, SourceLocation

# Token kinds, with the description the reference prints in "expected X, found Y".
ID = "identifier"
CONST = "numeric constant"
STRING = "string"
VAR = "variable"
NIL = "nil"
IF = "if"
ELSE = "else"
FUN = "function"
RETURN = "return"
FOR = "for"
WHILE = "while"
LANDOR = "logic and/or"
LNOT = "logic not"
ADDSUB = "+ or -"
MULDIV = "* or /"
MOD = "%"
POW = "^"
LRSHIFT = "bit shift"
BANDOR = "bitwise and/or"
BNOT = "bitwise not"
BLOCKOPEN = "{"
BLOCKCLOSE = "}"
PAROPEN = "("
PARCLOSE = ")"
IDXOPEN = "["
IDXCLOSE = "]"
LISTSEP = ","
ASSIGN = "="
DOT = "."
CMP = "== != < <= > >="
EOF = "end-of-file"

KEYWORDS: dict[str, str] = {
    "var": VAR, "nil": NIL, "if": IF, "else": ELSE, "function": FUN, "return": RETURN,
    "for": FOR, "while": WHILE, "and": LANDOR, "or": LANDOR, "not": LNOT,
}
SINGLE_CHAR: dict[str, str] = {
    "{": BLOCKOPEN, "}": BLOCKCLOSE, "(": PAROPEN, ")": PARCLOSE, "[": IDXOPEN, "]": IDXCLOSE,
    ",": LISTSEP, ".": DOT, "+": ADDSUB, "-": ADDSUB, "*": MULDIV, "/": MULDIV, "%": MOD,
    "^": POW, "&": BANDOR, "|": BANDOR,
}
WHITESPACE = " \t\r"
IDENTIFIER_CHARS = frozenset("abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ0123456789_")
ESCAPES = {"n": "\n", "t": "\t", "\\": "\\"}
_INCLUDE = "include"


@dataclass(frozen=True, slots=True)
class Token:
    kind: str
    text: str
    line: int
    col: int
    file: str | None  # realpath (latin-1 text form); None for end of file

    @property
    def annotation(self) -> str:
        """The `LINE,COL,FILE` debug suffix bzzparse writes for this look-ahead token."""
        return f"{self.line},{self.col},{self.file if self.file is not None else '(null)'}"


EOF_TOKEN = Token(EOF, "", 0, 1, None)


def bytes_text(data: bytes) -> str:
    """Bytes -> one character per byte (the reference's byte-offset columns)."""
    return data.decode("latin-1")


def user_text(byte_text: str) -> str:
    """Inverse of `bytes_text` for text shown to users (UTF-8 where it decodes)."""
    return byte_text.encode("latin-1").decode("utf-8", errors="replace")


@dataclass(slots=True)
class _OpenFile:
    text: str
    path: str  # realpath in byte-text form
    display: str  # the name as given (used in messages)
    pos: int = 0
    line: int = 1
    line_start: int = 0


class Scanner:
    """Pull lexer over a stack of open files (the main script and its active includes)."""

    def __init__(self, path: str, source_bytes: bytes, *, include_path: Sequence[str] = (),
                 reference_quirks: bool = False,
                 warn: Callable[[str], None] | None = None) -> None:
        self.include_path = list(include_path)
        self.reference_quirks = reference_quirks
        self.warn = warn or (lambda message: None)
        self.included_files: list[str] = []
        self.stack: list[_OpenFile] = []
        self.texts: dict[str, str] = {}  # realpath -> text of every file read (for messages)
        self.main_realpath = bytes_text(os.fsencode(os.path.realpath(path)))
        self._push(source_bytes, self.main_realpath, str(path))
        self.last: Token = EOF_TOKEN  # the last real token handed out

    # -- files ---------------------------------------------------------------------------

    def _push(self, data: bytes, realpath: str, display: str) -> None:
        self.stack.append(_OpenFile(bytes_text(data) + "\n", realpath, display))
        self.texts.setdefault(realpath, self.stack[-1].text)

    def source_line(self, realpath: str | None, line: int) -> str | None:
        """Line `line` (1-based) of a file this scanner read, as the user wrote it."""
        text = self.texts.get(realpath) if realpath is not None else None
        if text is None:
            return None
        lines = text.split("\n")
        return user_text(lines[line - 1]) if 1 <= line <= len(lines) else None

    def error_at(self, token: Token, message: str) -> CompileError:
        """A CompileError located at `token` (which must come from a file, not EOF)."""
        return CompileError(message, SourceLocation(user_text(token.file or ""), token.line,
                                                    token.col),
                            self.source_line(token.file, token.line))

    def _error(self, f: _OpenFile, message: str, col: int, line: int | None = None) -> CompileError:
        line = f.line if line is None else line
        return CompileError(message, SourceLocation(user_text(f.path), line, col),
                            self.source_line(f.path, line))

    def _find_include(self, name: str, f: _OpenFile) -> str | None:
        candidates = [name]
        if not os.path.isabs(name):
            for directory in self.include_path:
                if directory:
                    candidates.append(os.path.join(directory, name))
            if not self.reference_quirks:
                candidates.append(os.path.join(os.path.dirname(user_text(f.path)), name))
        for index, candidate in enumerate(candidates):
            if os.path.isfile(candidate):
                if index == len(candidates) - 1 and index > len(self.include_path) \
                        and not self.reference_quirks:
                    self.warn(f"include '{name}' found next to the including file "
                              f"({candidate}); bzzc only looks in the working directory "
                              "and BUZZ_INCLUDE_PATH")
                return candidate
        return None

    def _include(self, f: _OpenFile) -> None:
        text = f.text
        pos = f.pos + len(_INCLUDE)
        while pos < len(text) and text[pos] in " \t":
            pos += 1
        quote = text[pos] if pos < len(text) else ""
        if quote not in ("'", '"'):
            raise self._error(f, "Syntax error: expected string after include "
                                 "(write: include \"file.bzz\")", pos - f.line_start)
        end = pos + 1
        while end < len(text) and text[end] != quote:
            if text[end] == "\n":
                raise self._error(f, "Syntax error: expected end of string", end - f.line_start)
            end += 1
        if end >= len(text):
            raise self._error(f, "Syntax error: expected end of string", end - f.line_start)
        name = text[pos + 1:end]
        f.pos = end + 1
        found = self._find_include(user_text(name), f)
        if found is None:
            raise self._error(f, f"Can't read '{user_text(name)}' (looked in the working "
                                 "directory and the include path)", f.pos - f.line_start)
        realpath = bytes_text(os.fsencode(os.path.realpath(found)))
        if any(open_file.path == realpath for open_file in self.stack):
            # still open: an include cycle. The reference skips the include silently (corpus
            # include_cycle.bzz); we skip it too, so the bytecode is identical, and say so.
            if not self.reference_quirks:
                chain = " -> ".join(os.path.basename(user_text(o.path)) for o in self.stack)
                self.warn(f"{user_text(f.path)}:{f.line}:{f.pos - f.line_start}: include cycle "
                          f"({chain} -> {os.path.basename(user_text(realpath))}): "
                          f"'{user_text(name)}' is still being read, so this include is skipped")
            return
        try:
            with open(found, "rb") as handle:
                data = handle.read()
        except OSError:
            raise self._error(f, f"Can't read '{user_text(name)}'", f.pos - f.line_start) from None
        self.included_files.append(user_text(realpath))
        self._push(data, realpath, found)

    # -- tokens --------------------------------------------------------------------------

    def next_token(self) -> Token:
        """The next token that is not a statement end (newline or `;`)."""
        token = self._scan()
        if token.kind != EOF:
            self.last = token
        return token

    def _scan(self) -> Token:
        while self.stack:
            f = self.stack[-1]
            text = f.text
            pos = f.pos
            n = len(text)
            while pos < n and text[pos] in WHITESPACE:
                pos += 1
            f.pos = pos
            if pos >= n:
                self.stack.pop()
                continue
            c = text[pos]
            if c == "\n" or c == ";":
                if c == "\n":
                    f.line += 1
                    f.line_start = pos + 1
                f.pos = pos + 1
                continue
            if c == "#":
                end = text.find("\n", pos)
                end = n - 1 if end < 0 else end
                f.pos = end + 1
                f.line += 1
                f.line_start = end + 1
                continue
            if text.startswith(_INCLUDE, pos):
                after = text[pos + len(_INCLUDE)] if pos + len(_INCLUDE) < n else ""
                continues_word = after.isascii() and (after.isalnum() or after == "_")
                if self.reference_quirks or not continues_word:
                    self._include(f)
                    continue
                self.warn(f"{user_text(f.path)}:{f.line}:{pos - f.line_start}: bzzc takes any word "
                          "starting with 'include' for an include directive and rejects this "
                          "identifier; rename it to run on a real robot")
            col = pos - f.line_start
            line = f.line
            if c.isascii() and c.isalpha():
                end = pos + 1
                while end < n and text[end] in IDENTIFIER_CHARS:
                    end += 1
                word = text[pos:end]
                f.pos = end
                return Token(KEYWORDS.get(word, ID), word, line, col, f.path)
            if "0" <= c <= "9":
                end = pos + 1
                while end < n and ("0" <= text[end] <= "9" or text[end] == "."):
                    end += 1
                f.pos = end
                return Token(CONST, text[pos:end], line, col, f.path)
            if c in SINGLE_CHAR:
                f.pos = pos + 1
                return Token(SINGLE_CHAR[c], c, line, col, f.path)
            nxt = text[pos + 1] if pos + 1 < n else ""
            if c == "=":
                if nxt == "=":
                    f.pos = pos + 2
                    return Token(CMP, "==", line, col, f.path)
                f.pos = pos + 1
                return Token(ASSIGN, "=", line, col, f.path)
            if c == "!":
                if nxt == "=":
                    f.pos = pos + 2
                    return Token(CMP, "!=", line, col, f.path)
                f.pos = pos + 1
                return Token(BNOT, "!", line, col, f.path)
            if c in "<>":
                if nxt == c:
                    f.pos = pos + 2
                    return Token(LRSHIFT, c + c, line, col, f.path)
                if nxt == "=":
                    f.pos = pos + 2
                    return Token(CMP, c + "=", line, col, f.path)
                f.pos = pos + 1
                return Token(CMP, c, line, col, f.path)
            if c in "'\"":
                return self._string(f, pos, line, col)
            shown = user_text(c) if ord(c) < 128 and c.isprintable() else f"\\x{ord(c):02x}"
            raise self._error(f, f"Syntax error: unknown character '{shown}' (octal: {ord(c):o}; "
                                 f"hex: {ord(c):x})" + _unknown_char_hint(c, f.text),
                              _lexer_col(col))
        return EOF_TOKEN

    def _string(self, f: _OpenFile, start: int, line: int, col: int) -> Token:
        text = f.text
        n = len(text)
        quote = text[start]
        end = start + 1
        line_now, line_start = f.line, f.line_start
        while True:
            if end >= n:
                raise self._error(f, "Syntax error: string closing quote not found",
                                  _lexer_col(col), line)
            ch = text[end]
            if ch == quote and not (text[end - 1] == "\\" and text[end - 2] != "\\"):
                break
            if ch == "\n":
                line_now += 1
                line_start = end + 1
            end += 1
        f.pos = end + 1
        f.line, f.line_start = line_now, line_start
        raw = text[start + 1:end]
        value = decode_escapes(raw)
        if "\\" in raw:
            quirky = _reference_decode(text, start + 1, len(raw))
            if quirky != value:
                if self.reference_quirks:
                    value = quirky
                else:
                    self.warn(f"{user_text(f.path)}:{line}:{col}: bzzc would compile this string "
                              f"as {user_text(quirky)!r} (its escape decoding reads past the "
                              f"closing quote); compiled as {user_text(value)!r}")
        if not self.reference_quirks:
            for character, why in _UNSTORABLE.items():
                if character in value:
                    raise self._error(f, f"Syntax error: a string cannot hold {why}", col, line)
        return Token(STRING, value, line, col, f.path)


#: Characters the bytecode cannot store in a string (frontend quirk table, rows 2 and 15): the
#: `.basm` string table is one string per line, and the `.bo` ends each string at a NUL byte.
_UNSTORABLE = {
    "\n": "a line break (the bytecode's string table keeps one string per line): "
          "use two strings",
    "\0": "a NUL byte (the bytecode ends each string at NUL)",
}


def decode_escapes(raw: str) -> str:
    """The string a user means: `\\n` newline, `\\t` tab, `\\\\` backslash, `\\c` -> c."""
    out: list[str] = []
    i = 0
    while i < len(raw):
        ch = raw[i]
        if ch == "\\" and i + 1 < len(raw):
            out.append(ESCAPES.get(raw[i + 1], raw[i + 1]))
            i += 2
        else:
            out.append(ch)
            i += 1
    return "".join(out)


def _reference_decode(text: str, start: int, length: int) -> str:
    """bzzparse's decoder: emits `length` (raw) bytes, 2 source bytes per escape -> over-read.

    The source buffer ends with the appended newline and a NUL, which ends the C string.
    """
    buffer = text + "\0"
    out: list[str] = []
    i = start
    while len(out) < length:
        ch = buffer[i] if i < len(buffer) else "\0"
        if ch == "\\":
            nxt = buffer[i + 1] if i + 1 < len(buffer) else "\0"
            out.append(ESCAPES.get(nxt, nxt))
            i += 2
        else:
            out.append(ch)
            i += 1
    result = "".join(out)
    nul = result.find("\0")
    return result if nul < 0 else result[:nul]


def _unknown_char_hint(c: str, text: str) -> str:
    if c == "_":
        return " (Buzz identifiers must start with a letter)"
    if _reads_as_binary(text):
        return " (the file is not text: is it a Buzz script?)"
    return ""


def _reads_as_binary(text: str) -> bool:
    """A file (one character per byte) that holds a NUL byte or is not UTF-8: git's and
    grep's test for a binary file, with UTF-8 as the only text encoding a script may use."""
    if "\0" in text:
        return True
    try:
        text.encode("latin-1").decode("utf-8")
    except UnicodeDecodeError:
        return True
    return False


def _lexer_col(col: int) -> int:
    """Column the reference prints for a lexer error: one left of the character (corpus README
    §6). At column 0 that would be -1; we print 0, since a column cannot be negative."""
    return max(col - 1, 0)
