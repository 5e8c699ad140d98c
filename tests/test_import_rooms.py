"""The rooms of `bbzide/` import one way: no import cycle, and no room imports a higher one.

Every `import` statement that runs counts, including the lazy ones inside functions (a cycle
that only closes at run time is still a cycle a reader must untangle); imports under
`if TYPE_CHECKING:` never run and name types only, so they do not. `from P import X`
is an edge to the module `P.X` when that is a module, else to `P` (and so to a package's
`__init__`, which is how a package importing its own submodules closes a cycle).
"""

from __future__ import annotations

import ast
from pathlib import Path

PACKAGE = Path(__file__).resolve().parent.parent / "bbzide"

#: The rooms from lowest to highest; a module may import its own room and the ones below.
#: `harness` (the corpus harness) and `worlds` both sit on the VM model and never use each
#: other; `cli` and `__main__` route to every room's commands, so they are the top.
ROOM_RANK = {
    "diagnostics": 0,
    "compiler": 1,
    "vm": 2,
    "harness": 3,
    "worlds": 3,
    "recording": 4,
    "debugger": 5,
    "lessons": 6,
    "ui": 7,
    "cli": 8,
    "__main__": 9,
    "__init__": 8,
}


def module_name(path: Path) -> str:
    parts = list(path.relative_to(PACKAGE.parent).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def runtime_nodes(tree: ast.AST) -> list[ast.AST]:
    """Every node of `tree` except the bodies of `if TYPE_CHECKING:` blocks."""
    found: list[ast.AST] = []
    pending = [tree]
    while pending:
        node = pending.pop()
        found.append(node)
        if isinstance(node, ast.If) and "TYPE_CHECKING" in ast.unparse(node.test):
            pending.extend(node.orelse)
            continue
        pending.extend(ast.iter_child_nodes(node))
    return found


def import_graph() -> dict[str, set[str]]:
    modules = {module_name(path): path for path in PACKAGE.rglob("*.py")}
    graph: dict[str, set[str]] = {}
    for name, path in modules.items():
        targets: set[str] = set()
        for node in runtime_nodes(ast.parse(path.read_text(), str(path))):
            if isinstance(node, ast.Import):
                targets |= {alias.name for alias in node.names}
            elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
                for alias in node.names:
                    submodule = f"{node.module}.{alias.name}"
                    targets.add(submodule if submodule in modules else node.module)
        graph[name] = {target for target in targets if target in modules and target != name}
    return graph


def strongly_connected(graph: dict[str, set[str]]) -> list[set[str]]:
    """Tarjan's components of more than one module: each is an import cycle."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    found: list[set[str]] = []

    def visit(node: str) -> None:
        index[node] = low[node] = len(index)
        stack.append(node)
        on_stack.add(node)
        for target in sorted(graph[node]):
            if target not in index:
                visit(target)
                low[node] = min(low[node], low[target])
            elif target in on_stack:
                low[node] = min(low[node], index[target])
        if low[node] == index[node]:
            component = set()
            while True:
                member = stack.pop()
                on_stack.discard(member)
                component.add(member)
                if member == node:
                    break
            if len(component) > 1:
                found.append(component)

    for node in sorted(graph):
        if node not in index:
            visit(node)
    return found


def room(module: str) -> str:
    parts = module.split(".")
    return parts[1] if len(parts) > 1 else "__init__"


def test_no_import_cycle() -> None:
    assert strongly_connected(import_graph()) == []


def test_a_cycle_is_found() -> None:
    graph = {"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}
    assert strongly_connected(graph) == [{"a", "b", "c"}]


def test_no_room_imports_a_higher_one() -> None:
    graph = import_graph()
    unknown = {room(module) for module in graph} - ROOM_RANK.keys()
    assert not unknown, f"rooms without a rank in ROOM_RANK: {sorted(unknown)}"
    upward = sorted(
        f"{module} -> {target}"
        for module, targets in graph.items()
        for target in targets
        if ROOM_RANK[room(target)] > ROOM_RANK[room(module)]
        or (ROOM_RANK[room(target)] == ROOM_RANK[room(module)] and room(target) != room(module))
    )
    assert upward == []
