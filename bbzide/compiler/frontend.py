"""Entry point of the Buzz compiler front end: a `.bzz` script -> `.basm` text (bzzparse's job).

`compile_to_basm` reads the script (or takes the editor buffer), runs the single-pass
parser/code generator and returns the `.basm` text, the syntax tree, warnings and the files
that were included. All user mistakes raise `bbzide.diagnostics.CompileError` with the
reference's line:col.

Quirk decisions. `reference_quirks=True` reproduces bzzparse byte for byte (the corpus tests use
it); the default mode is for users. Each row: reference behaviour -> default / reference mode.

1. String escapes over-read (`"tab\\there"` becomes `tab<TAB>here"`, spec §A.2).
   default: decoded as written (`tab<TAB>here`) + warning "bzzc would compile this string as ...";
   reference: the over-read is reproduced.
2. A `\\n` escape puts a raw newline into the `.basm` string table (bzzasm then rejects it).
   default: kept (the string means a newline) + warning; reference: kept.
3. Any word starting with `include` is an include directive (`included_count = 1` fails).
   default: such a word is an identifier + warning that bzzc rejects it;
   reference: directive ("Syntax error: expected string after include").
4. Includes are looked up in the process CWD, then the include path (BUZZ_INCLUDE_PATH).
   default: then also in the including file's folder (extension) + warning;
   reference: CWD and include path only ("Can't read ...").
5. `_` is not accepted as the first character of an identifier.
   both: rejected ("unknown character '_'") with a hint: scripts must still build with bzzc.
6. `not` negates the whole rest of the condition (`not a and b` = `not (a and b)`).
   both: kept; changing it would give a program that behaves differently on the robot.
7. `and` / `or` do not short-circuit (both operands are evaluated).
   both: kept, same reason.
8. `var` in a top-level `if`/`while`/`for` block makes a local with no function active
   (lstore/lload at top level; bzzrun crashes on it).
   default: same code + warning; reference: same code, no warning.
9. A stray top-level `}` silently ends the script (the rest of the file is ignored).
   default: CompileError "unmatched }"; reference: the rest is ignored.
10. A bare identifier as the last statement crashes bzzparse (SIGSEGV).
   both: CompileError "expected function call or assignment" at the identifier.
11. Errors at the end of the file carry no position (`NAME.bzz: Syntax error: ...`).
   both: the same message, located at the last token of the script.
   Lexer errors are reported one column left of the character (as the reference); for a
   character in column 0 we report column 0, not -1.
12. An include cycle (a file includes one that is still being read) is skipped silently.
   default: skipped (same code) + warning naming the cycle; reference: skipped, no warning.
13. A script without statements (empty, or only comments) compiles to a lone `nop` with no
   `done` (corpus: empty_file): a robot runs past its end and stops with a PC error.
   default: same code + warning; reference: same code, no warning.
14. Not quirks but easy to trip on, kept in both modes as the reference: `0x1F` is `0` then
   `x1F`; `1.2.3` is a float; newlines and `;` are optional separators
   (`for (i = 0; ...)` fails with "expected ,").
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from dataclasses import dataclass, field

from bbzide.compiler import scanner as T
from bbzide.compiler.call_sites import ScriptSymbols
from bbzide.compiler.codegen import CodeGenerator
from bbzide.compiler.parser import Parser
from bbzide.compiler.scanner import Scanner, user_text
from bbzide.compiler.syntax_tree import Node
from bbzide.diagnostics import CompileError


@dataclass
class FrontendResult:
    basm: str
    tree: Node
    warnings: list[str] = field(default_factory=list)
    included_files: list[str] = field(default_factory=list)
    #: the chunk lines in `.basm` order; the `callc` ones carry their call site (call_sites.py)
    code_lines: list[str] = field(default_factory=list)
    symbols: ScriptSymbols = field(default_factory=ScriptSymbols)
    #: the main script's text as compiled (error lines are read from it, not from the disk)
    source_text: str = ""


def compile_to_basm(path: str | os.PathLike, *, source: str | None = None,
                    include_path: Sequence[str] = (), string_table: Sequence[str] | None = None,
                    reference_quirks: bool = False) -> FrontendResult:
    """Compile one Buzz script to `.basm` text (see the module docstring for the quirk table)."""
    path_text = os.fspath(path)
    if source is None:
        try:
            with open(path_text, "rb") as handle:
                data = handle.read()
        except OSError as exc:
            raise CompileError(f"Can't read '{path_text}': {exc.strerror}") from None
    else:
        data = _source_bytes(source)
    warnings: list[str] = []
    scanner = Scanner(path_text, data, include_path=include_path,
                      reference_quirks=reference_quirks, warn=warnings.append)
    codegen = CodeGenerator([T.bytes_text(_source_bytes(s)) for s in string_table or ()])
    parser = Parser(scanner, codegen, path_text, reference_quirks=reference_quirks,
                    warn=warnings.append)
    try:
        tree = parser.parse_script()
    except RecursionError:
        tok = parser.tok if parser.tok.kind != T.EOF else scanner.last
        if tok.file is None:
            raise CompileError("script nested too deeply to compile") from None
        raise scanner.error_at(tok, "script nested too deeply to compile (Python's recursion "
                                    "limit; split the expression or the nested blocks)") from None
    for text in codegen.strings:
        if "\n" in text:
            warnings.append(f"the string {user_text(text)!r} contains a newline: bzzasm "
                            "cannot assemble it (the .basm string table is one string per line)")
    # back from one-char-per-byte to text; bytes that are not UTF-8 survive as surrogates, so
    # `basm.encode("utf-8", "surrogateescape")` gives exactly the bytes bzzparse writes
    basm = codegen.render().encode("latin-1").decode("utf-8", errors="surrogateescape")
    text = source if source is not None else data.decode("utf-8", errors="replace")
    return FrontendResult(basm, tree, warnings, scanner.included_files, codegen.call_lines(),
                          parser.symbols, text)


def _source_bytes(text: str) -> bytes:
    """Editor text -> the bytes bzzc would read (surrogate-escaped bytes restored)."""
    try:
        return text.encode("utf-8", errors="surrogateescape")
    except UnicodeEncodeError:  # a lone surrogate that is no escaped byte
        return text.encode("utf-8", errors="replace")
