"""Recursive-descent parser for Buzz that emits `.basm` as it goes (single pass, like bzzparse).

Grammar and emission order follow the spec (§A.3 grammar, §B.4 emission per construct). Every
`emit` is annotated with `self.tok`, the current look-ahead token, which is what makes the debug
positions identical to the reference. Symbols: a stack of scopes (index 0 = globals); a global's
slot is its string id, a local's slot is the number of entries of its scope when it was added
(spec §A.4, including the cloned scopes of nested blocks and lambdas).

Errors are `CompileError`s at the look-ahead token, with the reference wording first and a hint
after it. Errors at the end of input carry the last real token's position (the reference prints
only the script name there).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

from bbzide.compiler import scanner as T
from bbzide.compiler.call_sites import CallSite, ScriptSymbols
from bbzide.compiler.codegen import CodeGenerator
from bbzide.compiler.scanner import Scanner, Token, user_text
from bbzide.compiler.syntax_tree import Node
from bbzide.diagnostics import CompileError, SourceLocation

# Sentinels for `idref`'s "what has been referenced so far" (reference: negative values).
TABLE = -1
CLOSURE = -2

BINARY_OPS = {"+": "add", "-": "sub", "*": "mul", "/": "div", "%": "mod", "^": "pow",
              "<<": "lshift", ">>": "rshift", "&": "band", "|": "bor",
              "and": "land", "or": "lor", "==": "eq", "!=": "neq", "<": "lt", "<=": "lte",
              ">": "gt", ">=": "gte"}


@dataclass(slots=True)
class Symbol:
    slot: int
    is_global: bool


class Parser:
    """One parse of one script (and its includes); `parse_script` returns the syntax tree and
    leaves the `.basm` in the code generator."""

    def __init__(self, scanner: Scanner, codegen: CodeGenerator, script_name: str, *,
                 reference_quirks: bool = False,
                 warn: Callable[[str], None] | None = None) -> None:
        self.reference_quirks = reference_quirks
        self.warn = warn or (lambda message: None)
        self.function_depth = 0  # named functions and lambdas being parsed
        self.scanner = scanner
        self.gen = codegen
        self.script_name = script_name
        self.scopes: list[dict[str, Symbol]] = []
        self.tok: Token = T.EOF_TOKEN
        self.nodes: list[list[Node]] = []
        self.symbols = ScriptSymbols()

    # -- tokens and errors ---------------------------------------------------------------

    def advance(self) -> None:
        self.tok = self.scanner.next_token()

    def error(self, message: str, hint: str = "") -> CompileError:
        tok = self.tok
        text = f"Syntax error: {message}"
        if hint:
            text += f" ({hint})"
        if tok.kind == T.EOF:
            last = self.scanner.last
            if last.file is None:
                return CompileError(f"{text} (at the end of {self.script_name})")
            return self.scanner.error_at(last, text)
        return self.scanner.error_at(tok, text)

    def found(self) -> str:
        return "end of file" if self.tok.kind == T.EOF else self.tok.kind

    def expect(self, kind: str, hint: str = "") -> None:
        if self.tok.kind != kind:
            raise self.error(f"expected {kind}, found {self.found()}", hint)

    def emit(self, op: str) -> None:
        self.gen.emit(op, self.tok)

    def location(self, tok: Token) -> SourceLocation:
        return SourceLocation(user_text(tok.file) if tok.file else self.script_name, tok.line,
                              tok.col)

    def node(self, kind: str, tok: Token, name: str | None = None) -> Node:
        node = Node(kind, tok.line, tok.col, user_text(tok.file) if tok.file else None, name)
        self.nodes[-1].append(node)
        return node

    # -- symbols -------------------------------------------------------------------------

    def lookup(self, name: str) -> Symbol | None:
        for scope in reversed(self.scopes):
            symbol = scope.get(name)
            if symbol is not None:
                return symbol
        return None

    def global_symbol(self, name: str) -> Symbol:
        symbol = self.scopes[0].get(name)
        if symbol is None:
            symbol = self.scopes[0][name] = Symbol(self.gen.string_id(name), True)
        return symbol

    def add_local(self, name: str) -> Symbol:
        scope = self.scopes[-1]
        symbol = scope[name] = Symbol(len(scope), False)
        return symbol

    def push_block_scope(self) -> None:
        self.scopes.append({} if len(self.scopes) == 1 else dict(self.scopes[-1]))

    # -- script and statements -----------------------------------------------------------

    def parse_script(self) -> Node:
        root = Node("script", 1, 0, user_text(self.scanner.main_realpath))
        self.nodes.append(root.children)
        self.advance()
        if self.tok.kind == T.EOF:
            if not self.reference_quirks:  # quirk 13 of the frontend's table
                self.warn(f"{user_text(self.scanner.main_realpath)}: the script has no "
                          "statements: like bzzc it compiles to a lone nop without `done`, so a "
                          "robot running it stops with a PC error (program counter out of range)")
            return root
        self.scopes.append({})
        self.gen.open_chunk(self.gen.new_label())
        self.statlist()
        if self.tok.kind == T.BLOCKCLOSE and not self.reference_quirks:
            raise self.error("unmatched }", "bzzc would silently ignore the rest of the file")
        self.gen.emit_exit(self.tok)
        return root

    def statlist(self) -> None:
        while self.tok.kind not in (T.EOF, T.BLOCKCLOSE):
            self.stat()

    def stat(self) -> None:
        kind = self.tok.kind
        if kind == T.VAR:
            self.vardef()
        elif kind == T.FUN:
            self.fundef()
        elif kind == T.IF:
            self.if_stat()
        elif kind == T.FOR:
            self.for_stat()
        elif kind == T.WHILE:
            self.while_stat()
        else:
            self.command()

    def block(self, push_scope: bool) -> None:
        self.expect(T.BLOCKOPEN)
        self.advance()
        if self.tok.kind == T.BLOCKCLOSE:
            self.advance()
            return
        if push_scope:
            self.push_block_scope()
        scope = self.scopes[-1]
        start = len(scope)
        self.statlist()
        self.expect(T.BLOCKCLOSE, "a block opened with { is not closed")
        self.advance()
        added = len(scope) - start
        if added > 0:
            self.emit(f"lremove {added}")
        for name in [n for n, s in scope.items() if s.slot >= start]:
            del scope[name]
        if push_scope:
            self.scopes.pop()

    def blockstat(self) -> None:
        if self.tok.kind == T.BLOCKOPEN:
            node = self.node("block", self.tok)
            self.nodes.append(node.children)
            self.block(True)
            self.nodes.pop()
        else:
            self.stat()

    def vardef(self) -> None:
        start = self.tok
        self.advance()
        self.expect(T.ID)
        name = self.tok.text
        self.nodes.append(self.node("var", start, name).children)
        existing = self.lookup(name)
        if existing is not None and not existing.is_global:
            raise self.scanner.error_at(self.tok, f"Duplicated symbol '{name}' (a local variable "
                                                  "of that name is already visible here)")
        if len(self.scopes) == 1:
            symbol = self.global_symbol(name)
            self.symbols.defined.add(name)
            self.emit(f"pushs {symbol.slot}")
        else:
            symbol = self.add_local(name)
            if self.function_depth == 0 and not self.reference_quirks:
                self.warn(f"{user_text(self.tok.file or '')}:{self.tok.line}:{self.tok.col}: "
                          f"'var {name}' in a top-level block makes a local variable outside any "
                          "function; the Buzz VM crashes on it (declare it outside the block)")
        self.advance()
        if self.tok.kind == T.ASSIGN:
            if not symbol.is_global:
                self.emit("pushnil")
                self.emit(f"lstore {symbol.slot}")
            self.advance()
            self.expression()
        else:
            self.emit("pushnil")
        self.emit("gstore" if symbol.is_global else f"lstore {symbol.slot}")
        self.nodes.pop()

    def fundef(self) -> None:
        start = self.tok
        self.advance()
        self.expect(T.ID)
        name = self.tok.text
        if len(self.scopes) != 1:
            raise self.error(
                f"the definition of function {name}() is nested within another scope. To define "
                f"local functions, use the lambda syntax {name} = function() {{ ... }}.")
        symbol = self.global_symbol(name)
        self.symbols.defined.add(name)
        label = self.gen.new_label()
        self.gen.register_function(symbol.slot, label)
        previous = self.gen.open_chunk(label)
        node = self.node("function", start, name)
        self.advance()
        self.expect(T.PAROPEN)
        self.advance()
        self.scopes.append({})
        self.add_local("self")
        self.params_and_body(node, previous, docstring=True)

    def params_and_body(self, node: Node, previous: list[str], docstring: bool) -> None:
        """`(a, b) { ... }` of a function or lambda whose scope is already open: parameters,
        body, the closing `ret0`; then the scope and the code chunk are closed. Named
        functions may carry a docstring string after `)`; lambdas may not."""
        node.params = self.idlist()
        self.expect(T.PARCLOSE)
        self.advance()
        if docstring and self.tok.kind == T.STRING:
            self.advance()
        self.nodes.append(node.children)
        self.function_depth += 1
        self.block(False)
        self.function_depth -= 1
        self.nodes.pop()
        self.emit("ret0")
        self.scopes.pop()
        self.gen.close_chunk(previous)

    def idlist(self) -> list[str]:
        names: list[str] = []
        if self.tok.kind == T.ID:
            while True:
                name = self.tok.text
                names.append(name)
                existing = self.lookup(name)
                if existing is None or existing.is_global:
                    self.add_local(name)
                self.advance()
                if self.tok.kind != T.LISTSEP:
                    break
                self.advance()
                self.expect(T.ID)
        return names

    def if_stat(self) -> None:
        node = self.node("if", self.tok)
        self.nodes.append(node.children)
        else_label, end_label = self.gen.new_label(), self.gen.new_label()
        self.advance()
        self.expect(T.PAROPEN, "Buzz needs parentheses around the condition: if (x) ...")
        self.advance()
        self.condition()
        self.expect(T.PARCLOSE)
        self.advance()
        self.emit(f"jumpz @__label_{else_label}")
        self.blockstat()
        if self.tok.kind == T.ELSE:
            self.advance()
            self.emit(f"jump @__label_{end_label}")
            self.gen.emit_label(else_label, self.tok)
            self.blockstat()
            self.gen.emit_label(end_label, self.tok)
        else:
            self.gen.emit_label(else_label, self.tok)
        self.nodes.pop()

    def while_stat(self) -> None:
        node = self.node("while", self.tok)
        self.nodes.append(node.children)
        start_label, end_label = self.gen.new_label(), self.gen.new_label()
        self.advance()
        self.expect(T.PAROPEN, "Buzz needs parentheses around the condition: while (x) ...")
        self.advance()
        self.gen.emit_label(start_label, self.tok)
        self.condition()
        self.expect(T.PARCLOSE)
        self.advance()
        self.emit(f"jumpz @__label_{end_label}")
        self.blockstat()
        self.nodes.pop()
        self.emit(f"jump @__label_{start_label}")
        self.gen.emit_label(end_label, self.tok)

    def for_stat(self) -> None:
        node = self.node("for", self.tok)
        self.nodes.append(node.children)
        cond, update, body, end = (self.gen.new_label() for _ in range(4))
        hint = "Buzz writes for loops as for (init, condition, update)"
        self.advance()
        self.expect(T.PAROPEN, hint)
        self.advance()
        self.command()
        self.expect(T.LISTSEP, hint)
        self.advance()
        self.gen.emit_label(cond, self.tok)
        self.condition()
        self.expect(T.LISTSEP, hint)
        self.advance()
        self.emit(f"jumpnz @__label_{body}")
        self.emit(f"jump @__label_{end}")
        self.gen.emit_label(update, self.tok)
        self.command()
        self.expect(T.PARCLOSE, hint)
        self.advance()
        self.emit(f"jump @__label_{cond}")
        self.gen.emit_label(body, self.tok)
        self.blockstat()
        self.nodes.pop()
        self.emit(f"jump @__label_{update}")
        self.gen.emit_label(end, self.tok)

    def command(self) -> None:
        start = self.tok
        node = self.node("return" if start.kind == T.RETURN else "call", start,
                         start.text if start.kind == T.ID else None)
        self.nodes.append(node.children)
        if start.kind == T.RETURN:
            self.advance()
            if self.tok.kind == T.BLOCKCLOSE:
                self.emit("ret0")
            else:
                self.condition()
                self.emit("ret1")
        else:
            self.assignment_or_call(node)
        self.nodes.pop()

    def assignment_or_call(self, node: Node) -> None:
        info, is_global = self.idref(lvalue=True)
        if self.tok.kind == T.ASSIGN:
            if info == CLOSURE:
                raise self.error("can't have a function call as lvalue",
                                 "a call's result cannot be assigned to")
            node.kind = "assign"
            if is_global:
                self.symbols.defined.add(node.name or "")
                self.emit(f"pushs {info}")
            self.advance()
            self.expression()
            if is_global:
                self.emit("gstore")
            elif info >= 0:
                self.emit(f"lstore {info}")
            else:
                self.emit("tput")
        elif info == CLOSURE:
            self.emit("pop")
        else:
            raise self.error("expected function call or assignment",
                             "a statement must be a call like f() or an assignment like x = 1")

    # -- expressions ---------------------------------------------------------------------

    def condition(self) -> None:
        if self.tok.kind == T.LNOT:
            self.advance()
            self.condition()
            self.emit("lnot")
            return
        self.binary_level(self.comparison, T.LANDOR)

    def comparison(self) -> None:
        self.expression()
        if self.tok.kind == T.CMP:
            op = self.tok.text
            self.advance()
            self.expression()
            self.emit(BINARY_OPS[op])

    def expression(self) -> None:
        if self.tok.kind == T.BLOCKOPEN:
            self.tabledef()
            return
        self.binary_level(self.product, T.ADDSUB)

    def product(self) -> None:
        self.binary_level(self.modulo, T.MULDIV)

    def modulo(self) -> None:
        self.binary_level(self.power, T.MOD)

    def power(self) -> None:
        self.bitshift()
        if self.tok.kind == T.POW:
            self.advance()
            self.power()
            self.emit("pow")

    def bitshift(self) -> None:
        self.binary_level(self.bandor, T.LRSHIFT)

    def bandor(self) -> None:
        self.binary_level(self.bnot, T.BANDOR)

    def binary_level(self, operand: Callable[[], None], operator_kind: str) -> None:
        """One left-associative precedence level: `operand (OP operand)*`, each OP emitted
        after its right operand (bzzparse's order, which fixes the `.basm` annotations)."""
        operand()
        while self.tok.kind == operator_kind:
            op = self.tok.text
            self.advance()
            operand()
            self.emit(BINARY_OPS[op])

    def bnot(self) -> None:
        if self.tok.kind == T.BNOT:
            self.advance()
            self.bnot()
            self.emit("bnot")
        else:
            self.operand()

    def push_number(self, text: str) -> None:
        self.emit(f"pushf {text}" if "." in text else f"pushi {text}")

    def operand(self) -> None:
        tok = self.tok
        kind = tok.kind
        if kind == T.FUN:
            self.lambda_()
        elif kind == T.NIL:
            self.emit("pushnil")
            self.advance()
        elif kind == T.CONST:
            self.push_number(tok.text)
            self.advance()
        elif kind == T.STRING:
            self.emit(f"pushs {self.gen.string_id(tok.text)}")
            self.advance()
        elif kind == T.PAROPEN:
            self.advance()
            self.condition()
            self.expect(T.PARCLOSE)
            self.advance()
        elif kind == T.ADDSUB:
            self.advance()
            if self.tok.kind == T.CONST:
                self.push_number(tok.text + self.tok.text)
                self.advance()
            else:
                self.power()
                if tok.text == "-":
                    self.emit("unm")
        else:
            self.idref(lvalue=False)

    def lambda_(self) -> None:
        label = self.gen.label_counter
        self.emit(f"pushl @__label_{label}")
        node = self.node("lambda", self.tok)
        self.advance()
        self.gen.new_label()
        previous = self.gen.open_chunk(label)
        self.expect(T.PAROPEN)
        self.advance()
        if len(self.scopes) == 1:
            self.scopes.append({})
            self.add_local("self")
        else:
            self.scopes.append(dict(self.scopes[-1]))
        self.params_and_body(node, previous, docstring=False)

    def tabledef(self) -> None:
        self.advance()
        if self.tok.kind not in (T.DOT, T.BLOCKCLOSE):
            raise self.error(f"expected .id = expression or }}, found {self.found()}",
                             "table fields are written {.name = value, .1 = value}")
        self.emit("pusht")
        if self.tok.kind == T.DOT:
            self.table_field()
            while self.tok.kind == T.LISTSEP:
                self.table_field()
        self.expect(T.BLOCKCLOSE)
        self.advance()

    def table_field(self) -> None:
        self.emit("dup")
        if self.tok.kind == T.LISTSEP:
            self.advance()
            self.expect(T.DOT)
        self.advance()
        key = self.tok
        if key.kind == T.ID:
            self.emit(f"pushs {self.gen.string_id(key.text)}")
        elif key.kind == T.CONST:
            self.push_number(key.text)
        else:
            raise self.error(f"expected id or numeric constant, found {self.found()}",
                             "table keys are names or numbers: {.name = v, .1 = v}")
        self.advance()
        self.expect(T.ASSIGN)
        self.advance()
        self.expression()
        self.emit("tput")

    def idref(self, lvalue: bool) -> tuple[int, bool]:
        """An identifier with its `.field`, `[index]` and `(call)` suffixes (spec §B.4 idref)."""
        self.expect(T.ID)
        name = self.tok.text
        symbol = self.lookup(name)
        if symbol is None:
            symbol = self.global_symbol(name)
        info, is_global = symbol.slot, symbol.is_global
        start = self.tok
        ref = self.node("ref", start, name)
        ref.scope = f"global (string id {info})" if is_global else f"local slot {info}"
        outer = self.gen.out
        own: list[str] = []
        self.gen.out = own
        self.advance()
        if is_global and (not lvalue or self.tok.kind != T.ASSIGN):
            self.symbols.read(name, self.location(start))
        # the called expression as written, and the call whose `callc` comes next
        callee_text = name
        call: CallSite | None = None
        while self.tok.kind in (T.DOT, T.IDXOPEN, T.PAROPEN):
            kind = self.tok.kind
            if is_global:
                if kind == T.PAROPEN:
                    self.emit("pushnil")
                self.emit(f"pushs {info}")
                self.emit("gload")
            elif info >= 0:
                if kind == T.PAROPEN:
                    self.emit("pushnil")
                self.emit(f"lload {info}")
            elif info == TABLE:
                self.emit("tget")
            else:
                self.gen.emit_call(call or CallSite(self.location(start), callee_text), self.tok)
            is_global = False
            if kind == T.DOT:
                info = TABLE
                self.advance()
                self.expect(T.ID)
                sid = self.gen.string_id(self.tok.text)
                callee_text += "." + self.tok.text
                self.advance()
                if self.tok.kind == T.PAROPEN:
                    self.emit("dup")
                self.emit(f"pushs {sid}")
            elif kind == T.IDXOPEN:
                info = TABLE
                self.advance()
                index: list[str] = []
                self.gen.out = index
                self.expression()
                self.gen.out = own
                self.expect(T.IDXCLOSE)
                callee_text += "[…]"
                self.advance()
                if self.tok.kind == T.PAROPEN:
                    self.emit("dup")
                own.extend(index)
            else:
                bare_global = callee_text == name and symbol.is_global
                call = CallSite(self.location(start), callee_text, name if bare_global else None)
                callee_text += "(…)"
                info = CLOSURE
                self.advance()
                count = 0
                if self.tok.kind != T.PARCLOSE:
                    self.condition()
                    count = 1
                    while self.tok.kind == T.LISTSEP:
                        self.advance()
                        self.condition()
                        count += 1
                self.expect(T.PARCLOSE, "arguments are separated by commas")
                self.advance()
                if self.tok.kind == T.PAROPEN:
                    # the self slot of a chained call goes before everything of this idref
                    outer.append(f"\tpushnil\t|{self.tok.annotation}")
                self.emit(f"pushi {count}")
        if not lvalue or info == CLOSURE:
            if is_global:
                self.emit(f"pushs {info}")
                self.emit("gload")
            elif info >= 0:
                self.emit(f"lload {info}")
            elif info == TABLE:
                self.emit("tget")
            else:
                self.gen.emit_call(call or CallSite(self.location(start), callee_text), self.tok)
        outer.extend(own)
        self.gen.out = outer
        return info, is_global
