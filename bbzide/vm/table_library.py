"""Global table closures ``foreach filter map reduce size`` (``bbztable.c``, spec §E.6) and the
live segment walk they share with the neighbors library.

Registered at the end of construct with ``function_register`` (closure first, then the
name string). The walk (``bbztable_foreach``) reads the segments while the callbacks run,
exactly like the C loop: a callback that changes the table changes what is visited next,
and a key whose entry is deleted in the current segment is skipped. The walk does not
check that ``t`` is a table (neither does the C); it stops at a segment index outside the
heap and after as many segment visits as the heap can hold (a corrupted chain would make
the firmware loop forever; the model stops instead).

In the fast mode ``foreach``, ``map``, ``filter`` and ``reduce`` walk the table in machine
code (``fasthost.table_walk``, :func:`walk_live`: the same live reads, the same calls),
handing an element back to this loop wherever the kernel does not cover it; an M300
flocking drone's ``foreach(neighbours, repel)`` was two thirds of its control step in
Python.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING

import numpy as np

from bbzide.vm.heap import CLOSURE, ELEM_INDEX, ELEM_VALID, INT, SEG_NEXT, TABLE, HeapFull
from bbzide.vm.kernels import fasthost, fastloop, kernels_now
from bbzide.vm.states import Error, State
from bbzide.vm.tables import table_set

if TYPE_CHECKING:
    from bbzide.vm.vm import VM

STR_FOREACH, STR_FILTER, STR_MAP, STR_REDUCE, STR_SIZE = 18, 28, 19, 20, 35


def foreach_live(vm: VM, t: int, fun: Callable[[int, int], None],
                 start: tuple[int, int, int] | None = None) -> None:
    """``bbztable_foreach``: call ``fun(key, value)`` for every valid element, live.
    ``start``: (segment, slot, segment visit) to go on from, where a compiled walk
    (``fasthost.table_walk``) stopped."""
    h = vm.heap
    E = h.elems
    max_segments = h.size // h.seg_size
    si, first, visit = (h.u16(t), 0, 0) if start is None else start
    for _ in range(visit, max_segments + 1):
        if si >= max_segments:
            return
        for i in range(first, E):
            kw = h.word(si, i)
            if kw & ELEM_VALID:
                fun(kw & ELEM_INDEX, h.word(si, i + E) & ELEM_INDEX)
        first = 0
        si = h.seg_next(si)
        if si == SEG_NEXT:
            return


#: What a compiled walk (:func:`table_walk_compiled`) needs: the walk's kind
#: (``fasthost.WALK_*``), the closure, the map/filter return table (else -1) and the rest of
#: ``fun`` once ``closure_call`` has returned, given the stack depth before the call, the
#: element's key and its value.
CompiledWalk = tuple[int, int, int, Callable[[int, int, int], None]]


def table_walk_compiled(vm: VM, t: int, walk: CompiledWalk,
                        accum: list[int] | None = None) -> tuple[int, int, int] | None:
    """Table ``t``'s elements by :func:`fasthost.table_walk`, re-entered after each call
    it leaves to Python; the (segment, slot, visit) :func:`foreach_live` goes on from, or
    None when the walk is over. ``accum``: the table library's reduce accumulator, in and
    out (``after_call`` updates it for a call Python ended). The host functions a kernel
    computes in place (``HostRegistry.computed_rows``) run in the calls; the queues are not
    packed here, so no other host function does."""
    kind, closure, result_table, after_call = walk
    w = np.zeros(fasthost.WALK_SLOTS, np.int64)
    h = vm.heap
    w[fasthost.W_SEGMENT] = h.u16(t)
    _hosts, outq, ctl, latch = fasthost.NO_HOST_ARGS
    hosts = vm.host.computed_rows()
    while True:
        saved, budget = vm.blockptr, vm.instruction_budget
        regs = vm.kernel_registers(saved, budget)
        if accum is not None:
            w[fasthost.W_ACCUM] = accum[0]
        result = fasthost.table_walk(
            h.view, vm._stack_view, vm._bcode_view, regs, h.gc_info, h.gc_traversed,
            fastloop.RULES, h.obj_size, h.elems, h.reserved, kind, closure, result_table, w,
            hosts, outq, ctl, latch)
        vm.take_kernel_registers(regs)
        _index, status, depth, segment, slot, visit, key, data, reduced = w.tolist()
        if accum is not None:
            accum[0] = reduced
        if result == fasthost.WALK_DONE:
            return None
        if result == fasthost.WALK_PYTHON:
            return segment, slot, visit
        if result == fasthost.WALK_IN_CALL:  # closure_call's loop, where the kernel left it
            vm._loop(saved, budget, resume=(status, regs))
        after_call(depth, key, data)
        if vm.state != State.READY:
            return segment, slot + 1, visit
        w[fasthost.W_SLOT] = slot + 1


def walk_live(vm: VM, t: int, fun: Callable[[int, int], None], walk: CompiledWalk,
              accum: list[int] | None = None) -> None:
    """:func:`foreach_live` of ``fun`` over ``t``, in machine code where the fast mode
    covers it (:func:`table_walk_compiled` with ``walk``; ``accum`` as there)."""
    start = None
    if kernels_now(vm):
        start = table_walk_compiled(vm, t, walk, accum)
        if start is None:
            return
    foreach_live(vm, t, fun, start)


def table_size_live(vm: VM, t: int) -> int:
    """``bbztable_size`` (u8 count of valid keys over the chain, no type check)."""
    n = 0

    def count(_k: int, _v: int) -> None:
        nonlocal n
        n += 1

    foreach_live(vm, t, count)
    return n & 0xFF


def table_set_quiet(vm: VM, t: int, k: int, v: int) -> bool:
    """``bbztable_set`` called directly by library C code: a full heap is NOT an error."""
    try:
        return table_set(vm.heap, t, k, v)
    except HeapFull:
        return False


def to_bool(vm: VM, o: int) -> bool:
    """``bbztype_tobool``: only a non-zero int is true."""
    return vm.heap.obj_type(o) == INT and vm.heap.u16(o) != 0


def call_and_take(vm: VM, self_slot: int, c: int, *args: int) -> int | None:
    """Call closure ``c`` as the C library loops do (``bbzvm_lload(self_slot)``, push ``c``
    and ``args``, ``bbzvm_closure_call``), then pop and return its result; when it left
    nothing on the stack, set BBZVM_ERROR_RET and return None."""
    ss = vm.stack_depth()
    vm.op_lload(self_slot)
    vm.push(c)
    for arg in args:
        vm.push(arg)
    vm.closure_call(len(args))
    return take_result(vm, ss)


def take_result(vm: VM, depth: int) -> int | None:
    """The end of :func:`call_and_take` once the call returned (``depth``: the stack
    depth before its pushes): pop and return the result, or RET when there is none."""
    if not vm.stack_depth() > depth:
        vm.seterror(Error.RET)
        return None
    ret = vm.stack[vm.stackptr]
    vm.pop()
    return ret


def table_foreach(vm: VM) -> None:
    if not vm.assert_lnum(2):
        return
    t = vm.lsym(1)
    if not vm.assert_type(t, TABLE):
        return
    c = vm.lsym(2)
    if not vm.assert_type(c, CLOSURE):
        return

    def entry(key: int, value: int) -> None:
        call_and_take(vm, 1, c, key, value)

    def after_call(depth: int, _key: int, _value: int) -> None:
        take_result(vm, depth)

    walk_live(vm, t, entry, (fasthost.WALK_TABLE_FOREACH, c, -1, after_call))
    vm.ret0()


def _map_base(vm: VM, kind: int, keep: Callable[[int, int, int, int], None]) -> None:
    if not vm.assert_lnum(2):
        return
    t = vm.lsym(1)
    if not vm.assert_type(t, TABLE):
        return
    c = vm.lsym(2)
    if not vm.assert_type(c, CLOSURE):
        return
    ret_tbl = vm.push_table()

    def entry(key: int, value: int) -> None:
        ret = call_and_take(vm, 1, c, key, value)
        if ret is not None:
            keep(ret_tbl, key, value, ret)

    def after_call(depth: int, key: int, value: int) -> None:
        ret = take_result(vm, depth)
        if ret is not None:
            keep(ret_tbl, key, value, ret)

    walk_live(vm, t, entry, (kind, c, ret_tbl, after_call))
    vm.ret1()


def table_map(vm: VM) -> None:
    _map_base(vm, fasthost.WALK_TABLE_MAP,
              lambda t, k, _v, ret: table_set_quiet(vm, t, k, ret) and None)


def table_filter(vm: VM) -> None:
    def keep(t: int, k: int, v: int, ret: int) -> None:
        if to_bool(vm, ret):
            table_set_quiet(vm, t, k, v)

    _map_base(vm, fasthost.WALK_TABLE_FILTER, keep)


def table_reduce(vm: VM) -> None:
    if not vm.assert_lnum(3):
        return
    t = vm.lsym(1)
    if not vm.assert_type(t, TABLE):
        return
    c = vm.lsym(2)
    if not vm.assert_type(c, CLOSURE):
        return
    accum = [vm.lsym(3)]  # held by the C loop's local, not on the stack

    def entry(key: int, value: int) -> None:
        ret = call_and_take(vm, 1, c, key, value, accum[0])
        if ret is not None:
            accum[0] = ret

    def after_call(depth: int, _key: int, _value: int) -> None:
        ret = take_result(vm, depth)
        if ret is not None:
            accum[0] = ret

    walk_live(vm, t, entry, (fasthost.WALK_TABLE_REDUCE, c, -1, after_call), accum)
    vm.push(accum[0])
    vm.ret1()


def table_size(vm: VM) -> None:
    if not vm.assert_lnum(1):
        return
    t = vm.lsym(1)
    if not vm.assert_type(t, TABLE):
        return
    vm.push_int(table_size_live(vm, t))
    vm.ret1()


def register(vm: VM) -> None:
    vm.function_register(STR_FOREACH, "table_foreach", table_foreach)
    vm.function_register(STR_FILTER, "table_filter", table_filter)
    vm.function_register(STR_MAP, "table_map", table_map)
    vm.function_register(STR_REDUCE, "table_reduce", table_reduce)
    vm.function_register(STR_SIZE, "table_size", table_size)
