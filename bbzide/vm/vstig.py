"""Virtual stigmergy: the ``stigmergy`` global and the single vstig store (spec §F.6,
``bbzvstig.c``, ``bbzmsg.c`` ``bbzmsg_process_vstig``).

BittyBuzz keeps ONE store for every ``stigmergy.create(id)`` (the id is never used and never
sent): ``vm->vstig.data`` entries {key string id, value heap index, u8 Lamport timestamp,
robot}. Local puts stop at ``vstig_cap`` entries (error VSTIG); entries learnt from messages
are appended without a capacity check (the firmware overflows its array; the model just
grows the list). Stored values are made permanent so the GC keeps them.

Each function below mirrors one C function statement by statement, including the
``bbzvm_gc()`` calls in the middle of them, because those collections are visible in the
heap bytes. A failed assertion returns without ``ret`` exactly where the C macro returns.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING

from bbzide.vm import messages
from bbzide.vm.heap import STRING, TABLE, USERDATA, VALID, HeapFull
from bbzide.vm.states import Error
from bbzide.vm.tables import table_get

if TYPE_CHECKING:
    from bbzide.vm.vm import VM

# Base string ids of the BittyBuzz .bst (spec §D.2)
STR_STIGMERGY = 32
STR_CREATE = 2
STR_ID = 0
STR_PUT, STR_GET, STR_SIZE = 33, 34, 35
STR_ONCONFLICT, STR_ONCONFLICTLOST = 36, 37
STR_ROBOT, STR_DATA, STR_TIMESTAMP = 38, 27, 39
STR_ONCONFLICT_FIELD = 44      # __INTERNAL_1_DO_NOT_USE__: where onconflict(f) keeps f
STR_ONCONFLICTLOST_FIELD = 45  # __INTERNAL_2_DO_NOT_USE__


@dataclass
class VstigEntry:
    key: int        # string id
    value: int      # heap index
    timestamp: int  # Lamport clock (u8)
    robot: int


@dataclass
class VstigStore:
    """``vm->vstig``: the ``stigmergy`` table object and the entry store."""

    hpos: int = 0
    entries: list[VstigEntry] = field(default_factory=list)


def _add_data(vm: VM, sid: int, data: int) -> None:
    """``bbztable_add_data``: the table is the stack top and stays there."""
    t = vm.stack[vm.stackptr]
    vm.push_string(sid)
    vm.push(data)
    vm.tput()
    vm.push(t)


def _add_function(vm: VM, sid: int, symbol: str, fn: object) -> None:
    """``bbztable_add_function`` on the table at the stack top."""
    vm.add_function(vm.stack[vm.stackptr], sid, symbol, fn)  # type: ignore[arg-type]


def _entry_of(vm: VM, key: int) -> VstigEntry | None:
    """The first entry whose key, as a temporary string object, ``bbztype_cmp``-equals the
    key object ``key``: a string of the same id (any other type matches no entry)."""
    h = vm.heap
    if h.obj_type(key) != STRING:
        return None
    sid = h.u16(key)
    for e in vm.vstig.entries:
        if e.key == sid:
            return e
    return None


def _obj_bytes(vm: VM, i: int) -> bytes:
    s = vm.heap.obj_size
    return bytes(vm.heap.data[i * s:i * s + s])


def queue_vstig(vm: VM, typ: int, robot: int, key: int, value: int, lamport: int) -> None:
    """``bbzoutmsg_queue_append_vstig`` (the value object's bytes are copied)."""
    messages.outmsg_append_vstig(vm.queues, typ, robot, key, _obj_bytes(vm, value), lamport)


# ---- library closures -------------------------------------------------------------------
def vstig_create(vm: VM) -> None:
    if not vm.assert_lnum(1):
        return
    vm.vstig.entries.clear()
    vm.push_table()
    _add_data(vm, STR_ID, vm.lsym(1))
    _add_function(vm, STR_PUT, "bbzvstig_put", vstig_put)
    _add_function(vm, STR_GET, "bbzvstig_get", vstig_get)
    vm.gc()
    _add_function(vm, STR_SIZE, "bbzvstig_size", vstig_size)
    _add_function(vm, STR_ONCONFLICT, "bbzvstig_onconflict", vstig_onconflict)
    vm.gc()
    _add_function(vm, STR_ONCONFLICTLOST, "bbzvstig_onconflictlost", vstig_onconflictlost)
    vm.ret1()
    vm.gc()


def _set_handler(vm: VM, field_sid: int) -> None:
    if not vm.assert_lnum(1):
        return
    vm.push(vm.vstig.hpos)
    vm.gc()
    _add_data(vm, field_sid, vm.lsym(1))
    vm.gc()
    vm.ret0()
    vm.gc()


def vstig_onconflict(vm: VM) -> None:
    _set_handler(vm, STR_ONCONFLICT_FIELD)


def vstig_onconflictlost(vm: VM) -> None:
    _set_handler(vm, STR_ONCONFLICTLOST_FIELD)


def vstig_get(vm: VM) -> None:
    from bbzide.vm.messages import VSTIG_QUERY

    if not vm.assert_lnum(1):
        return
    key = vm.lsym(1)
    vm.gc()
    e = _entry_of(vm, key)
    if e is not None:
        queue_vstig(vm, VSTIG_QUERY, e.robot, e.key, e.value, e.timestamp)
        vm.push(e.value)
        vm.ret1()
        vm.gc()
        return
    vm.push_nil()
    queue_vstig(vm, VSTIG_QUERY, vm.robot, vm.heap.u16(key), vm.nil, 0)
    vm.ret1()
    vm.gc()


def vstig_put(vm: VM) -> None:
    from bbzide.vm.messages import VSTIG_PUT

    if not vm.assert_lnum(2):
        return
    key = vm.lsym(1)
    value = vm.lsym(2)
    if vm.heap.obj_type(value) == TABLE:
        vm.seterror(Error.TYPE)
        return
    vm.gc()
    e = _entry_of(vm, key)
    if e is not None:
        e.robot = vm.robot
        vm.unmake_permanent(e.value)
        e.value = value
        vm.make_permanent(value)
        vm.gc()
        e.timestamp = (e.timestamp + 1) & 0xFF
        queue_vstig(vm, VSTIG_PUT, e.robot, e.key, e.value, e.timestamp)
        vm.ret0()
        vm.gc()
        return
    if len(vm.vstig.entries) < vm.profile.vstig_cap:
        e = VstigEntry(key=vm.heap.u16(key), value=value, timestamp=1, robot=vm.robot)
        vm.make_permanent(key)
        vm.make_permanent(value)
        vm.vstig.entries.append(e)
        queue_vstig(vm, VSTIG_PUT, e.robot, e.key, e.value, e.timestamp)
    else:
        vm.seterror(Error.VSTIG)
    vm.ret0()
    vm.gc()


def vstig_size(vm: VM) -> None:
    if not vm.assert_lnum(0):
        return
    vm.push_int(len(vm.vstig.entries) & 0xFF)
    vm.ret1()


# ---- incoming messages (bbzmsg_process_vstig) -----------------------------------------
def is_newer(vm: VM, lamport: int, old: int) -> bool:
    """``bbzlamport_isnewer``: circular u8 comparison within the threshold."""
    return lamport != old and ((lamport - old) & 0xFF) < vm.profile.lamport_threshold


def _alloc_copy(vm: VM, obj: bytes) -> int | None:
    """Allocate a slot (as userdata) and overwrite it with the message's object copy."""
    h = vm.heap
    try:
        o = h.obj_alloc(USERDATA)
    except HeapFull:
        vm.seterror(Error.MEM)
        return None
    s = h.obj_size
    h.data[o * s:o * s + s] = obj
    h.data[o * s] |= VALID
    return o


def process_vstig(vm: VM, rec: bytearray) -> bool:
    """``bbzmsg_process_vstig``. True when it ended with its collection (the in-queue loop
    may then count, not run, the next message's: ``inmsgs.go_on_inmsgs``)."""
    from bbzide.vm.messages import VSTIG_PUT, VSTIG_QUERY

    h = vm.heap
    typ = messages.rec_type(rec)
    rid = messages.rec_rid(rec)
    key = messages.rec_key(rec)
    lamport = messages.rec_lamport(rec)
    obj = messages.rec_value(rec, h.obj_size)
    for e in vm.vstig.entries:
        if e.key != key:
            continue
        if is_newer(vm, lamport, e.timestamp):
            e.robot = rid
            h.set_mdata(e.value, h.mdata(e.value) & ~VALID & 0xFF)
            o = _alloc_copy(vm, obj)
            if o is None:
                return False
            vm.unmake_permanent(e.value)
            e.value = o
            vm.make_permanent(o)
            e.timestamp = lamport
            queue_vstig(vm, VSTIG_PUT, e.robot, e.key, e.value, e.timestamp)
        elif typ == VSTIG_QUERY and is_newer(vm, e.timestamp, lamport):
            queue_vstig(vm, VSTIG_PUT, vm.robot, key, e.value, e.timestamp)
        elif e.timestamp == lamport and e.robot != rid:
            if not _conflict(vm, e, rid, key, lamport, obj):
                return False
        break
    else:
        o = _alloc_copy(vm, obj)
        if o is None:
            return False
        vm.make_permanent(o)
        e = VstigEntry(key=key, value=o, timestamp=lamport, robot=rid)
        vm.vstig.entries.append(e)
        queue_vstig(vm, VSTIG_PUT, e.robot, e.key, e.value, e.timestamp)
    vm.gc()
    return True


def _conflict(vm: VM, e: VstigEntry, rid: int, key: int, lamport: int, obj: bytes) -> bool:
    """Same timestamp, different robot. False when the C code returns early (an error)."""
    from bbzide.vm.messages import VSTIG_PUT
    h = vm.heap
    handler = table_get(h, vm.vstig.hpos, vm.new_string_obj(STR_ONCONFLICT_FIELD))
    if handler is not None:
        vm.push_nil()
        vm.push(handler)
        vm.push_string(key)
        vm.push_table()
        _add_data(vm, STR_ROBOT, vm.new_int(e.robot))
        _add_data(vm, STR_DATA, e.value)
        _add_data(vm, STR_TIMESTAMP, vm.new_int(e.timestamp))
        vm.push_table()
        rd = vm.stack[vm.stackptr]
        _add_data(vm, STR_ROBOT, vm.new_int(rid))
        o = _alloc_copy(vm, obj)
        if o is None:
            return False
        _add_data(vm, STR_DATA, o)
        _add_data(vm, STR_TIMESTAMP, vm.new_int(lamport))
        vm.closure_call(3)
        if h.obj_type(vm.stack[vm.stackptr]) != TABLE:
            vm.seterror(Error.RET)
            return False
        res = vm.stack[vm.stackptr]
        r = table_get(h, res, vm.new_string_obj(STR_ROBOT))
        old_rid = e.robot
        if r:
            e.robot = h.u16(r)
        h.set_mdata(e.value, h.mdata(e.value) & ~VALID & 0xFF)
        vm.unmake_permanent(e.value)
        d = table_get(h, res, vm.new_string_obj(STR_DATA))
        tmp = vm.nil if d is None else d
        e.value = tmp
        vm.make_permanent(tmp)
        e.timestamp = lamport
        if h.int_value(tmp) != vm.robot and old_rid == vm.robot:
            lost = table_get(h, vm.vstig.hpos, vm.new_string_obj(STR_ONCONFLICTLOST_FIELD))
            if lost is not None:
                vm.push_nil()
                vm.push(lost)
                vm.push_string(key)
                vm.push(rd)
                vm.closure_call(2)
        queue_vstig(vm, VSTIG_PUT, e.robot, e.key, e.value, e.timestamp)
    else:
        if rid >= e.robot:
            e.robot = rid
            h.set_mdata(e.value, h.mdata(e.value) & ~VALID & 0xFF)
            o = _alloc_copy(vm, obj)
            if o is None:
                return False
            vm.unmake_permanent(e.value)
            e.value = o
            vm.make_permanent(o)
            e.timestamp = lamport
        queue_vstig(vm, VSTIG_PUT, e.robot, e.key, e.value, e.timestamp)
    return True


def register(vm: VM) -> None:
    """``bbzvstig_register``: pushs stigmergy; table; add create; permanent; gstore; GC."""
    vm.vstig = VstigStore()
    vm.push_string(STR_STIGMERGY)
    t = vm.push_table()
    vm.vstig.hpos = t
    vm.add_function(t, STR_CREATE, "bbzvstig_create", vstig_create)
    vm.make_permanent(t)
    vm.gstore()
    vm.gc()
