"""Swarms: the ``swarm`` global, the swarm stack and this robot's membership (spec §F.8,
``bbzswarm.c`` with swarm-list broadcasts disabled, as in every reference build).

Membership is one byte, ``my_swarmlist`` (bit k = member of swarm k, ids 0..7); nothing is
sent and other robots' memberships are not tracked (asking about another robot is an
OUTOFRANGE error). ``swarm.intersection/union/difference`` and ``others`` exist only when
swarm-list broadcasts are enabled, so in these builds looking them up gives nil (the
corpus's ``swarm_setops`` ends with TYPE). ``exec`` pushes the swarm id on the swarm stack
(a heap darray) while the closure runs; ``swarm.id(n)`` reads it n entries from the top.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

from bbzide.vm.heap import CLOSURE, HeapFull
from bbzide.vm.states import Error
from bbzide.vm.table_library import to_bool
from bbzide.vm.tables import darray_get, darray_pop, darray_push, darray_size

if TYPE_CHECKING:
    from bbzide.vm.vm import VM

STR_ID, STR_SWARM, STR_CREATE = 0, 1, 2
STR_SELECT, STR_JOIN, STR_UNSELECT, STR_LEAVE, STR_IN, STR_EXEC = 3, 8, 9, 10, 11, 12

#: swarm ids fit the 8-bit membership list (``8 * sizeof(bbzswarmlist_t)``)
MAX_SWARMS = 8


@dataclass
class SwarmState:
    hpos: int = 0          # the swarm table
    swarmstack: int = 0    # darray of swarm ids being executed
    my_swarmlist: int = 0  # bit k = member of swarm k


def _bit(vm: VM, swarm: int) -> int:
    """``swarmlist_entry_fromswarm``: SWARM error (and an empty list) for ids ≥ 8."""
    if swarm < MAX_SWARMS:
        return 1 << swarm
    vm.seterror(Error.SWARM)
    return 0


def _get_id(vm: VM) -> int:
    """``get_id``: the ``id`` field of the stack-top table, as an unsigned 16-bit value."""
    vm.push_string(STR_ID)
    vm.op_tget()
    swarm = vm.heap.u16(vm.stack[vm.stackptr])
    vm.pop()
    return swarm


def _add_function(vm: VM, sid: int, symbol: str, fn: object) -> None:
    vm.add_function(vm.stack[vm.stackptr], sid, symbol, fn)  # type: ignore[arg-type]


def swarm_create(vm: VM) -> None:
    if not vm.assert_lnum(1):
        return
    swarm = vm.heap.u16(vm.lsym(1))
    if swarm < MAX_SWARMS:
        vm.push_table()
        vm.push_int(swarm)
        obj = vm.stack[vm.stackptr]
        vm.pop()
        t = vm.stack[vm.stackptr]
        vm.push_string(STR_ID)
        vm.push(obj)
        vm.tput()
        vm.push(t)
        _add_function(vm, STR_JOIN, "bbzswarm_join", swarm_join)
        _add_function(vm, STR_LEAVE, "bbzswarm_leave", swarm_leave)
        _add_function(vm, STR_IN, "bbzswarm_in", swarm_in)
        _add_function(vm, STR_SELECT, "bbzswarm_select", swarm_select)
        _add_function(vm, STR_UNSELECT, "bbzswarm_unselect", swarm_unselect)
        _add_function(vm, STR_EXEC, "bbzswarm_exec", swarm_exec)
    else:
        vm.push_nil()
        vm.seterror(Error.SWARM)
    vm.ret1()


def swarm_id(vm: VM) -> None:
    h = vm.heap
    argc = darray_size(h, vm.lsyms) - 1
    if not argc <= 1:
        vm.seterror(Error.LNUM)
        return
    stack = vm.swarm.swarmstack
    if darray_size(h, stack) > 0:
        depth = 0 if argc == 0 else h.u16(vm.lsym(1))
        sz = darray_size(h, stack)
        if not depth < sz:
            vm.seterror(Error.OUTOFRANGE)
            return
        v = darray_get(h, stack, sz - depth - 1)
        vm.push(vm.nil if v is None else v)
    else:
        vm.push_nil()
        vm.seterror(Error.OUTOFRANGE)
    vm.ret1()


def _addrm(vm: VM, add: bool) -> None:
    vm.op_lload(0)
    swarm = _get_id(vm)
    bit = _bit(vm, swarm)
    if add:
        vm.swarm.my_swarmlist |= bit
    else:
        vm.swarm.my_swarmlist &= ~bit & 0xFF


def swarm_join(vm: VM) -> None:
    if not vm.assert_lnum(0):
        return
    _addrm(vm, True)
    vm.ret0()


def swarm_leave(vm: VM) -> None:
    if not vm.assert_lnum(0):
        return
    _addrm(vm, False)
    vm.ret0()


def swarm_in(vm: VM) -> None:
    if not vm.assert_lnum(0):
        return
    vm.op_lload(0)
    swarm = _get_id(vm)
    bit = _bit(vm, swarm)
    vm.push_int(1 if vm.swarm.my_swarmlist & bit else 0)
    vm.ret1()


def _select(vm: VM, select: bool) -> None:
    if to_bool(vm, vm.lsym(1)):
        _addrm(vm, select)


def swarm_select(vm: VM) -> None:
    if not vm.assert_lnum(1):
        return
    _select(vm, True)
    vm.ret0()


def swarm_unselect(vm: VM) -> None:
    if not vm.assert_lnum(1):
        return
    _select(vm, False)
    vm.ret0()


def swarm_exec(vm: VM) -> None:
    if not vm.assert_lnum(1):
        return
    if not vm.assert_type(vm.lsym(1), CLOSURE):
        return
    vm.op_lload(0)
    swarm = _get_id(vm)
    if vm.swarm.my_swarmlist & _bit(vm, swarm):
        vm.push_int(swarm)
        obj = vm.stack[vm.stackptr]
        vm.pop()
        try:  # the C ignores bbzdarray_push's failure
            darray_push(vm.heap, vm.swarm.swarmstack, obj)
        except HeapFull:
            pass
        vm.op_lload(0)
        vm.op_lload(1)
        vm.closure_call(0)
        darray_pop(vm.heap, vm.swarm.swarmstack)
    vm.ret0()


def register(vm: VM) -> None:
    """``bbzswarm_register`` (swarmlist broadcasts disabled, the default)."""
    from bbzide.vm.tables import darray_new

    vm.swarm = SwarmState()
    vm.push_string(STR_SWARM)
    t = vm.push_table()
    vm.make_permanent(t)
    vm.swarm.hpos = t
    d = vm.alloc_or_mem(darray_new)
    vm.make_permanent(d)
    vm.swarm.swarmstack = d
    vm.add_function(t, STR_CREATE, "bbzswarm_create", swarm_create)
    vm.add_function(t, STR_ID, "bbzswarm_id", swarm_id)
    vm.gstore()
