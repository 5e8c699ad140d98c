"""The `.basm` writer: string table, labels, code chunks and the debug annotation of each line.

Design: like clox, the Buzz front end is a single-pass compiler. The parser (`parser.py`) calls
`emit` at exactly the moments the reference `bzzparse` emits, because each `.basm` line carries
the position of the parser's look-ahead token *at the moment of emission* (spec §B.3): an AST
walked afterwards would have to store one look-ahead position per emitted instruction, which is
the same information in a less obvious place. The parser still builds a syntax tree (see
`syntax_tree.py`) for the IDE, next to this output.

Buffers: `self.out` is where `emit` appends. An identifier reference collects its code in a
private buffer and index expressions / call arguments in their own buffers, then splices them
(spec §B.4 `idref`); `redirect` switches `out` for that.

Layout of the result (spec §B.3): `!N`, N string lines `'S`, an empty line, one registration
triple per named function, `\\tnop`, then every chunk in label order: an empty line,
`@__label_K`, its lines `\\tOP[ ARG]\\t|LINE,COL,FILE`.
"""

from __future__ import annotations

from collections.abc import Sequence

from bbzide.compiler.call_sites import CallLine, CallSite
from bbzide.compiler.scanner import Token


class CodeGenerator:
    def __init__(self, string_table: Sequence[str] | None = None) -> None:
        self.string_ids: dict[str, int] = {}
        self.strings: list[str] = []
        for line in string_table or ():
            self.string_id(line)
        self.label_counter = 0
        self.chunks: dict[int, list[str]] = {}
        self.registrations: list[tuple[int, int]] = []  # (string id, label)
        self.out: list[str] = []

    # -- strings and labels --------------------------------------------------------------

    def string_id(self, text: str) -> int:
        """Id of `text`, handing out the next id on first use (bzzparse `string_add`)."""
        sid = self.string_ids.get(text)
        if sid is None:
            sid = len(self.strings)
            self.string_ids[text] = sid
            self.strings.append(text)
        return sid

    def new_label(self) -> int:
        label = self.label_counter
        self.label_counter += 1
        return label

    def register_function(self, string_id: int, label: int) -> None:
        """A named function: `pushs S / pushcn @__label_L / gstore` in the prologue."""
        self.registrations.append((string_id, label))

    # -- chunks --------------------------------------------------------------------------

    def open_chunk(self, label: int) -> list[str]:
        """Start the code of a function body; returns the buffer to restore afterwards."""
        previous = self.out
        self.out = self.chunks[label] = []
        return previous

    def close_chunk(self, previous: list[str]) -> None:
        self.out = previous

    def redirect(self, buffer: list[str]) -> list[str]:
        previous = self.out
        self.out = buffer
        return previous

    # -- emission ------------------------------------------------------------------------

    def emit(self, op: str, lookahead: Token) -> None:
        self.out.append(f"\t{op}\t|{lookahead.annotation}")

    def emit_call(self, site: CallSite, lookahead: Token) -> None:
        """A `callc`, its line carrying the call's site (see `call_sites.py`)."""
        self.out.append(CallLine(f"\tcallc\t|{lookahead.annotation}", site))

    def call_lines(self) -> list[str]:
        """The chunk lines in `render` order (where the `CallLine`s are)."""
        return [line for label in sorted(self.chunks) for line in self.chunks[label]]

    def emit_label(self, label: int, lookahead: Token) -> None:
        self.out.append(f"@__label_{label}\t|{lookahead.annotation}")

    def emit_exit(self, lookahead: Token) -> None:
        self.out.append(f"\n@__exitpoint\t|{lookahead.annotation}")
        self.out.append(f"\tdone\t|{lookahead.annotation}")

    def render(self) -> str:
        parts = [f"!{len(self.strings)}\n"]
        parts.extend(f"'{s}\n" for s in self.strings)
        parts.append("\n")
        for sid, label in self.registrations:
            parts.append(f"\tpushs {sid}\n\tpushcn @__label_{label}\n\tgstore\n")
        parts.append("\tnop\n")
        for label in sorted(self.chunks):
            parts.append(f"\n@__label_{label}\n")
            for line in self.chunks[label]:
                parts.append(line)
                parts.append("\n")
        return "".join(parts)
