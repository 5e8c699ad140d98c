"""Neighbors: the ``neighbors`` global, broadcast listeners and neighbor data (spec §F.7,
``bbzneighbors.c``).

Two memory models, chosen by the profile, as in the firmware:

* **normal** (PC, Crazyflie, Zooids, M300): the data live in the heap. ``neighbors`` holds
  under string 44 a sub-table robot id → {distance, azimuth, elevation} and under string 45
  an int; ``vm.neighbors.count`` is a separate u8 counter. ``add`` marks an entry (key int 0
  → int 0 in its data table) during the last ``neighbors_mark_time`` cycles before a
  collection; the data GC deletes unmarked entries and unmarks the others.
* **XTREME** (Kilobot): the data live in a ring buffer of ``neighbors_cap + 1`` plain
  records outside the heap; the operations on ``neighbors`` build a temporary data table
  per element, newest first. The data GC reproduces the firmware's ``bringToTop``, which
  swaps positions (pos-1, pos) while a u8 ``pos`` counts up to its wrap-around.

The data GC is run by ``bbzvm_process_outmsgs`` every ``neighbors_clr_period + 1`` calls
(see :func:`process_outmsgs`). Every library closure mirrors its C function, including the
``bbzvm_gc()`` calls, which are visible in the heap bytes.
"""

from __future__ import annotations

import operator
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from bbzide.vm import messages
from bbzide.vm.heap import CLOSURE, INT, STRING
from bbzide.vm.kernels import fasthost, fastloop, kernels_now
from bbzide.vm.messages import RingBuffer
from bbzide.vm.states import Error, State
from bbzide.vm.table_library import (
    CompiledWalk,
    foreach_live,
    table_set_quiet,
    table_size_live,
    table_walk_compiled,
    to_bool,
)
from bbzide.vm.tables import compare, table_get

if TYPE_CHECKING:
    from bbzide.vm.vm import VM

STR_NEIGHBORS = 17
STR_BROADCAST, STR_LISTEN, STR_IGNORE = 29, 30, 31
STR_FOREACH, STR_FILTER, STR_MAP, STR_GET, STR_REDUCE, STR_COUNT = 18, 28, 19, 34, 20, 24
STR_DISTANCE, STR_AZIMUTH, STR_ELEVATION = 21, 22, 23
STR_DATA = 44   # __INTERNAL_1_DO_NOT_USE__: non-XTREME sub-table of neighbor data
STR_RESET = 45  # __INTERNAL_2_DO_NOT_USE__: the int "count" field

#: neighbor record mdata bit that marks an entry as refreshed since the last data GC
MARK = 0x01


@dataclass
class NeighborEntry:
    """``bbzneighbors_elem_t``: ints 0..255 (XTREME/int builds) or bbzfloat bits."""

    robot: int
    distance: int
    azimuth: int
    elevation: int
    mark: int = 0


def _empty_ring(capacity: int) -> RingBuffer[NeighborEntry]:
    return RingBuffer([NeighborEntry(0, 0, 0, 0) for _ in range(capacity)], capacity)


@dataclass
class NeighborsState:
    hpos: int = 0
    listeners: int = 0
    clear_counter: int = 10
    count: int = 0          # non-XTREME u8 counter (``vm->neighbors.count``)
    ring: RingBuffer[NeighborEntry] = field(default_factory=lambda: _empty_ring(16))

    def entries(self) -> list[NeighborEntry]:
        """XTREME ring content, oldest first (ring position 0 first)."""
        return [self.ring.at(i) for i in range(self.ring.size())]


# ---- helpers ------------------------------------------------------------------------------
def _add_data(vm: VM, sid: int, data: int) -> None:
    t = vm.stack[vm.stackptr]
    vm.push_string(sid)
    vm.push(data)
    vm.tput()
    vm.push(t)


def _add_function(vm: VM, sid: int, symbol: str, fn: Callable[[VM], None]) -> None:
    vm.add_function(vm.stack[vm.stackptr], sid, symbol, fn)


def _push_data_table(vm: VM, e: NeighborEntry) -> None:
    """``push_neighbor_data_table``: a new {distance, azimuth, elevation} table."""
    new = vm.new_float if vm.profile.neighbors_floats else vm.new_int
    vm.push_table()
    _add_data(vm, STR_DISTANCE, new(e.distance))
    _add_data(vm, STR_AZIMUTH, new(e.azimuth))
    _add_data(vm, STR_ELEVATION, new(e.elevation))


def _subfield(vm: VM, sid: int) -> int:
    """``bbztable_get_subfield`` of the stack-top table (nil when absent)."""
    v = table_get(vm.heap, vm.stack[vm.stackptr], vm.new_string_obj(sid))
    return vm.nil if v is None else v


def _add_neighborlike_fields(vm: VM, count: int) -> None:
    """The fields and methods of a neighbour-like table (the stack top, just made)."""
    if not vm.profile.xtreme:
        sub = vm.new_table_obj()
        _add_data(vm, STR_DATA, sub)
        cnt = vm.new_int(count)
        _add_data(vm, STR_RESET, cnt)
    if kernels_now(vm):
        # the fast mode adds them in machine code when the heap has room (fasthost)
        addresses = vm.host.register_all(_NEIGHBORLIKE_FUNCTIONS)
        h = vm.heap
        regs = vm.kernel_registers(None, None)
        done = fasthost.add_functions(
            h.view, vm._stack_view, regs, vm.stack[vm.stackptr], _NEIGHBORLIKE_METHOD_SIDS,
            addresses, h.obj_size, h.elems, h.reserved)
        if done:
            vm.take_kernel_registers(regs)
            return
    for sid, symbol, fn in _NEIGHBORLIKE_METHODS:
        _add_function(vm, sid, symbol, fn)


def _is_neighbors_table(vm: VM, self_obj: int) -> bool:
    return compare(vm.heap, self_obj, vm.neighbors.hpos) == 0


def _neighborlike_foreach(vm: VM, fun: Callable[[int, int], None],
                          walk: CompiledWalk | None = None) -> None:
    """Call ``fun(key, data)`` per neighbour. ``walk``: the fast mode may do the XTREME
    ring's neighbours in machine code (:func:`fasthost.xtreme_walk`), the same steps."""
    if not vm.profile.xtreme:
        vm.op_lload(0)
        sub = _subfield(vm, STR_DATA)
        vm.pop()
        start = None
        if walk is not None and kernels_now(vm):
            start = table_walk_compiled(vm, sub, walk)
            if start is None:
                return
        foreach_live(vm, sub, fun, start)
        return
    self_obj = vm.lsym(0)
    if _is_neighbors_table(vm, self_obj):
        ring = vm.neighbors.ring
        i = ring.size()
        if walk is not None and kernels_now(vm):
            i, collected = _walk_compiled(vm, walk)
            if i == 0 and collected and not vm.heap.unsettled:
                # the walk's last act was a collection of these very roots: the one below
                # would change nothing but the count (a collected heap is a fixed point)
                vm.heap.gc_runs += 1
                return
        while i:
            i -= 1
            e = ring.at(i)
            _push_data_table(vm, e)
            data = vm.stack[vm.stackptr]
            vm.pop()
            fun(vm.new_int(e.robot), data)
            vm.gc()
    else:
        foreach_live(vm, self_obj, fun)
    vm.gc()


_ENTRY_FIELDS = operator.attrgetter("robot", "distance", "azimuth", "elevation")


def _ring_rows(ring: RingBuffer[NeighborEntry]) -> np.ndarray:
    """The ring's entries newest first, one (robot, distance, azimuth, elevation) row each,
    as :func:`fasthost.xtreme_walk` reads them."""
    records, start, capacity = ring.records, ring.start, ring.capacity
    count = ring.size()
    flat: list[int] = []
    for i in range(count - 1, -1, -1):  # ring.at(i), inlined: one row per neighbour
        flat.extend(_ENTRY_FIELDS(records[((i + start) & 0xFF) % capacity]))
    return np.array(flat, np.int64).reshape(count, 4)


def _walk_compiled(vm: VM, walk: CompiledWalk) -> tuple[int, bool]:
    """The ring's neighbours, newest first, by :func:`fasthost.xtreme_walk`, re-entered
    after each neighbour it leaves to Python; returns how many (the oldest) are left for
    the Python loop, and whether the last thing done was a collection (of the VM as it is
    now: the end of a neighbour)."""
    kind, closure, result_table, after_call = walk
    rows = _ring_rows(vm.neighbors.ring)
    count = len(rows)
    w = np.zeros(fasthost.WALK_SLOTS, np.int64)
    h = vm.heap
    start = 0
    while True:
        saved, budget = vm.blockptr, vm.instruction_budget
        regs = vm.kernel_registers(saved, budget)
        result = fasthost.xtreme_walk(
            h.view, vm._stack_view, vm._bcode_view, regs, h.gc_info, h.gc_traversed,
            fastloop.RULES, h.obj_size, h.elems, h.reserved, rows, start, kind, closure,
            result_table, vm.profile.neighbors_floats, w, vm.host.computed_rows(),
            *fasthost.NO_HOST_ARGS[1:])
        vm.take_kernel_registers(regs)
        index, status, depth, _segment, _slot, _visit, key, data, _accum = w.tolist()
        if result == fasthost.WALK_DONE or result == fasthost.WALK_PYTHON:
            # the kernel ends each neighbour with a collection
            return count - index, result == fasthost.WALK_DONE and index > start
        if result == fasthost.WALK_IN_CALL:  # closure_call's loop, where the kernel left it
            vm._loop(saved, budget, resume=(status, regs))
        after_call(depth, key, data)
        vm.gc()
        start = index + 1
        if vm.state != State.READY or start == count:
            return count - start, vm.state == State.READY


# ---- library closures -------------------------------------------------------------------
def neighbors_broadcast(vm: VM) -> None:
    if not vm.assert_lnum(2):
        return
    h = vm.heap
    topic, value = vm.lsym(1), vm.lsym(2)
    s = h.obj_size
    messages.outmsg_append_broadcast(vm.queues, vm.robot, h.u16(topic),
                                     bytes(h.data[value * s:value * s + s]))
    vm.ret0()


def neighbors_listen(vm: VM) -> None:
    if not vm.assert_lnum(2):
        return
    topic = vm.lsym(1)
    if not vm.assert_type(topic, STRING):
        return
    c = vm.lsym(2)
    if not vm.assert_type(c, CLOSURE):
        return
    table_set_quiet(vm, vm.neighbors.listeners, topic, c)
    vm.ret0()


def neighbors_ignore(vm: VM) -> None:
    if not vm.assert_lnum(1):
        return
    topic = vm.lsym(1)
    if not vm.assert_type(topic, STRING):
        return
    table_set_quiet(vm, vm.neighbors.listeners, topic, vm.nil)
    vm.ret0()


def neighbors_foreach(vm: VM) -> None:
    if not vm.assert_lnum(1):
        return
    c = vm.lsym(1)
    if not vm.assert_type(c, CLOSURE):
        return

    def fun(key: int, value: int) -> None:
        vm.op_lload(0)
        vm.push(c)
        vm.push(key)
        vm.push(value)
        vm.closure_call(2)
        after_call(0, key, value)

    def after_call(_depth: int, _key: int, _value: int) -> None:
        vm.pop()
        vm.gc()

    _neighborlike_foreach(vm, fun, (fasthost.WALK_FOREACH, c, -1, after_call))
    vm.ret0()


def _map_base(vm: VM, kind: int, put: Callable[[int, int], None]) -> None:
    if not vm.assert_lnum(1):
        return
    c = vm.lsym(1)
    if not vm.assert_type(c, CLOSURE):
        return
    ret_tbl = vm.push_table()
    _add_neighborlike_fields(vm, 0)

    def fun(key: int, value: int) -> None:
        # call_and_take(vm, 0, c, key, value), its end in after_call
        ss = vm.stack_depth()
        vm.op_lload(0)
        vm.push(c)
        vm.push(key)
        vm.push(value)
        vm.closure_call(2)
        after_call(ss, key, value)

    def after_call(ss: int, key: int, value: int) -> None:
        if not vm.stack_depth() > ss:
            vm.seterror(Error.RET)
            return
        ret = vm.stack[vm.stackptr]
        vm.pop()
        vm.push(ret_tbl)
        vm.push_int(key)  # bbzvm_pushi(key): the firmware pushes the key's heap index
        put(value, ret)
        vm.gc()

    _neighborlike_foreach(vm, fun, (kind, c, ret_tbl, after_call))
    vm.ret1()


def neighbors_map(vm: VM) -> None:
    def put(_value: int, ret: int) -> None:
        vm.push(ret)
        vm.tput()

    _map_base(vm, fasthost.WALK_MAP, put)


def neighbors_filter(vm: VM) -> None:
    def put(value: int, ret: int) -> None:
        if to_bool(vm, ret):
            vm.push(value)
            vm.tput()
        else:
            vm.pop()
            vm.pop()

    _map_base(vm, fasthost.WALK_FILTER, put)


def neighbors_reduce(vm: VM) -> None:
    if not vm.assert_lnum(2):
        return
    c = vm.lsym(1)
    if not vm.assert_type(c, CLOSURE):
        return
    vm.op_lload(2)

    def fun(key: int, value: int) -> None:
        accum = vm.stack[vm.stackptr]
        vm.pop()
        ss = vm.stack_depth()
        vm.op_lload(0)
        vm.push(c)
        vm.push(key)
        vm.push(value)
        vm.push(accum)
        vm.closure_call(3)
        after_call(ss, key, value)

    def after_call(ss: int, _key: int, _value: int) -> None:
        if not vm.stack_depth() > ss:
            vm.seterror(Error.RET)
            return
        vm.gc()

    _neighborlike_foreach(vm, fun, (fasthost.WALK_REDUCE, c, -1, after_call))
    vm.ret1()


def neighbors_get(vm: VM) -> None:
    if not vm.assert_lnum(1):
        return
    robot = vm.lsym(1)
    if not vm.assert_type(robot, INT):
        return
    if not vm.profile.xtreme:
        vm.op_lload(0)
        vm.push_string(STR_DATA)
        vm.op_tget()
        vm.op_lload(1)
        vm.op_tget()
        vm.ret1()
        return
    wanted = vm.heap.int_value(robot)
    found = False

    def fun(key: int, value: int) -> None:
        nonlocal found
        if not found and vm.heap.int_value(key) == wanted:
            found = True
            vm.push(value)

    _neighborlike_foreach(vm, fun)
    if not found:
        vm.push_nil()
    vm.ret1()
    vm.gc()


def neighbors_count(vm: VM) -> None:
    if not vm.assert_lnum(0):
        return
    if not vm.profile.xtreme:
        vm.op_lload(0)
        data = _subfield(vm, STR_DATA)
        vm.pop()
        vm.push_int(table_size_live(vm, data))
        vm.ret1()
        return
    if _is_neighbors_table(vm, vm.lsym(0)):
        vm.push_int(vm.neighbors.ring.size())
    else:
        vm.op_lload(0)
        vm.push_string(STR_RESET)
        vm.op_tget()
    vm.ret1()


# ---- platform side: bbzneighbors_add and the data GC ------------------------------------
#: ``bbztable_set(t, bbzint_new(0), bbzint_new(0))``: which of the two int 0 objects the
#: compiler allocates first (argument evaluation order); the corpus decides.
_MARK_VALUE_FIRST = True


def add(vm: VM, entry: NeighborEntry) -> None:
    """``bbzneighbors_add`` (called by the platform's receive handler)."""
    n = vm.neighbors
    p = vm.profile
    if p.xtreme:
        ring = n.ring
        records = ring.records
        where = ring.indices()
        i = len(where)
        while i:
            i -= 1
            e = records[where[i]]
            if e.robot == entry.robot:
                e.distance, e.azimuth, e.elevation = entry.distance, entry.azimuth, \
                    entry.elevation
                if n.clear_counter < p.neighbors_mark_time:
                    e.mark |= MARK
                # swaps (pos, pos + 1) up to the end: the entry moves last, the rest
                # shift down one place
                for a, b in zip(where[i:], where[i + 1:], strict=False):
                    records[a] = records[b]
                records[where[-1]] = e
                return
        slot = ring.raw_index(ring.makeslot())
        e = ring.records[slot]
        e.robot, e.distance, e.azimuth, e.elevation = entry.robot, entry.distance, \
            entry.azimuth, entry.elevation
        if n.clear_counter < p.neighbors_mark_time:
            e.mark |= MARK
        return
    vm.push(n.hpos)
    n.count = (n.count + 1) & 0xFF
    vm.push_string(STR_DATA)
    vm.op_tget()
    vm.push_int(entry.robot)
    _push_data_table(vm, entry)
    if n.clear_counter < p.neighbors_mark_time:
        if _MARK_VALUE_FIRST:
            v = vm.new_int(0)
            k = vm.new_int(0)
        else:
            k = vm.new_int(0)
            v = vm.new_int(0)
        if not table_set_quiet(vm, vm.stack[vm.stackptr], k, v):
            vm.seterror(Error.MEM)
            return
    vm.tput()


def data_gc(vm: VM) -> None:
    """``bbzneighbors_data_gc``: drop the entries not refreshed since the last one."""
    n = vm.neighbors
    if vm.profile.xtreme:
        ring = n.ring
        unmarked = 0
        i = 0
        while i < ring.size():
            if not ring.at(i).mark & MARK:
                pos = i
                while pos > 0:  # bringToTop: u8 pos counts up until it wraps to 0
                    ring.swap((pos - 1) & 0xFF, pos)
                    pos = (pos + 1) & 0xFF
                unmarked += 1
            else:
                ring.at(i).mark &= ~MARK & 0xFF
            i = (i + 1) & 0xFF
        for _ in range(unmarked):
            ring.pop()
        return
    tbl = table_get(vm.heap, n.hpos, vm.new_string_obj(STR_DATA))
    if tbl is None:
        vm.seterror(Error.MEM)
        return

    def fun(key: int, value: int) -> None:
        if table_get(vm.heap, value, vm.new_int(0)) is None:
            n.count = (n.count - 1) & 0xFF
            table_set_quiet(vm, tbl, key, vm.nil)
        else:
            table_set_quiet(vm, value, vm.new_int(0), vm.nil)

    foreach_live(vm, tbl, fun)


def process_outmsgs(vm: VM) -> None:
    """``bbzvm_process_outmsgs``: the neighbor-data GC on every 11th call (u8 countdown)."""
    n = vm.neighbors
    was = n.clear_counter
    n.clear_counter = (n.clear_counter - 1) & 0xFF
    if was == 0:
        n.clear_counter = vm.profile.neighbors_clr_period
        data_gc(vm)


def register(vm: VM) -> None:
    """``bbzneighbors_register`` in the reference allocation order (spec §E.11 step 9)."""
    p = vm.profile
    vm.neighbors = NeighborsState(clear_counter=p.neighbors_clr_period,
                                  ring=_empty_ring(p.neighbors_cap + 1))
    vm.push_string(STR_NEIGHBORS)
    lst = vm.push_table()
    vm.pop()
    t = vm.push_table()
    vm.neighbors.hpos = t
    vm.neighbors.listeners = lst
    vm.make_permanent(t)
    vm.make_permanent(lst)
    if p.xtreme:
        vm.push_int(0)
        cnt = vm.stack[vm.stackptr]
        vm.pop()
        _add_data(vm, STR_RESET, cnt)
    _add_function(vm, STR_BROADCAST, "bbzneighbors_broadcast", neighbors_broadcast)
    _add_function(vm, STR_LISTEN, "bbzneighbors_listen", neighbors_listen)
    _add_function(vm, STR_IGNORE, "bbzneighbors_ignore", neighbors_ignore)
    _add_neighborlike_fields(vm, 0)
    vm.gstore()


#: (name, symbol, function) of a neighbour-like table's methods, in the firmware's order
_NEIGHBORLIKE_METHODS: tuple[tuple[int, str, Callable[[VM], None]], ...] = (
    (STR_FOREACH, "bbzneighbors_foreach", neighbors_foreach),
    (STR_FILTER, "bbzneighbors_filter", neighbors_filter),
    (STR_MAP, "bbzneighbors_map", neighbors_map),
    (STR_GET, "bbzneighbors_get", neighbors_get),
    (STR_REDUCE, "bbzneighbors_reduce", neighbors_reduce),
    (STR_COUNT, "bbzneighbors_count", neighbors_count))
#: their names' string ids, as fasthost.add_functions takes them
_NEIGHBORLIKE_METHOD_SIDS = np.array([sid for sid, _symbol, _fn in _NEIGHBORLIKE_METHODS],
                                     np.int64)
#: their (symbol, function) pairs, as HostRegistry.register_all takes them
_NEIGHBORLIKE_FUNCTIONS = tuple((symbol, fn) for _sid, symbol, fn in _NEIGHBORLIKE_METHODS)
