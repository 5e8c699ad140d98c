"""The in-queue's processing: ``bbzvm_process_inmsgs`` (``bbzvm.c``) and
``bbzmsg_process_broadcast`` (``bbzmsg.c``; spec §F.4, §F.5).

Once per control step the firmware takes at most ``msg_in_proc_max`` messages from the head
of the in-queue (sorted by type: broadcasts, then swarm, then stigmergy), collecting the heap
before each one. A broadcast calls the listener of its topic as ``f(topic, value, sender id)``
with self nil; a stigmergy message goes to :mod:`bbzide.vm.vstig`. The queues and the wire
format are :mod:`bbzide.vm.messages`; this module is the loop over them, above both.

In the fast mode the loop hands its broadcasts to the compiled in-queue kernel and its
stigmergy messages to the compiled stigmergy loop (both through the seam,
:mod:`bbzide.vm.kernels`); each stops at the first message or listener step it does not
cover, and this loop then goes on with the reference routines from exactly there.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from bbzide.vm import vstig
from bbzide.vm.heap import PERMANENT, TYPE_MASK, USERDATA, HeapFull
from bbzide.vm.kernels import fastinbox, fastloop, fastvstig
from bbzide.vm.message_layout import (
    BC_TOPIC,
    BC_VALUE,
    BROADCAST,
    RID,
    TYPE,
    VSTIG_PUT,
    VSTIG_QUERY,
)
from bbzide.vm.messages import RingBuffer, inmsg_extract, rec_rid, rec_topic, rec_value
from bbzide.vm.states import Error, State
from bbzide.vm.tables import table_get

if TYPE_CHECKING:
    from bbzide.vm.vm import VM

#: the compiled in-queue loop is used when numba compiles it (else Python alone)
_INBOX_KERNEL = fastloop.COMPILED
#: the record types of virtual-stigmergy messages
_STIGMERGY = (VSTIG_PUT, VSTIG_QUERY)


def process_broadcast(vm: VM, rec: bytearray) -> bool:
    """Call the listener of the topic as ``f(topic, value, sender id)`` (self nil).

    True when the last thing done was a collection (the caller may then count, not run,
    an immediately following one: see :func:`process_inmsgs`). With room for the five
    pushes (always, but for a nearly full stack) they are written straight into the
    stack: the same slots and stack pointer as ``push``, minus the five checks.
    """
    h = vm.heap
    s = h.obj_size
    sp = vm.stackptr
    if sp + 5 >= vm.stack_size:
        return _process_broadcast_checked(vm, rec)
    stack = vm.stack
    topic = vm.new_string_obj(rec[BC_TOPIC] | (rec[BC_TOPIC + 1] << 8))
    stack[sp + 1] = topic  # push_string + pop: the slot above the top keeps it
    listener = table_get(h, vm.neighbors.listeners, topic)
    if listener is None:
        return False
    stack[sp + 1] = vm.nil
    stack[sp + 2] = listener
    stack[sp + 3] = topic
    try:  # bbzvm_pushu(0): a userdata object whose pointer-sized payload is 0
        x = h.obj_alloc(USERDATA)
        h.set_ptr(x, 0)
    except HeapFull:
        vm.stackptr = sp + 3
        vm.seterror(Error.MEM)
        x = vm.nil
    stack[sp + 4] = x
    o = x * s
    d = h.data
    d[o] = (d[o] & ~TYPE_MASK & ~PERMANENT & 0xFF) | (rec[BC_VALUE] & TYPE_MASK)
    d[o + 1:o + s] = rec[BC_VALUE + 1:BC_VALUE + s]
    stack[sp + 5] = vm.new_int(rec[RID] | (rec[RID + 1] << 8))
    vm.stackptr = sp + 5
    vm.closure_call(3)
    vm.pop()
    vm.gc()
    return True


def _process_broadcast_checked(vm: VM, rec: bytearray) -> bool:
    """:func:`process_broadcast` with every push checked (a stack with no room left)."""
    h = vm.heap
    s = h.obj_size
    topic = vm.push_string(rec_topic(rec))
    vm.pop()
    listener = table_get(h, vm.neighbors.listeners, topic)
    if listener is None:
        return False
    vm.push_nil()
    vm.push(listener)
    vm.push(topic)
    try:  # bbzvm_pushu(0): a userdata object whose pointer-sized payload is 0
        x = h.obj_alloc(USERDATA)
        h.set_ptr(x, 0)
    except HeapFull:
        vm.seterror(Error.MEM)
        x = vm.nil
    vm.push(x)
    value = rec_value(rec, s)
    o = x * s
    h.data[o] = (h.data[o] & ~TYPE_MASK & 0xFF) | (value[0] & TYPE_MASK)
    h.data[o] &= ~PERMANENT & 0xFF
    h.data[o + 1:o + s] = value[1:]
    vm.push_int(rec_rid(rec))
    vm.closure_call(3)
    vm.pop()
    vm.gc()
    return True


def process_inmsgs(vm: VM) -> None:
    """``bbzvm_process_inmsgs``: at most ``msg_in_proc_max`` messages, each after a GC.

    The fast mode hands the loop to the compiled :func:`fastinbox.process_broadcasts`,
    which stops at the first message (or listener step) it does not cover; from there
    this loop goes on with the reference routines, then calls the kernel again when the
    head is a broadcast. Stigmergy messages at the head go to the compiled
    :func:`fastvstig.process_vstigs` the same way (a search-and-rescue drone gets some
    sixteen of them a step).
    """
    if vm.state == State.ERROR:
        return
    go_on_inmsgs(vm, 0, False)


def go_on_inmsgs(vm: VM, count: int, collected: bool, taken: bool = False) -> None:
    """The loop of :func:`process_inmsgs` from where a compiled step stopped
    (``fastbatch``): ``count`` messages taken, the heap just ``collected``; ``taken``:
    message ``count``'s collection is done, its extraction is next."""
    q = vm.queues
    # collected: the heap is what a collection just left, so the next one would change
    # nothing (the fast mode's PC_ONLY rule, vm._SKIP_RULES): fast mode counts it only
    compiled = _INBOX_KERNEL and not vm.stress_gc
    while taken or (not q.inbox.empty() and count < vm.profile.msg_in_proc_max):
        collected = collected and not vm.heap.unsettled  # (not a fixed point: collect)
        # the head's type, for a kernel to take it (None: the reference routines only)
        head = q.inbox.at(0)[TYPE] if compiled and vm.state == State.READY else None
        if head in _STIGMERGY:
            status, count, collected = _process_vstig_compiled(vm, count, collected, taken)
            taken = False
            if status != fastvstig.PYTHON_MESSAGE:
                continue
            # message `count` is collected for; the kernel left the whole of it to us
        elif taken:
            taken = False
        elif head == BROADCAST:
            status, count, collected = _process_compiled(vm, count, collected)
            if status != fastinbox.PYTHON_MESSAGE:
                continue
            # the kernel took message `count` and collected for it: a stigmergy message
            # goes on in the stigmergy kernel from its extraction, the rest is ours
            taken = q.inbox.at(0)[TYPE] in _STIGMERGY
            if taken:
                continue
        else:
            count += 1
            if collected and not vm.stress_gc:
                vm.heap.gc_runs += 1
            else:
                vm.gc()
        collected = False
        if vm.state == State.ERROR:
            return
        rec = inmsg_extract(q)
        t = rec[TYPE]
        if t == BROADCAST:
            collected = process_broadcast(vm, rec)
        elif t in (VSTIG_PUT, VSTIG_QUERY):
            collected = vstig.process_vstig(vm, rec)


def _take_scratch(q: RingBuffer[bytearray], packed: bytearray, size: int) -> None:
    """The scratch record back from a kernel's packed in-queue (``packed``: the records
    concatenated, the scratch one last): it holds the last message the kernel took."""
    scratch = q.capacity * size
    q.records[q.capacity][:] = packed[scratch:scratch + size]


def _process_compiled(vm: VM, count: int, collected: bool) -> tuple[int, int, bool]:
    """Run :func:`fastinbox.process_broadcasts` from message ``count + 1``; a listener
    call it leaves under way is finished here (``VM._loop`` resumed, then the end of
    :func:`process_broadcast`). Returns (kernel status, messages taken, collected)."""
    q = vm.queues.inbox
    records = q.records
    size = len(records[0])
    packed = bytearray().join(records)
    inq = np.array((q.start, q.end, q.capacity, size, count, vm.profile.msg_in_proc_max,
                    collected, vm.neighbors.listeners, 0, 0), np.int64)
    saved, budget = vm.blockptr, vm.instruction_budget
    regs = vm.kernel_registers(saved, budget)
    h = vm.heap
    status = fastinbox.process_broadcasts(
        h.view, vm._stack_view, vm._bcode_view, regs, h.gc_info, h.gc_traversed,
        fastloop.RULES, h.obj_size, h.elems, h.reserved, np.frombuffer(packed, np.uint8),
        inq, *vm.kernel_hosts())
    vm.take_kernel_registers(regs)
    start, _end, _slots, _size, count, _max, collected, _lst, extracted, inner = \
        inq.tolist()
    q.start = start
    if extracted:
        _take_scratch(q, packed, size)
    if status == fastinbox.IN_CALL:
        vm._loop(saved, budget, resume=(inner, regs))
        vm.pop()
        vm.gc()
        collected = True
    return status, count, bool(collected)


def _process_vstig_compiled(vm: VM, count: int, collected: bool,
                            taken: bool) -> tuple[int, int, bool]:
    """Run :func:`fastvstig.process_vstigs` from message ``count + 1`` (``taken``: from
    message ``count``, its collection done) on the queues and the stigmergy entries packed
    for the call, and write back what it changed. Returns (kernel status, messages taken,
    collected)."""
    queues = vm.queues
    q, out = queues.inbox, queues.outbox
    records, outs = q.records, out.records
    size = len(records[0])
    packed = bytearray().join(records)
    before_out = bytearray().join(outs)
    packed_out = bytearray(before_out)
    entries = vm.vstig.entries
    known = len(entries)
    # a row for every entry, and one for each message the call may append
    table = np.zeros((known + q.size(), fastvstig.ENTRY_COLUMNS), np.int64)
    if known:
        table[:known] = [(e.key, e.value, e.timestamp, e.robot) for e in entries]
    before = table[:known].copy()
    state = np.array((q.start, q.end, q.capacity, size, count, vm.profile.msg_in_proc_max,
                      collected, taken, vm.robot, vm.profile.lamport_threshold,
                      vm.vstig.hpos, 0, known, out.start, out.end, out.capacity), np.int64)
    regs = vm.kernel_registers(None, None)
    h = vm.heap
    status = fastvstig.process_vstigs(
        h.view, vm._stack_view, regs, h.gc_info, h.gc_traversed, h.obj_size, h.elems,
        h.reserved, np.frombuffer(packed, np.uint8), state, table,
        np.frombuffer(packed_out, np.uint8))
    vm.take_kernel_registers(regs)
    (q.start, _end, _slots, _size, count, _max, collected, _taken, _robot, _threshold,
     _hpos, extracted, rows, out.start, out.end, _out_slots) = state.tolist()
    if extracted:
        _take_scratch(q, packed, size)
        now = memoryview(packed_out)
        changed = np.frombuffer(packed_out, np.uint8) != np.frombuffer(before_out, np.uint8)
        for k in np.flatnonzero(changed.reshape(-1, size).any(axis=1)).tolist():
            outs[k][:] = now[k * size:(k + 1) * size]
        for k in np.flatnonzero((table[:known] != before).any(axis=1)).tolist():
            e = entries[k]
            e.value, e.timestamp, e.robot = table[k, 1:].tolist()
        entries.extend(vstig.VstigEntry(*row) for row in table[known:rows].tolist())
    return status, count, bool(collected)
