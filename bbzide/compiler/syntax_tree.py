"""Syntax tree of a Buzz script, with source positions, for the IDE (outline, go-to, hovers).

Design: one small generic node type rather than a class per construct. The code generator does
not walk this tree (the front end is single-pass, see `codegen.py`), so the tree only has to
answer "what is where": `kind` names the construct (`script`, `function`, `lambda`, `var`,
`assign`, `call`, `if`, `while`, `for`, `return`, `block`, `ref`), `name` carries the identifier
when there is one (function name, variable, assigned/called name), `params` the parameter names,
and `children` the nested statements in source order. A `ref` node is one use of an identifier
(the start of every `a`, `a.b`, `a[i]`, `a(...)`), with `scope` telling how the compiler resolved
it: `global (string id N)` or `local slot N` (the activation-record slot). Refs are children
of the statement they occur in, so `walk()` lists every use in source order. `line`/`col` are
those of the construct's first token (1-based line, 0-based column, as everywhere in bbzide).
"""

from __future__ import annotations

from dataclasses import dataclass, field


@dataclass(slots=True)
class Node:
    kind: str
    line: int
    col: int
    file: str | None
    name: str | None = None
    params: list[str] = field(default_factory=list)
    scope: str | None = None
    children: list[Node] = field(default_factory=list)

    def walk(self):
        """This node and all its descendants, depth first, in source order."""
        yield self
        for child in self.children:
            yield from child.walk()
