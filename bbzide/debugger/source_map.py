"""Where a robot is in its source: statement lines, functions and local names by pc.

Design: the compiler's debug map gives each instruction the position of the parser's
*lookahead* token when it was emitted (the reference bzzc's convention), so the last
instructions of a statement carry the position of the next statement's first token (a
`callc` of `f(x)` followed by `g()` is mapped to `g`'s line). A debugger that stepped by
those lines would run `f` during "the next line". So the debugger maps each pc to a
*statement* instead, from the script's syntax tree (the compiler's `syntax_tree.Node`s, one
per statement with the position of its first token):

* the code is cut into functions at their entry pcs (the operands of `pushcn`, named
  functions, and `pushl`, lambdas; the top level starts at the first instruction), and each
  region is matched with its tree node (a lambda's `pushl` sits at the lambda's `function`
  token; a named function is registered under its name's string id);
* within a function, an instruction belongs to the last of the function's own statements
  (nested lambdas excluded) that starts strictly before the instruction's debug position: the
  instructions emitted while the lookahead *is* a statement's first token end the statement
  before it. An instruction before any statement (the `ret0` mapped to the end of the file)
  takes the line of the instruction before it.

The code that only closes a structure (a loop's jump back, a block's `lremove`, the
function's final `ret0`) belongs to no line.

A line "has code" when some instruction of the main file's functions belongs to a statement
starting on it: that is where a breakpoint can stop.

Local names: a function's lsyms slots are `self` (0), its parameters, then its `var`s in
source order (a block's `var`s leave at the block's end), and a lambda nested in a function
starts from a copy of the enclosing scope (the parser's `add_local`, spec §A.4); the same
walk over the tree names each slot.
"""

from __future__ import annotations

import bisect
from dataclasses import dataclass, field

from bbzide.compiler.bytecode import read_bbo
from bbzide.compiler.opcodes import Op
from bbzide.compiler.program import BittyBuzzProgram
from bbzide.compiler.syntax_tree import Node

#: the tree nodes that are statements (a `block` node only groups its statements)
STATEMENT_KINDS = frozenset({"var", "function", "if", "while", "for", "return", "call",
                             "assign"})
FUNCTION_KINDS = frozenset({"function", "lambda"})


@dataclass
class FunctionCode:
    """One function's code region [start, end) and what the debugger shows of it."""

    start: int
    end: int
    name: str                          # "step", "lambda at line 11", "<top level>"
    node: Node | None
    #: statement start positions (line, col), sorted, and each one's line
    statement_starts: list[tuple[int, int]] = field(default_factory=list)
    #: lsyms slot -> local name
    local_names: dict[int, str] = field(default_factory=dict)


class SourceMap:
    """pc -> statement line, function and local names for one program (see the module doc)."""

    def __init__(self, program: BittyBuzzProgram) -> None:
        self.program = program
        self.main_file = program.source_file
        code = read_bbo(program.bbo)
        self.instructions = code.instructions
        #: instruction offsets, ascending (the pcs an instruction starts at)
        self.offsets = [ins.offset for ins in code.instructions]
        self.size = len(program.bbo)
        tree = _syntax_tree(program)
        self.functions = self._functions(tree)
        self._starts = [f.start for f in self.functions]
        #: pc -> statement line (None: the pc maps to no statement of the main file)
        self.line_of: dict[int, int | None] = {}
        self._map_lines()
        #: the lines a breakpoint can stop at
        self.code_lines = sorted({line for line in self.line_of.values() if line is not None})

    # ---- queries ----------------------------------------------------------------------------
    def line(self, pc: int) -> int | None:
        """The statement line of the instruction at `pc` (None outside the main file)."""
        return self.line_of.get(pc)

    @property
    def entry_pcs(self) -> list[int]:
        """The first pc of each function (the top level's included)."""
        return list(self._starts)

    def function_at(self, pc: int) -> FunctionCode | None:
        index = bisect.bisect_right(self._starts, pc) - 1
        if index < 0:
            return None
        found = self.functions[index]
        return found if pc < found.end else None

    def column(self, pc: int) -> int:
        """The debug map's column of `pc` (0 when unmapped)."""
        location = self.program.location_of(pc)
        return location.col if location is not None else 0

    def boot_only(self, line: int) -> str | None:
        """When all the code of `line` is in the top level or in `init` (run once, when a
        robot boots): which ("the top level", "init"); else None."""
        functions = [self.function_at(pc) for pc, found in self.line_of.items()
                     if found == line]
        where = {function.name for function in functions if function is not None}
        if where and where <= {"<top level>", "init"}:
            return " and ".join("the top level" if w == "<top level>" else w
                                for w in sorted(where))
        return None

    def nearest_code_line(self, line: int) -> int | None:
        """The first line with code at or after `line` (None: none after it)."""
        index = bisect.bisect_left(self.code_lines, line)
        return self.code_lines[index] if index < len(self.code_lines) else None

    # ---- building ---------------------------------------------------------------------------
    def _functions(self, tree: Node | None) -> list[FunctionCode]:
        program = self.program
        instructions = self.instructions
        first = instructions[0].offset if instructions else 0
        entries: dict[int, tuple[str, Node | None]] = {first: ("<top level>", tree)}
        lambdas: dict[tuple[int, int], Node] = {}
        named: dict[str, Node] = {}
        if tree is not None:
            for node in tree.walk():
                if node.kind == "lambda":
                    lambdas[(node.line, node.col)] = node
                elif node.kind == "function" and node.name:
                    named.setdefault(node.name, node)
        previous = None
        for ins in instructions:
            if ins.opcode == Op.PUSHL and ins.operand is not None:
                location = program.location_of(ins.offset)
                node = lambdas.get((location.line, location.col)) if location else None
                line = node.line if node is not None else (location.line if location else 0)
                entries.setdefault(ins.operand, (f"lambda at line {line}", node))
            elif ins.opcode == Op.PUSHCN and ins.operand is not None:
                name = None
                if previous is not None and previous.opcode == Op.PUSHS \
                        and previous.operand is not None \
                        and previous.operand < len(program.strings):
                    name = program.strings[previous.operand]
                entries.setdefault(ins.operand, (name or f"function at pc {ins.operand}",
                                                 named.get(name or "")))
            previous = ins
        starts = sorted(e for e in entries if e < self.size)
        functions = []
        for index, start in enumerate(starts):
            end = starts[index + 1] if index + 1 < len(starts) else self.size
            name, node = entries[start]
            function = FunctionCode(start, end, name, node)
            if node is not None:
                statements = sorted((s.line, s.col) for s in _own_statements(node)
                                    if _in_file(s, self.main_file, tree))
                function.statement_starts = statements
                function.local_names = _local_names(node, tree)
            functions.append(function)
        return functions

    def _map_lines(self) -> None:
        program = self.program
        for function in self.functions:
            starts = function.statement_starts
            line: int | None = None
            for offset in self.offsets:
                if not function.start <= offset < function.end:
                    continue
                location = program.location_of(offset)
                if location is not None and location.file == self.main_file and starts:
                    index = bisect.bisect_left(starts, (location.line, location.col)) - 1
                    if index >= 0:
                        line = starts[index][0]
                elif location is not None and location.file != self.main_file \
                        and location.line > 0:
                    line = None           # an included file's code: no main-file line
                # else (line 0: the end of the file) the line of the instruction before
                self.line_of[offset] = line
            self._unmap_structure(function)

    def _unmap_structure(self, function: FunctionCode) -> None:
        """No line for the code that only closes a structure: a `jump` (back to a loop's
        condition, over an `else`), an `lremove` (a block's locals leaving) and the
        function's closing `ret0`/`done`. Their debug positions lie after the last
        statement, but running them is not running that statement (a false `if` jumps
        straight to them)."""
        last = None
        for ins in self.instructions:
            if not function.start <= ins.offset < function.end:
                continue
            if ins.opcode in (Op.JUMP, Op.LREMOVE):
                self.line_of[ins.offset] = None
            last = ins
        if last is not None and last.opcode in (Op.RET0, Op.DONE):
            self.line_of[last.offset] = None


def _syntax_tree(program: BittyBuzzProgram) -> Node | None:
    """The script's syntax tree, parsed again from the text it was compiled from."""
    if program.source_file is None or program.source_text is None:
        return None
    from bbzide.compiler.frontend import compile_to_basm
    from bbzide.diagnostics import UserError

    try:
        return compile_to_basm(program.source_file, source=program.source_text).tree
    except UserError:  # an include that moved since: no statement map (lines unknown)
        return None


def _own_statements(function: Node) -> list[Node]:
    """The statements of `function` itself (the tree below it, nested functions excluded)."""
    found: list[Node] = []

    def visit(node: Node) -> None:
        for child in node.children:
            if child.kind in STATEMENT_KINDS:
                found.append(child)
            if child.kind not in FUNCTION_KINDS:
                visit(child)

    visit(function)
    return found


def _in_file(node: Node, main_file: str | None, tree: Node | None) -> bool:
    """Whether `node` is in the main script (its file is the tree root's, or unrecorded)."""
    return node.file is None or tree is None or node.file == tree.file


def _local_names(function: Node, tree: Node | None) -> dict[int, str]:
    """lsyms slot -> name for `function` (a tree node), as the parser numbers them."""
    if function.kind == "script":
        return {}
    path = _path_to(tree, function) if tree is not None else [function]
    scope: list[str] = []
    for index, node in enumerate(path):
        if node.kind in FUNCTION_KINDS:
            enclosing = [p for p in path[:index] if p.kind in FUNCTION_KINDS]
            if not enclosing:
                scope = ["self"]
            scope = scope + [p for p in node.params if p not in scope]
            stop = next((p for p in path[index + 1:] if p.kind in FUNCTION_KINDS), None)
            scope = _declared_before(node, stop, scope)
    return dict(enumerate(scope)) if path and path[-1] is function else {}


def _declared_before(function: Node, stop: Node | None, scope: list[str]) -> list[str]:
    """`scope` plus the `var`s of `function` visible where `stop` (a nested lambda on the
    way to the frame's function) is defined; with `stop` None, every `var` of the function
    (a slot keeps its name after its block ends: only a later `var` reuses the slot)."""
    names = list(scope)
    slots: dict[int, str] = dict(enumerate(names))

    def visit(node: Node, depth: list[str]) -> bool:
        for child in node.children:
            if child is stop:
                names[:] = depth
                return True
            if child.kind == "var" and child.name and child.name not in depth:
                depth.append(child.name)
                slots[len(depth) - 1] = child.name
            if child.kind in FUNCTION_KINDS:
                continue
            if child.kind == "block":
                if visit(child, list(depth)):
                    return True
            elif visit(child, depth):
                return True
        return False

    if visit(function, list(scope)):
        return names
    return [slots[i] for i in range(len(slots))]


def _path_to(tree: Node, target: Node) -> list[Node]:
    """The nodes from the root down to `target` (the root first); [] when absent."""
    stack: list[tuple[Node, list[Node]]] = [(tree, [tree])]
    while stack:
        node, path = stack.pop()
        if node is target:
            return path
        for child in node.children:
            stack.append((child, [*path, child]))
    return []
