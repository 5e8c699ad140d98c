"""The syntax tree the IDE reads: constructs, names, parameters, positions, symbol resolution."""

from __future__ import annotations

from bbzide.compiler.frontend import compile_to_basm

SOURCE = """x = 1
function f(a, b) {
  var c = a + b
  return c
}
g = function(q) { return q }
if (x) { log(f(1, 2)) }
"""


def test_outline_and_positions(tmp_path):
    script = tmp_path / "t.bzz"
    script.write_text(SOURCE)
    tree = compile_to_basm(script).tree
    top = [(n.kind, n.name, n.line, n.col) for n in tree.children if n.kind != "ref"]
    assert top == [("assign", "x", 1, 0), ("function", "f", 2, 0), ("assign", "g", 6, 0),
                   ("if", None, 7, 0)]
    function = tree.children[1]
    assert function.params == ["a", "b"]
    assert [(n.kind, n.name) for n in function.children] == [("var", "c"), ("return", None)]
    assert [n.name for n in tree.children[0].children] == ["x"]  # the ref of the assignment
    lam = next(n for n in tree.walk() if n.kind == "lambda")
    assert (lam.line, lam.col, lam.params) == (6, 4, ["q"])
    assert tree.file == str(script.resolve())


def test_references_say_how_names_resolve(tmp_path):
    script = tmp_path / "t.bzz"
    script.write_text(SOURCE)
    refs = [(n.name, n.line, n.col, n.scope) for n in compile_to_basm(script).tree.walk()
            if n.kind == "ref"]
    assert ("a", 3, 10, "local slot 1") in refs
    assert ("c", 4, 9, "local slot 3") in refs
    assert ("log", 7, 9, "global (string id 3)") in refs  # x=0, f=1, g=2, log=3
