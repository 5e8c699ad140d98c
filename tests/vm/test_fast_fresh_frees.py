"""Fresh temporaries freed without a collection, in the fast mode against the reference.

The compiled kernel skips the collection after an instruction that drops stack roots (pop,
jumpz/jumpnz, unary and binary operations, tget, gload) when each dropped root is either
kept by the permanent roots or a *fresh* leaf (``fastloop.FRESH``: allocated by a skipped
step in a slot the last collection did not reach, so referenced by its stack slot alone),
and frees those leaves itself at the start of the next step, as the skipped collection
would. These scripts are made of such temporaries — literals in arithmetic, comparisons
tested by ``if``/``while``, expression statements, unary operators, tables read with
literal keys, the copy of a global table a method call makes (``dup``), globals whose
overwritten value only they held (``fastloop.OWNED``) — on roomy heaps
and on heaps small enough that freed slots are reused at once and the object end retreats.
Every observable byte must be the reference's, after each chunk of a few instructions (a
budget stop may fall between a drop and its free) and at the end.
"""

from __future__ import annotations

import dataclasses
import re

import pytest

from bbzide.compiler import bittybuzz_string_table, compile_source
from bbzide.compiler.assembler import assemble
from bbzide.compiler.bo2bbo import bo_to_bbo
from bbzide.compiler.frontend import compile_to_basm
from bbzide.vm.compiled import fastloop
from bbzide.vm.heap import TABLE
from bbzide.vm.inspector import globals_by_name
from bbzide.vm.profiles import CRAZYFLIE, KILOBOT, PC, Profile
from bbzide.vm.tables import darray_get, darray_size, table_get
from bbzide.vm.vm import VM, State
from tests.vm.chunked_runs import assert_modes_agree, chunk_stops

SCRIPTS = {
    "arithmetic with literals": """
g = 255
i = 0
while (i < 40) {
  hops = (i * 7) / 33 + 1
  if (hops < g) { g = hops }
  x = -(i % 5) + (i % 3) * 2 - 1
  y = ((not (i > 20)) or (i == 3))
  i = i + 1
}
""",
    "tables read with literal keys": """
t = {.a = 1, .b = 2}
t[1] = 10
t[2] = 20
s = 0
i = 0
while (i < 30) {
  s = s + t.a * t[1] + t[2] / (t.b + 1)
  if (t[i % 3] == nil) { s = s + 1 }
  t[3] = i
  i = i + 1
}
""",
    "temporaries in functions": """
function dist(x, y) {
  var d = x * x + y * y
  if (d > 100 and x != y) { return d / 10 }
  return -d
}
acc = {}
i = 0
while (i < 25) {
  acc[i % 4] = dist(i, 25 - i) + dist(i % 3, 2)
  dist(1, i)
  i = i + 1
}
""",
    "globals overwritten": """
a = 0
b = 1.5
name = "x"
function keep(v) {
  a = 7                     # the argument, a's old value, must outlive this
  return v + 1
}
function swap(k) {
  a = k + 5                 # only a holds it, until
  var w = a                 # pushed (no call between: no collection tells)
  a = 9
  return w * 2
}
function hold() {
  var v = a                 # a local holds it too
  a = 8                     # which must not free it
  return v * 2
}
i = 0
while (i < 40) {
  a = a + 1                 # a fresh int replaces the one only a held
  b = b * 2.0 - 1.0
  c = a                     # now two globals hold it: overwriting a must not free it
  a = i * 3
  a = a
  z = keep(a)
  a = i + 2
  z = hold()
  z = swap(i)
  name = "y"
  name = "x"
  d = nil                   # storing nil deletes the global
  d = i
  i = i + c % 5 - c % 5 + 1
}
""",
    "table slots overwritten": """
t = {.x = 0, .y = 0.5, .n = {.v = 1}}
u = {}
seen = {}
function store(k, v) {
  t[k] = v * 2              # the argument's product: only t's slot holds it, until
}
function peek(k, v) {
  seen[k] = v               # a second slot holds the walked value: not t's alone
}
i = 0
while (i < 40) {
  t.x = t.x + 1             # read back, dropped, then its slot's only value replaced
  t.y = t.y * 2.0 - 1.0
  t.n.v = t.n.v + i % 3     # a table below a table
  u[i % 4] = i * 3
  u[i % 4] = u[i % 4]       # the same number stored again
  t.z = u[i % 4]            # two slots hold it: overwriting one must not free it
  u[i % 4] = 7
  store(i % 3, i)           # a key that is a local's value
  store(i % 3 + 1, i + 1)
  if (i % 5 == 0) { foreach(t, peek) }
  t[i % 3] = nil            # storing nil deletes the key
  t.x = t.x + t.x           # the same number twice on the stack
  i = i + 1
}
""",
    "locals removed": """
g = {.k = 0}
h = 0
function f(a, b) {
  var d = a * b             # only the frame's slot holds it, until the function ends
  var e = d + 1
  if (d > 20) {
    var q = d - e           # a block's local, removed at the block's end
    h = q                   # a global holds it too: its removal must not free it
  }
  var w = g.k + e
  g.k = d                   # a table holds d too
  return w
}
function l(x) {
  var c = x + 0.5
  return c * 2.0
}
i = 0
while (i < 40) {
  r = f(i, i % 7) + l(i)
  i = i + 1
}
""",
    "long expressions of stored numbers": """
a = 1
b = 2
c = 3
d = 4
e = 5
t = {.p = 6, .q = 7}
i = 0
while (i < 40) {
  a = a + b * c - d / e + t.p - t.q + a   # more stored numbers on the stack than followed
  t.p = t.p + a % 3 - b
  b = (c + d) % 9 + 1
  e = e % 5 + 1
  i = i + 1
}
""",
    "method calls on global tables": """
counter = {.n = 0, .add = function(k) { self.n = self.n + k  return self.n }}
log = {.last = 0}
i = 0
while (i < 30) {
  counter.add(i % 4)
  log.last = counter.n + counter.add(1)
  if (log.last > 40) { counter.n = 0 }
  i = i + 1
}
""",
}


def _bbo(name: str) -> bytes:
    return compile_source(SCRIPTS[name], "fresh.bzz").to_bbo().bbo


PROFILES = [PC, KILOBOT, CRAZYFLIE,
            # freed slots reused by the next allocation; the object end retreating
            dataclasses.replace(KILOBOT, name="small heap", heap_size=600),
            dataclasses.replace(PC, name="small pc heap", heap_size=1100),
            # segments at odd offsets (the collector reads their words two bytes at a time)
            dataclasses.replace(PC, name="odd-sized pc heap", heap_size=1101)]


@pytest.mark.parametrize("name", sorted(SCRIPTS))
@pytest.mark.parametrize("profile", PROFILES, ids=lambda p: p.name)
def test_fresh_frees_identical(name: str, profile: Profile) -> None:
    assert_modes_agree(_bbo(name), profile, 500, name)


def _fresh_tops(name: str) -> tuple[int, int]:
    """Stopped after each chunk of the fast VM's run of script ``name``: at how many stops the
    stack top was a fresh temporary, and how many of those were tables (``dup``'s copies);
    on the way, a flagged object is never on the stack twice."""
    tops = tables = 0
    for vm in chunk_stops(_bbo(name), PC, False, 3000):
        stack = list(vm.stack[:vm.stackptr + 1])
        fresh = [x for x in stack if vm.heap.gc_info[x] == fastloop.FRESH]
        assert len(fresh) == len(set(fresh))
        if stack and vm.heap.gc_info[stack[-1]] == fastloop.FRESH:
            tops += 1
            tables += vm.heap.obj_type(stack[-1]) == TABLE
    assert vm.state == State.DONE
    return tops, tables


@pytest.mark.skipif(not fastloop.COMPILED, reason="the kernel runs as Python without numba")
def test_the_kernel_marks_fresh_temporaries() -> None:
    tops, _tables = _fresh_tops("arithmetic with literals")
    assert tops > 10


@pytest.mark.skipif(not fastloop.COMPILED, reason="the kernel runs as Python without numba")
def test_the_kernel_marks_method_calls_table_copies_fresh() -> None:
    _tops, tables = _fresh_tops("method calls on global tables")
    assert tables > 0


@pytest.mark.skipif(not fastloop.COMPILED, reason="the kernel runs as Python without numba")
def test_the_kernel_marks_values_only_a_global_holds() -> None:
    """A fresh int or float a skipped ``gstore`` moved into a global is marked
    ``fastloop.OWNED`` (overwriting the global frees it); a value that is on the stack is
    never so marked."""
    owned_seen = 0
    for vm in chunk_stops(_bbo("globals overwritten"), PC, False, 3000):
        info = vm.heap.gc_info
        owned = [x for x in range(vm.heap.rtobj // vm.heap.obj_size)
                 if info[x] == fastloop.OWNED and vm.heap.data[x * vm.heap.obj_size] & 0x08]
        owned_seen += bool(owned)
        assert not set(owned) & set(vm.stack[:vm.stackptr + 1])
    assert vm.state == State.DONE
    assert owned_seen > 10




COUNTERS = {
    "alone": """
i = 0
while (i < 400) {
  i = i + 1
}
""",
    # the same counter in a function the top level calls
    "in a function": """
i = 0
function count() {
  while (i < 400) {
    i = i + 1
  }
}
count()
""",
}


@pytest.mark.skipif(not fastloop.COMPILED, reason="the kernel runs as Python without numba")
@pytest.mark.parametrize("name", sorted(COUNTERS))
def test_a_counter_stays_its_globals_alone_while_it_counts(name: str) -> None:
    """``i = i + 1``: ``gload`` puts i's number on the stack (one more reference), ``add``
    drops it again (its global's alone once more), so at the ``gstore`` the number it
    replaces is ``fastloop.OWNED``, and the store frees it without a collection. Run from
    the start for one budget after another,
    the VM stopped before a ``gstore`` of the loop holds i's number as OWNED; and the run
    is the reference's."""
    program = compile_source(COUNTERS[name], "counter.bzz",
                             string_table=bittybuzz_string_table([])).to_bbo()
    gstore = 29
    owned_at_store = []
    for budget in range(30, 200):  # from the loop's second time round on
        vm = VM(PC, stress_gc=False)
        vm.construct()
        vm.set_bcode(program.bbo)
        vm.run(max_instructions=budget)
        if vm.bcode[vm.pc] == gstore:
            value = globals_by_name(vm, program.strings)["i"]
            owned_at_store.append(vm.heap.gc_info[value] == fastloop.OWNED)
    assert len(owned_at_store) > 5 and all(owned_at_store)
    assert_modes_agree(program.bbo, PC, 3000, name)


#: a table entry counted up, and a local's number dropped when its function ends
SLOT_OWNERS = {
    "a table's entry": ("""
t = {.n = 0}
i = 0
while (i < 400) {
  t.n = t.n + 1
  i = i + 1
}
""", 31),
    "a function's local": ("""
s = 0
function twice(x) {
  var d = x * 2
  s = s + d % 3
}
i = 0
while (i < 400) {
  twice(i)
  i = i + 1
}
""", 43),
}


@pytest.mark.skipif(not fastloop.COMPILED, reason="the kernel runs as Python without numba")
@pytest.mark.parametrize("name", sorted(SLOT_OWNERS))
def test_a_number_its_slot_alone_holds_is_freed_with_it(name: str) -> None:
    """``t.n = t.n + 1`` and a local ``d`` at the end of its function (``lremove``): the
    number the ``tput`` replaces, the one the ``lremove`` drops, is ``fastgc.OWNED`` (new or
    not) when the instruction runs, so the kernel frees it without a collection. Run from
    the start for one budget after another, the VM stopped before such an instruction
    finds it so; and the run is the reference's."""
    source, opcode = SLOT_OWNERS[name]
    program = compile_source(source, "slot.bzz",
                             string_table=bittybuzz_string_table([])).to_bbo()
    owned_at = []
    for budget in range(60, 400):
        vm = VM(PC, stress_gc=False)
        vm.construct()
        vm.set_bcode(program.bbo)
        vm.run(max_instructions=budget)
        if vm.bcode[vm.pc] != opcode:
            continue
        if opcode == 31:  # the value under the key about to be replaced
            value = table_get(vm.heap, vm.stack[vm.stackptr - 2], vm.stack[vm.stackptr - 1])
        else:  # the frame's last local
            value = darray_get(vm.heap, vm.lsyms, darray_size(vm.heap, vm.lsyms) - 1)
        assert value is not None
        owned_at.append(int(vm.heap.gc_info[value]) & 0x7F == fastloop.OWNED)
    assert len(owned_at) > 5 and all(owned_at), owned_at
    assert_modes_agree(program.bbo, PC, 3000, name)


#: a function whose local ``y`` is removed while a copy of its number is still on the stack:
#: ``lload 2`` twice (the number on the stack twice), one copy popped, ``lremove 1``, then
#: the other copy stored in ``g``. The compiler emits no such sequence (a block's locals go
#: when its statements have left the stack empty); bytecode may, and the VM runs it.
TWICE = """g = 0
function f(x) {
  var y = x * 2
  g = 1
}
i = 0
while (i < 30) {
  f(i)
  i = i + 1
}
"""


def test_a_local_removed_while_its_number_is_on_the_stack_keeps_the_number() -> None:
    """The first ``lload`` follows the local's number (OWNED: its slot's alone until then);
    the second finds it followed and stops following it, so dropping one copy does not make
    it the slot's alone again, and the ``lremove`` leaves it to a collection, which keeps it
    for the copy the stack still holds (then ``g``'s)."""
    basm = compile_to_basm("twice.bzz", source=TWICE).basm
    edited, count = re.subn(r"\tlremove 1\t[^\n]*",
                            "\tpushs 0\n\tlload 2\n\tlload 2\n\tpop\n\tlremove 1\n\tgstore", basm)
    assert count == 1
    bbo = bo_to_bbo(assemble(edited, "twice.basm").bo, "twice.bo").bbo
    for profile in PROFILES:
        assert_modes_agree(bbo, profile, 500, f"twice ({profile.name})")
