"""Entry point of the Buzz compiler front end: a `.bzz` script -> `.basm` text (bzzparse's job).

`compile_to_basm` reads the script (or takes the editor buffer), runs the single-pass
parser/code generator and returns the `.basm` text, the syntax tree, warnings and the files
that were included. All user mistakes raise `bbzide.diagnostics.CompileError` with the
reference's line:col.

Quirk decisions (`reference_quirks=False`, the default, vs `True`, byte-for-byte bzzparse):

| reference behaviour | default mode | reference mode |
|---|---|---|
| string escapes over-read: `"tab\\there"` -> `tab<TAB>here"` | decoded correctly (`tab<TAB>here`), warning "bzzc would compile this string as ..." | over-read reproduced |
| `\\n` escape puts a raw newline into the `.basm` (bzzasm rejects it) | kept (the string means a newline), warning | kept |
| any word starting with `include` is an include directive (`included_count = 1` fails) | an identifier, with a warning that bzzc rejects it | directive (error "expected string after include") |
| include looked up only in the CWD and the include path | then also next to the including file (warning says so) | CWD and include path only |
| `_` not allowed as first identifier character | rejected in both, with a hint (code must still build with bzzc) | rejected |
| `not` negates the whole rest of the condition | kept (changing it would change program meaning vs bzzc) | kept |
| no short-circuit for `and`/`or` | kept (same reason) | kept |
| `var` in a top-level `if/while/for` block makes a local with no function active (bzzrun crashes) | same code, warning | same code |
| a stray top-level `}` silently ends the script | CompileError "unmatched }" | rest of file ignored |
| bare identifier as the last statement crashes bzzparse | CompileError "expected function call or assignment" | same error |
| errors at end of file have no position | position of the last token | same |
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from dataclasses import dataclass, field

from bbzide.compiler import scanner as T
from bbzide.compiler.codegen import CodeGenerator
from bbzide.compiler.parser import Parser
from bbzide.compiler.scanner import Scanner, user_text
from bbzide.compiler.syntax_tree import Node
from bbzide.diagnostics import CompileError, SourceLocation


@dataclass
class FrontendResult:
    basm: str
    tree: Node
    warnings: list[str] = field(default_factory=list)
    included_files: list[str] = field(default_factory=list)


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
        data = source.encode("utf-8", errors="surrogateescape")
    warnings: list[str] = []
    scanner = Scanner(path_text, data, include_path=include_path,
                      reference_quirks=reference_quirks, warn=warnings.append)
    codegen = CodeGenerator([T.bytes_text(s.encode("utf-8", errors="surrogateescape"))
                             for s in string_table or ()])
    parser = Parser(scanner, codegen, path_text, reference_quirks=reference_quirks,
                    warn=warnings.append)
    try:
        tree = parser.parse_script()
    except RecursionError:
        tok = parser.tok
        raise CompileError("script nested too deeply to compile",
                           SourceLocation(user_text(tok.file or path_text), tok.line, tok.col)
                           ) from None
    for text in codegen.strings:
        if "\n" in text:
            warnings.append(f"the string {user_text(text)!r} contains a newline: bzzasm "
                            "cannot assemble it (the .basm string table is one string per line)")
    basm = codegen.render()
    return FrontendResult(user_text(basm), tree, warnings, scanner.included_files)
