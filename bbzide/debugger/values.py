"""A robot's values as the debugger shows them, and Buzz expressions evaluated over them.

Design: everything is read from the heap bytes (`vm.inspector`'s walks; nothing runs on the
VM and nothing is written), so evaluating a condition or a watch at a breakpoint cannot change
the robot. Values are decoded into plain Python: nil -> None, int, float, string -> str,
table -> `TableValue` (a dict of decoded keys), closure -> `ClosureValue`.

Expressions are a subset of Buzz's (the grammar of `bbzide/compiler/parser.py` for
expressions: precedence `or` < `and` < `not` < comparisons < `+ -` < `* / %` < unary `-` <
`^`, then `.field`, `[index]` and calls): names (the frame's locals first, then the globals),
int/float/string literals, `nil`, `size(table)`. Ints are BittyBuzz's 16-bit ints (wrapped
like the VM's), `/` of two ints truncates toward zero, comparisons give 1 or 0, and "true" is
a non-zero int, as `VM._truth` (so `if (x)` and a condition `x` agree). A name that is not
defined, a field of a non-table, a division by zero are `EvaluationError`s with one-line text.
"""

from __future__ import annotations

import math
import re
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any

from bbzide.compiler import bbzfloat
from bbzide.vm.heap import CLOSURE, FLAG1, FLAG2, FLOAT, INT, NIL, STRING, TABLE
from bbzide.vm.inspector import table_contents
from bbzide.vm.vm import VM

#: Nesting shown of a table inside a table when displayed (deeper ones are `{...}`): a
#: frame's locals stay one readable line each.
DISPLAY_DEPTH = 2
#: Entries shown of one table when displayed (then `...`): the neighbours' table of a dense
#: swarm would fill a screen.
DISPLAY_ENTRIES = 8


class EvaluationError(ValueError):
    """An expression that does not parse or cannot be evaluated (one line of text)."""


@dataclass(frozen=True)
class ClosureValue:
    """A closure: a Buzz function (`native` False: lambda or named function) or a host one."""

    text: str


class TableValue(dict):  # type: ignore[type-arg]
    """A decoded table (keys and values decoded); `heap_index` says which object it is."""

    heap_index: int = -1


# ---- decoding ---------------------------------------------------------------------------------
def decode(vm: VM, index: int, strings: list[str], depth: int = DISPLAY_DEPTH + 2) -> Any:
    """The heap object `index` as a Python value (tables decoded `depth` levels deep)."""
    h = vm.heap
    kind = h.obj_type(index)
    if kind == NIL:
        return None
    if kind == INT:
        return h.int_value(index)
    if kind == FLOAT:
        return bbzfloat.to_float(h.u16(index))
    if kind == STRING:
        sid = h.u16(index)
        return strings[sid] if sid < len(strings) else f"#{sid}"
    if kind == TABLE:
        table = TableValue()
        table.heap_index = index
        if depth > 0:
            darray = bool(h.mdata(index) & FLAG1)
            for key, value in table_contents(vm, index):
                decoded_key = key if darray else decode(vm, key, strings, 0)
                table[decoded_key] = decode(vm, value, strings, depth - 1)
        return table
    if kind == CLOSURE:
        mdata = h.mdata(index)
        if mdata & FLAG2:
            return ClosureValue("function")
        if mdata & FLAG1:
            return ClosureValue("function")
        call = vm.host.lookup(h.ptr_value(index))
        return ClosureValue(f"host function {call.symbol}" if call else "host function")
    return ClosureValue("userdata")


def display(value: Any, depth: int = DISPLAY_DEPTH) -> str:
    """One value as the debugger prints it (`3`, `0.5`, `"g"`, `nil`, `{.x = 1, .y = 2}`)."""
    if value is None:
        return "nil"
    if isinstance(value, float):
        return f"{value:g}"
    if isinstance(value, str):
        return f'"{value}"'
    if isinstance(value, ClosureValue):
        return value.text
    if isinstance(value, TableValue):
        if depth <= 0:
            return "{...}"
        parts = []
        for count, (key, item) in enumerate(value.items()):
            if count == DISPLAY_ENTRIES:
                parts.append("...")
                break
            name = f".{key}" if isinstance(key, str) and key.isidentifier() else \
                f"[{display(key, 0)}]"
            parts.append(f"{name} = {display(item, depth - 1)}")
        return "{" + ", ".join(parts) + "}"
    return str(value)


# ---- expressions ------------------------------------------------------------------------------
_TOKEN = re.compile(r"""\s*(?:
    (?P<number>\d+\.\d*(?:[eE][-+]?\d+)?|\d*\.\d+(?:[eE][-+]?\d+)?|\d+)
  | (?P<string>"[^"]*"|'[^']*')
  | (?P<name>[A-Za-z_][A-Za-z_0-9]*)
  | (?P<op><=|>=|==|!=|[-+*/%^<>().\[\],])
)""", re.VERBOSE)
_KEYWORDS = {"and", "or", "not", "nil"}


@dataclass(frozen=True)
class Expression:
    """A parsed expression: `evaluate(lookup)` with `lookup(name)` giving a name's value
    (raising `KeyError` when the name is not defined)."""

    text: str
    _root: tuple[Any, ...]

    def evaluate(self, lookup: Callable[[str], Any]) -> Any:
        return _evaluate(self._root, lookup)

    @property
    def names(self) -> set[str]:
        found: set[str] = set()
        _names(self._root, found)
        return found


def parse_expression(text: str) -> Expression:
    """Parse `text`; an `EvaluationError` says what is wrong, in one line."""
    tokens = _tokens(text)
    parser = _Parser(tokens, text)
    root = parser.expression()
    if parser.position != len(tokens):
        raise EvaluationError(f"unexpected {tokens[parser.position][1]!r} in {text!r}")
    return Expression(text, root)


def _tokens(text: str) -> list[tuple[str, str]]:
    tokens = []
    position = 0
    stripped = text.rstrip()
    while position < len(stripped):
        match = _TOKEN.match(stripped, position)
        if match is None or match.end() == position:
            raise EvaluationError(f"cannot read {stripped[position:].strip()[:12]!r} in "
                                  f"{text!r}")
        kind = match.lastgroup or ""
        value = match.group(kind)
        if kind == "name" and value in _KEYWORDS:
            kind = "op" if value != "nil" else "nil"
        tokens.append((kind, value))
        position = match.end()
    if not tokens:
        raise EvaluationError("an empty expression")
    return tokens


class _Parser:
    """Recursive descent over the tokens; nodes are tuples (kind, ...)."""

    def __init__(self, tokens: list[tuple[str, str]], text: str) -> None:
        self.tokens = tokens
        self.text = text
        self.position = 0

    def peek(self) -> str | None:
        return self.tokens[self.position][1] if self.position < len(self.tokens) else None

    def take(self) -> tuple[str, str]:
        if self.position >= len(self.tokens):
            raise EvaluationError(f"{self.text!r} ends too early")
        token = self.tokens[self.position]
        self.position += 1
        return token

    def expect(self, op: str) -> None:
        kind, value = self.take()
        if value != op or kind != "op":
            raise EvaluationError(f"expected {op!r}, found {value!r} in {self.text!r}")

    def expression(self) -> tuple[Any, ...]:
        return self.binary(0)

    #: binary operators by precedence level (lowest first), as Buzz's parser
    LEVELS: tuple[tuple[str, ...], ...] = (("or",), ("and",), ("==", "!=", "<", "<=", ">",
                                                               ">="), ("+", "-"),
                                            ("*", "/", "%"))

    def binary(self, level: int) -> tuple[Any, ...]:
        if level == len(self.LEVELS):
            return self.unary()
        if level == 2 and self.peek() == "not" and self._is_op():
            self.take()
            return ("not", self.binary(level))
        left = self.binary(level + 1)
        while self.peek() in self.LEVELS[level] and self._is_op():
            op = self.take()[1]
            left = ("binary", op, left, self.binary(level + 1))
        return left

    def _is_op(self) -> bool:
        return self.tokens[self.position][0] == "op"

    def unary(self) -> tuple[Any, ...]:
        if self.peek() == "-" and self._is_op():
            self.take()
            return ("neg", self.unary())
        base = self.postfix()
        if self.peek() == "^" and self._is_op():
            self.take()
            return ("binary", "^", base, self.unary())
        return base

    def postfix(self) -> tuple[Any, ...]:
        node = self.primary()
        while True:
            token = self.peek()
            if token == "." and self._is_op():
                self.take()
                kind, name = self.take()
                if kind != "name":
                    raise EvaluationError(f"expected a field name after '.', found {name!r}")
                node = ("index", node, ("const", name))
            elif token == "[" and self._is_op():
                self.take()
                key = self.expression()
                self.expect("]")
                node = ("index", node, key)
            elif token == "(" and self._is_op():
                self.take()
                arguments = []
                if self.peek() != ")":
                    arguments.append(self.expression())
                    while self.peek() == ",":
                        self.take()
                        arguments.append(self.expression())
                self.expect(")")
                node = ("call", node, tuple(arguments))
            else:
                return node

    def primary(self) -> tuple[Any, ...]:
        kind, value = self.take()
        if kind == "number":
            return ("const", float(value) if any(c in value for c in ".eE") else int(value))
        if kind == "string":
            return ("const", value[1:-1])
        if kind == "nil":
            return ("const", None)
        if kind == "name":
            return ("name", value)
        if value == "(":
            inner = self.expression()
            self.expect(")")
            return inner
        raise EvaluationError(f"unexpected {value!r} in {self.text!r}")


def _names(node: tuple[Any, ...], found: set[str]) -> None:
    if node[0] == "name":
        found.add(node[1])
    for part in node[1:]:
        if isinstance(part, tuple) and part and isinstance(part[0], str):
            _names(part, found)
        elif isinstance(part, tuple):
            for item in part:
                _names(item, found)


def truth(value: Any) -> bool:
    """Buzz's truth (`VM._truth`): a non-zero int; anything else is false."""
    return isinstance(value, int) and value != 0


def _int16(value: int) -> int:
    value &= 0xFFFF
    return value - 0x10000 if value & 0x8000 else value


def _evaluate(node: tuple[Any, ...], lookup: Callable[[str], Any]) -> Any:
    kind = node[0]
    if kind == "const":
        return node[1]
    if kind == "name":
        try:
            return lookup(node[1])
        except KeyError:
            raise EvaluationError(f"{node[1]!r} is not defined here") from None
    if kind == "not":
        return 0 if truth(_evaluate(node[1], lookup)) else 1
    if kind == "neg":
        value = _evaluate(node[1], lookup)
        if isinstance(value, bool) or not isinstance(value, int | float):
            raise EvaluationError(f"cannot negate {display(value)}")
        return _int16(-value) if isinstance(value, int) else -value
    if kind == "index":
        table = _evaluate(node[1], lookup)
        key = _evaluate(node[2], lookup)
        if not isinstance(table, Mapping):
            raise EvaluationError(f"{display(table)} is not a table")
        return table.get(key)
    if kind == "call":
        if node[1] != ("name", "size") or len(node[2]) != 1:
            raise EvaluationError("the only call in a debugger expression is size(table)")
        table = _evaluate(node[2][0], lookup)
        if not isinstance(table, Mapping):
            raise EvaluationError(f"size() of {display(table)}: not a table")
        return len(table)
    op, left_node, right_node = node[1], node[2], node[3]
    left = _evaluate(left_node, lookup)
    if op == "and":  # Buzz evaluates both sides (land), so do we: no short cut
        return int(truth(left) and truth(_evaluate(right_node, lookup)))
    if op == "or":
        right = _evaluate(right_node, lookup)
        return int(truth(left) or truth(right))
    right = _evaluate(right_node, lookup)
    return _binary(op, left, right)


def _binary(op: str, left: Any, right: Any) -> Any:
    if op in ("==", "!="):
        equal = left == right and type(left) is type(right) or \
            (isinstance(left, int | float) and isinstance(right, int | float) and left == right)
        return int(equal) if op == "==" else int(not equal)
    numbers = isinstance(left, int | float) and isinstance(right, int | float)
    if op in ("<", "<=", ">", ">="):
        if not numbers and not (isinstance(left, str) and isinstance(right, str)):
            raise EvaluationError(f"cannot compare {display(left)} and {display(right)}")
        return int({"<": left < right, "<=": left <= right, ">": left > right,
                    ">=": left >= right}[op])
    if not numbers:
        raise EvaluationError(f"{display(left)} {op} {display(right)}: not numbers")
    both_int = isinstance(left, int) and isinstance(right, int)
    if op in ("/", "%") and right == 0:
        raise EvaluationError("division by zero")
    if op == "+":
        result = left + right
    elif op == "-":
        result = left - right
    elif op == "*":
        result = left * right
    elif op == "/":
        result = int(left / right) if both_int else left / right
    elif op == "%":
        result = int(math.fmod(left, right)) if both_int else math.fmod(left, right)
    else:  # "^"
        result = int(left ** right) if both_int and right >= 0 else float(left) ** right
    return _int16(result) if isinstance(result, int) else result
