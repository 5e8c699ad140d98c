"""Compiled host functions of the fast VM mode: a C closure's call without leaving machine code.

When the instruction kernel (:func:`fastloop.run`) meets a ``callc`` of a C closure it sets
the call up and returns ``HOST_CALL``; ``VM._loop`` then looks the host function up, runs
it in Python, and re-enters the kernel. For a Kilobot's ``step`` of the gradient example
(``neighbors.broadcast``, ``led``) those two round trips were a third of the VM's time.
:func:`run_hosted` is ``run`` plus the host functions whose whole effect the kernel can
do itself, on their happy path, under the kernel's rule (check everything first, hand the
call back to Python with nothing done otherwise):

* ``neighbors.broadcast(topic, value)`` — ``bbzneighbors_broadcast``: the out-queue append
  (``messages.outmsg_append_broadcast``, the full-queue overwrite and the sort by type
  included) on the packed out-queue (:mod:`packed_queues`), then ``ret0``;
* a **latched** host function (``host.LatchedHostFunction``: a world function whose only
  effect is to store its int arguments as the robot's state, e.g. a Kilobot's ``led``):
  its arguments are type-checked (ints only, below the row's bound if it has one) and
  stored in the robot's latch slot, ``ret0``; the world gets them after the swarm step
  (``swarm_batch``); a function latched once a step (every call of it counts: an M300's
  ``set_role``) hands its second call of a step to Python;
* a **rounded distance** (``host.RoundedDistanceHostFunction``: an M300's
  ``distance(x1, y1, x2, y2)``, ``round(hypot(x1 - x2, y1 - y2))``): four int arguments,
  the int result pushed and ``ret1``; it touches no queue, so a walk begun from Python
  (:func:`table_walk`, :func:`xtreme_walk`) runs it in place too (``HostRegistry.computed_rows``);
* a **reading** (``host.ReadingHostFunction``: an M300's ``clock()``, ``position()``,
  ``camera()``): no argument; the value the compiled swarm step wrote in the robot's reading
  row before the kernel (``packed_queues.READ_*``) pushed as ``HostCall.ret`` pushes it —
  an int, nil, or a record of ints (:func:`push_int_record`, field names from the row's
  ``H_KEYS``) — and ``ret1``; a row with no reading (``READ_NONE``), or one a latched call
  of this step made stale (``H_STALE_AFTER``: an M300's ``arrived()`` after ``goto``), goes
  to Python;
* a **drawn** record (``host.DrawnHostFunction``: an M300's ``random_goal()``): no
  argument; the first row of the robot's drawn rows that no call of this step has taken
  (the swarm step wrote the results of the next ``DRAWN_ROWS`` calls there, the random
  stream left as it was) pushed as a record and marked taken; the swarm step then moves
  the stream on by the rows taken; once every row is taken the call goes to Python;
* a **lookup** (``host.LookupHostFunction``: an M300's ``prior(cell)``, ``missed(flown)``):
  one int argument, clamped into its table (``HostRegistry.computed_rows``: the table's
  address and length in the row), the int pushed and ``ret1``; like the distance it touches
  no queue;
* a stigmergy ``v.get(key)`` and ``v.put(key, value)`` (``vstig.vstig_get``/``vstig_put``)
  on the packed entries (``ctl``'s ``VSTIG_*``: the compiled swarm step's robots only):
  their collections, the entry read, updated or added, the QUERY or PUT queued, the value
  (or nil) pushed and ``ret1``, or ``ret0``; a table value (TYPE), a full stigmergy (VSTIG)
  or a packed table without a free row goes to Python.
  Anything else — another
  argument count (LNUM), a non-int (TYPE), a result outside an int16, a return the
  kernel's ``_ret`` refuses, no room for the result, the budget about to run out, a
  ``run`` without a saved block pointer — goes to Python.

After a host function ``VM._loop`` counts a step (``n``), applies no skip rule (``callc``
has none: the next step collects) and checks the budget; :func:`run_hosted` does the same
(it refuses a call after which the budget would be exceeded, so the error stays Python's),
but for a call whose dropped frame holds only kept roots and fresh temporaries
(``fastloop.host_frame_droppable``) and whose result, if any, is one new int (or nil): the
next step's collection is then its effect — the frame's temporaries freed, that int marked
and fresh (:func:`_host_compiled`).

The table of compiled host functions (``hosts``, one row per closure address: see the
``H_*`` columns) is built by ``Robot.compiled_hosts`` from the VM's host registry; it is
empty for a VM whose queues are not packed, so :func:`run_hosted` is then exactly ``run``.
:func:`call_pushed` is the set-up shared by every compiled entry into a closure call
(``fastinbox``): the argument count is on the stack, ``closure_call``'s registers, run.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from bbzide.vm.compiled.fastgc import COMPILED, _compile, _compile_owning, _i, collect_with
from bbzide.vm.compiled.fastloop import (
    CALL,
    CALL_IN_WALK,
    CALL_ON_FIXED_HEAP,
    EXIT,
    FRESH,
    HOST_CALL,
    NEW,
    NONE,
    R_BP,
    R_BUDGET,
    R_CALL_FIRST,
    R_FIXED,
    R_GC_RUNS,
    R_HOST,
    R_HOST_COUNT,
    R_LEFT_FRAME,
    R_LSYMS,
    R_LTSEG,
    R_MARK_DEPTH,
    R_N,
    R_NIL,
    R_OLD_CHANGED,
    R_PENDING,
    R_PRIOR,
    R_REACHED,
    R_RTOBJ,
    R_SAVED,
    R_SP,
    R_STACK_SIZE,
    R_UNSETTLED,
    _obj_alloc,
    _ret,
    _ret_ok,
    _room,
    _s16,
    _seg_alloc,
    _table_set,
    _true,
    _u16,
    end_host_frame,
    forget_left_frame,
    host_frame_droppable,
    run,
    take_collection,
    undo_to_fixed_point,
)
from bbzide.vm.compiled.fastring import out_template, sort_ring_by_type
from bbzide.vm.compiled.fasttables import darray_get, darray_size
from bbzide.vm.compiled.fastviews import view_i64, view_i64_rows
from bbzide.vm.compiled.packed_queues import (
    CTL_SLOTS,
    DRAWN_ROWS,
    LATCH_ARGS,
    LATCH_SLOTS,
    OUT_END,
    OUT_SLOTS,
    OUT_START,
    READ_NIL,
    READ_NONE,
    READ_TAKEN,
    ROBOT,
    VSTIG_ADDRESS,
    VSTIG_CAP,
    VSTIG_CAPACITY,
    VSTIG_COLUMNS,
    VSTIG_ROWS,
)
from bbzide.vm.heap_layout import (
    CLOSURE,
    FLAG2,
    FLOAT,
    GC_MARK,
    INT,
    NO_ACTREC,
    PERMANENT,
    STRING,
    TABLE,
)
from bbzide.vm.message_layout import (
    BC_TOPIC,
    BC_VALUE,
    BROADCAST,
    RID,
    TYPE,
    VS_DATA,
    VS_KEY,
    VS_LAMPORT,
    VSTIG_PUT,
    VSTIG_QUERY,
)

__all__ = ["COMPILED", "run_hosted", "call_pushed", "no_hosts", "HOST_BROADCAST",
           "HOST_LATCH", "HOST_DISTANCE", "HOST_READ_INT", "HOST_READ_RECORD",
           "H_LATCH_BELOW", "H_LATCH_ONCE", "H_STALE_AFTER", "clear_stale_readings",
           "HOST_VSTIG_GET", "HOST_LOOKUP", "HOST_VSTIG_PUT", "HOST_DRAWN", "HOST_TABLE_FOREACH",
           "H_KEYS", "run_walking", "enter_call",
           "HOST_COLUMNS",
           "NO_HOST_ARGS", "xtreme_walk",
           "WALK_FOREACH", "WALK_REDUCE", "WALK_MAP", "WALK_FILTER", "WALK_TABLE_FOREACH",
           "WALK_TABLE_MAP", "WALK_TABLE_FILTER", "WALK_TABLE_REDUCE", "W_ACCUM",
           "WALK_DONE", "WALK_PYTHON", "WALK_IN_CALL", "WALK_AFTER_CALL", "table_walk",
           "WALK_SLOTS", "rounded_distance", "collect_on_registers", "push_int_record"]

# Columns of a ``hosts`` row (a reading's record: its field names' string ids from
# ``H_KEYS`` on, LATCH_ARGS of them), and its kinds.
H_ADDRESS, H_PTR_SIZE, H_KIND, H_SLOT, H_ARGC, H_KEYS = range(6)
#: a latch's columns: every argument's exclusive upper bound (-1: none; the lower one is
#: 0), and 1 when only one call a step is latched (a second one goes to Python); a
#: reading's column: the latch slots (bit k: slot k) whose call this step makes its row
#: stale (the world state it reads is one that latched function stores)
H_LATCH_BELOW = H_KEYS + LATCH_ARGS
H_LATCH_ONCE = H_LATCH_BELOW + 1
H_STALE_AFTER = H_LATCH_ONCE + 1
HOST_COLUMNS = H_STALE_AFTER + 1
HOST_BROADCAST, HOST_LATCH, HOST_DISTANCE, HOST_READ_INT, HOST_READ_RECORD = 1, 2, 3, 4, 5
HOST_VSTIG_GET, HOST_LOOKUP, HOST_VSTIG_PUT, HOST_DRAWN = 6, 7, 8, 9
#: the table library's ``foreach`` (``table_library.table_foreach``): not a host function
#: :func:`_host_compiled` does, but a walk :func:`run_walking` makes in place
HOST_TABLE_FOREACH = 10



def no_hosts() -> np.ndarray:
    """An empty ``hosts`` table (the Python entries: their queues are not packed)."""
    return np.zeros((0, HOST_COLUMNS), np.int64)


#: (hosts, outq, ctl, latch) for an entry with no compiled host function (never written)
NO_HOST_ARGS = (no_hosts(), np.zeros(1, np.uint8), np.zeros(CTL_SLOTS, np.int64),
                np.zeros((1, 1 + LATCH_ARGS), np.int64))


@_compile
def out_append_broadcast(d: Any, outq: Any, ctl: Any, size: int, topic: int, value: int,
                         s: int) -> None:
    """``messages.outmsg_append_broadcast`` of heap objects ``topic`` (its u16) and
    ``value`` (its ``s`` bytes) on the packed out-queue (``_out_template``'s overflow bug
    included: a full queue gets the unused record copied over its last one)."""
    slots = ctl[OUT_SLOTS]
    m, end = out_template(outq, ctl[OUT_START], ctl[OUT_END], slots, size)
    ctl[OUT_END] = end
    o = m * size
    rid = ctl[ROBOT] & 0xFFFF
    outq[o + TYPE] = BROADCAST
    outq[o + RID] = rid & 0xFF
    outq[o + RID + 1] = rid >> 8
    outq[o + BC_TOPIC] = d[topic * s + 1]
    outq[o + BC_TOPIC + 1] = d[topic * s + 2]
    for j in range(s):
        outq[o + BC_VALUE + j] = d[value * s + j]
    sort_ring_by_type(outq, ctl[OUT_START], ctl[OUT_END], slots, size, outq[:0])


@_compile
def out_append_vstig(d: Any, outq: Any, rings: Any, base: int, size: int, s: int, typ: int,
                     rid: int, key: int, value: int, lamport: int) -> None:
    """``messages.outmsg_append_vstig`` of heap object ``value`` (its ``s`` bytes) on the
    packed out-queue whose start, end and slots are ``rings[base:base + 3]``: a full queue
    gets its unused record copied over its last one and the message written into the unused
    record (``out_template``), then the sort by type."""
    slots = rings[base + 2]
    m, end = out_template(outq, rings[base], rings[base + 1], slots, size)
    rings[base + 1] = end
    o = m * size
    outq[o + TYPE] = typ
    outq[o + RID] = rid & 0xFF
    outq[o + RID + 1] = (rid >> 8) & 0xFF
    outq[o + VS_LAMPORT] = lamport & 0xFF
    outq[o + VS_KEY] = key & 0xFF
    outq[o + VS_KEY + 1] = (key >> 8) & 0xFF
    for j in range(s):
        outq[o + VS_DATA + j] = d[value * s + j]
    sort_ring_by_type(outq, rings[base], rings[base + 1], slots, size, outq[:0])


@_compile
def _address_matches(d: Any, c: int, s: int, address: int, ptr_size: int) -> bool:
    """Does C closure ``c`` hold ``address`` (``Heap.ptr_value`` masked to the pointer)?"""
    for j in range(min(ptr_size, s - 1)):
        if _i(d[c * s + 1 + j]) != (address >> (8 * j)) & 0xFF:
            return False
    return True


@_compile
def _host_row(d: Any, c: int, s: int, hosts: Any) -> int:
    """The row of ``hosts`` whose address C closure ``c`` holds, or -1."""
    for r in range(len(hosts)):
        if _address_matches(d, c, s, hosts[r, H_ADDRESS], hosts[r, H_PTR_SIZE]):
            return r
    return -1


@_compile
def rounded_distance(dx: int, dy: int) -> int:
    """``round(math.hypot(dx, dy))`` of ints, in ints: the integer square root ``r`` of
    ``n = dx² + dy²``, plus one when ``n > r² + r`` (then √n > r + ½; it is never exactly
    r + ½, since (r + ½)² is not an integer, so Python's rounding of ties never arises)."""
    n = dx * dx + dy * dy
    r = int(np.sqrt(n))
    while r * r > n:
        r -= 1
    while (r + 1) * (r + 1) <= n:
        r += 1
    return r + 1 if n > r * r + r else r


@_compile_owning
def _host_compiled(d: Any, stack: Any, bsize: int, regs: Any, info: Any, traversed: Any,
                   s: int, elems: int, reserved: int, hosts: Any, outq: Any, ctl: Any,
                   latch: Any) -> bool:
    """The host function of the C closure ``regs[R_HOST]`` whose call ``run`` set up, and
    ``VM._loop``'s end of that step — with the next step's collection replaced by its
    effect when the call's frame is droppable (``R_HOST_COUNT``,
    ``fastloop.host_frame_droppable``); False with nothing done when Python must do it."""
    saved = regs[R_SAVED]
    budget = regs[R_BUDGET]
    n = regs[R_N]
    if saved == NONE or (budget != NONE and n + 1 > budget):
        return False
    nobj = len(d) // s
    c = regs[R_HOST]
    row = _host_row(d, c, s, hosts)
    if row < 0:
        return False
    kind = hosts[row, H_KIND]
    if kind == HOST_TABLE_FOREACH:
        return False  # a walk: run_walking's, or Python's
    argc = hosts[row, H_ARGC]
    lsyms = regs[R_LSYMS]
    if darray_size(d, lsyms, s, elems) != argc + 1:
        return False  # LNUM: Python reports it
    for i in range(1, argc + 1):
        o = darray_get(d, lsyms, i, s, elems)
        if o < 0 or o >= nobj:
            return False
        if kind != HOST_BROADCAST and kind != HOST_VSTIG_GET and kind != HOST_VSTIG_PUT \
                and _i(d[o * s]) & 7 != INT:
            return False  # TYPE (or a string id the world would read as an int): Python
    if kind == HOST_LATCH:
        if hosts[row, H_LATCH_ONCE] == 1 and latch[hosts[row, H_SLOT], 0]:
            return False  # its second call this step: the first is applied, then Python's
        below = hosts[row, H_LATCH_BELOW]
        for i in range(1, argc + 1):
            if below >= 0 and not 0 <= _int_arg(d, lsyms, i, s, elems) < below:
                return False  # outside its range: Python reports it
    sp = regs[R_SP]
    bp = regs[R_BP]
    result = 0
    reading = kind == HOST_READ_INT or kind == HOST_READ_RECORD or kind == HOST_DRAWN
    record = kind == HOST_READ_RECORD or kind == HOST_DRAWN
    read = READ_NONE
    read_row = hosts[row, H_SLOT]
    if kind == HOST_DRAWN:  # the first row no call of this step has taken
        first_row = read_row
        while read_row < first_row + DRAWN_ROWS and latch[read_row, 0] == READ_TAKEN:
            read_row += 1
        if read_row == first_row + DRAWN_ROWS:
            return False  # every row drawn ahead is taken: Python draws the next
    if reading:
        read = latch[read_row, 0]
        if read == READ_NONE:
            return False  # no reading this step: Python asks the world
        stale_after = hosts[row, H_STALE_AFTER]
        for slot in range(LATCH_SLOTS):
            if stale_after >> slot & 1 and latch[slot, 0]:
                return False  # a latched call changed what it reads: applied, then Python
        result = latch[read_row, 1] & 0xFFFF
    if kind == HOST_DISTANCE:
        result = rounded_distance(
            _int_arg(d, lsyms, 1, s, elems) - _int_arg(d, lsyms, 3, s, elems),
            _int_arg(d, lsyms, 2, s, elems) - _int_arg(d, lsyms, 4, s, elems))
        if result > 0x7FFF:
            return False
    elif kind == HOST_LOOKUP:  # the table: address in H_SLOT, length in H_KEYS
        length = hosts[row, H_KEYS]
        values = view_i64(hosts[row, H_SLOT], length)
        result = values[min(max(_int_arg(d, lsyms, 1, s, elems), 0), length - 1)] & 0xFFFF
    stigmergy = kind == HOST_VSTIG_GET or kind == HOST_VSTIG_PUT
    if kind == HOST_DISTANCE or kind == HOST_LOOKUP or reading or kind == HOST_VSTIG_GET:
        # ret1 of a pushed value: an int (one object), nil or an existing object (none), a
        # record (push_int_record checks its own room, and is the last check: it writes only
        # when it succeeds)
        objects = 1 if kind == HOST_DISTANCE or kind == HOST_LOOKUP \
            or (read != READ_NIL and kind == HOST_READ_INT) else 0
        if (sp + 1 >= regs[R_STACK_SIZE]
                or not _ret_ok(d, stack, True, sp + 1, bp, lsyms, bsize, s, elems)
                or not _room(d, regs, s, reserved, elems, objects, 0)):
            return False
        if record and read != READ_NIL and not push_int_record(
                d, stack, regs, hosts[row, H_KEYS:H_KEYS + _record_fields(hosts, row)],
                latch[read_row, 1:], s, elems, reserved):
            return False
    elif not _ret_ok(d, stack, False, sp, bp, lsyms, bsize, s, elems):
        return False
    # v.get(key), v.put(key, value): vstig._entry_of, before anything is written
    entries = latch  # (an int64 matrix of the right type when there is no stigmergy call)
    entry = -1
    key = -1
    if stigmergy:
        entries = view_i64_rows(ctl[VSTIG_ADDRESS], ctl[VSTIG_CAPACITY], VSTIG_COLUMNS)
        key = darray_get(d, lsyms, 1, s, elems)
        if _i(d[key * s]) & 7 == STRING:
            entry = find_entry(entries, ctl[VSTIG_ROWS], _u16(d, key, s))
        if entry >= 0 and not 0 <= entries[entry, 1] < nobj:
            return False
    if kind == HOST_VSTIG_PUT:
        put = darray_get(d, lsyms, 2, s, elems)
        if _i(d[put * s]) & 7 == TABLE:
            return False  # TYPE: Python reports it
        rows = ctl[VSTIG_ROWS]
        if entry < 0 and (rows >= ctl[VSTIG_CAP] or rows >= ctl[VSTIG_CAPACITY]):
            return False  # VSTIG (the stigmergy is full), or no packed row left: Python
    count = regs[R_HOST_COUNT]
    # a frame is dropped when the call made nothing, or one int (or pushed nil): that int
    # is then a fresh leaf, referenced by its stack slot alone
    int_result = kind == HOST_DISTANCE or kind == HOST_LOOKUP or kind == HOST_READ_INT
    droppable = ((int_result or not (reading or stigmergy)) and count >= 0
                 and not regs[R_UNSETTLED]
                 and host_frame_droppable(d, info, count, c, lsyms, s, elems))
    fresh_result = -1
    # ---- commit: the host function's effect, then ret0 (ret1) and the end of the step
    with_value = False
    out_record = len(outq) // (ctl[OUT_SLOTS] + 1)  # (for the kinds that queue a message)
    if stigmergy:  # its first gc (the collector's mark stack kept for the last one)
        frames = np.empty((4, regs[R_MARK_DEPTH] + 2), np.int64)
        _collect(d, stack, regs, info, traversed, frames, s, elems, reserved)
    if kind == HOST_DISTANCE or kind == HOST_LOOKUP or (kind == HOST_READ_INT
                                                        and read != READ_NIL):
        o = _obj_alloc(d, regs, s, reserved, INT, 0)  # push_int(result)
        d[o * s + 1] = result & 0xFF
        d[o * s + 2] = result >> 8
        if regs[R_PRIOR] & GC_MARK:
            droppable = False  # a free slot the last collection reached: not fresh
        fresh_result = o
        sp += 1
        stack[sp] = o
        with_value = True
    elif reading and read == READ_NIL:
        sp += 1
        stack[sp] = regs[R_NIL]  # push_nil
        with_value = True
    elif record:
        sp += 1  # push_int_record pushed the table
        with_value = True
        if kind == HOST_DRAWN:
            latch[read_row, 0] = READ_TAKEN  # the swarm step moves the stream on for it
    elif kind == HOST_VSTIG_GET:
        # vstig_get (after its gc): the QUERY queued (the entry's, or nil at timestamp 0
        # under this robot), its value (or nil) pushed; after the ret1 below, gc again
        if entry >= 0:
            value = entries[entry, 1]
            out_append_vstig(d, outq, ctl, OUT_START, out_record, s, VSTIG_QUERY,
                             entries[entry, 3], entries[entry, 0], value, entries[entry, 2])
        else:
            value = regs[R_NIL]
            out_append_vstig(d, outq, ctl, OUT_START, out_record, s, VSTIG_QUERY, ctl[ROBOT],
                             _u16(d, key, s), value, 0)
        sp += 1
        stack[sp] = value
        with_value = True
    elif kind == HOST_VSTIG_PUT:
        # vstig_put (after its gc): a held key's entry takes the value (robot, PERMANENT
        # bits moved, gc, timestamp + 1) or a new entry is made (key and value made
        # PERMANENT); the PUT queued; after the ret0 below, gc again
        if entry >= 0:
            entries[entry, 3] = ctl[ROBOT]
            old = entries[entry, 1]
            d[old * s] = _i(d[old * s]) & (0xFF ^ PERMANENT)
            entries[entry, 1] = put
            d[put * s] = _i(d[put * s]) | PERMANENT
            _collect(d, stack, regs, info, traversed, frames, s, elems, reserved)
            entries[entry, 2] = (entries[entry, 2] + 1) & 0xFF
        else:
            entry = ctl[VSTIG_ROWS]
            entries[entry, 0] = _u16(d, key, s)
            entries[entry, 1] = put
            entries[entry, 2] = 1
            entries[entry, 3] = ctl[ROBOT]
            d[key * s] = _i(d[key * s]) | PERMANENT
            d[put * s] = _i(d[put * s]) | PERMANENT
            ctl[VSTIG_ROWS] = entry + 1
        out_append_vstig(d, outq, ctl, OUT_START, out_record, s, VSTIG_PUT,
                         entries[entry, 3], entries[entry, 0], entries[entry, 1],
                         entries[entry, 2])
    elif kind == HOST_BROADCAST:
        out_append_broadcast(d, outq, ctl, out_record, darray_get(d, lsyms, 1, s, elems),
                             darray_get(d, lsyms, 2, s, elems), s)
    else:
        slot = hosts[row, H_SLOT]
        latch[slot, 0] = 1
        for i in range(1, argc + 1):
            latch[slot, i] = _int_arg(d, lsyms, i, s, elems)
    return_pc = _i(stack[bp - 2])
    block = _i(stack[bp])
    _ret(d, stack, regs, with_value, sp, bp, lsyms, bsize, s, elems)
    if stigmergy:
        _collect(d, stack, regs, info, traversed, frames, s, elems, reserved)
    regs[R_N] = n + 1
    regs[R_FIXED] = 0
    regs[R_PENDING] = -1
    if droppable:
        end_host_frame(d, regs, info, count, c, lsyms, return_pc, block, s, elems,
                       reserved)
        if fresh_result >= 0:  # the collection marks the result, a fresh leaf
            d[fresh_result * s] = _i(d[fresh_result * s]) | GC_MARK
            info[fresh_result] = FRESH
        regs[R_FIXED] = 1
    return True


@_compile
def clear_stale_readings(hosts: Any, latch: Any, slot: int) -> None:
    """Once the call latched in ``slot`` is taken for the world (the swarm step's end of a
    robot's kernel part), the reading rows it made stale (``H_STALE_AFTER``) are emptied
    (``READ_NONE``): a kernel entered from Python for the rest of that step hands those
    readings to Python, which reads the state the applied latch left."""
    for r in range(len(hosts)):
        kind = hosts[r, H_KIND]
        if (kind == HOST_READ_INT or kind == HOST_READ_RECORD) \
                and hosts[r, H_STALE_AFTER] >> slot & 1:
            latch[hosts[r, H_SLOT], 0] = READ_NONE


@_compile
def find_entry(entries: Any, count: int, key: int) -> int:
    """The first of ``count`` stigmergy entry rows (``packed_queues.VSTIG_COLUMNS``: the
    key first) with ``key``, or -1."""
    for i in range(count):
        if entries[i, 0] == key:
            return i
    return -1


@_compile
def _record_fields(hosts: Any, row: int) -> int:
    """The fields of a reading's record: its row's string ids before the first -1."""
    n = 0
    while n < LATCH_ARGS and hosts[row, H_KEYS + n] >= 0:
        n += 1
    return n


@_compile
def _int_arg(d: Any, lsyms: int, i: int, s: int, elems: int) -> int:
    """Argument ``i`` of the activation record, an int object: its signed value."""
    return _s16(_u16(d, darray_get(d, lsyms, i, s, elems), s))


@_compile
def run_hosted(d: Any, stack: Any, bcode: Any, regs: Any, info: Any, traversed: Any,
               rules: Any, s: int, elems: int, reserved: int, hosts: Any, outq: Any,
               ctl: Any, latch: Any) -> int:
    """:func:`fastloop.run`, with the host functions of ``hosts`` done in place (see the
    module comment); returns what ``run`` last returned."""
    while True:
        status = run(d, stack, bcode, regs, info, traversed, rules, s, elems, reserved)
        if status != HOST_CALL or len(hosts) == 0 or not _host_compiled(
                d, stack, len(bcode), regs, info, traversed, s, elems, reserved, hosts, outq,
                ctl, latch):
            return status


@_compile
def call_pushed(d: Any, stack: Any, bcode: Any, regs: Any, info: Any, traversed: Any,
                rules: Any, s: int, elems: int, reserved: int, sp: int, hosts: Any,
                outq: Any, ctl: Any, latch: Any, entry: int) -> int:
    """``closure_call``'s loop once its arguments and count are pushed (``sp``: the new
    stack top): the registers of a fresh ``_loop`` with its ``callc`` still to make
    (``entry``: ``fastloop.CALL`` or ``CALL_ON_FIXED_HEAP``), then :func:`run_hosted`."""
    enter_call(regs, sp, entry)
    return run_hosted(d, stack, bcode, regs, info, traversed, rules, s, elems, reserved,
                      hosts, outq, ctl, latch)


@_compile
def enter_call(regs: Any, sp: int, entry: int) -> None:
    """The registers of ``closure_call``'s fresh ``_loop`` (``sp``: the stack top, the
    argument count on it), its ``callc`` still to make (``entry``): :func:`call_pushed`'s,
    and ``fastinbox.call_global``'s before :func:`run_walking` (an element's call, a
    :func:`call_pushed`, walks nothing: no walk nests in another)."""
    regs[R_SP] = sp
    regs[R_SAVED] = regs[R_BP]
    regs[R_N] = 0
    regs[R_FIXED] = 0
    regs[R_PENDING] = -1
    regs[R_CALL_FIRST] = entry


@_compile
def _new_table(d: Any, regs: Any, s: int, reserved: int, elems: int) -> int:
    """``Heap.obj_alloc(TABLE)`` when the caller has checked the room: the table object,
    then its first segment."""
    t = _obj_alloc(d, regs, s, reserved, TABLE, 0)
    seg = _seg_alloc(d, regs, elems)
    d[t * s + 1] = seg & 0xFF
    d[t * s + 2] = seg >> 8
    return t


# ---- a host function's record returned (HostCall.ret of a dict, e.g. position()) --------
@_compile
def push_int_record(d: Any, stack: Any, regs: Any, sids: Any, values: Any, s: int,
                    elems: int, reserved: int) -> bool:
    """``HostCall.ret`` of a dict of ints before its ``ret1``: push a new table, then per
    field the name string (``new_string_obj``: deduplicated), the int (``new_int``,
    ``values`` already masked to 16 bits) and ``table_put_raw``. False, with nothing
    written, unless the stack has room for the push and the heap for every object and
    segment (the fields' names differ, so each put adds an element)."""
    sp = regs[R_SP]
    count = len(sids)
    segments = max(1, (count + elems - 1) // elems)
    if sp + 1 >= regs[R_STACK_SIZE] or not _room(d, regs, s, reserved, elems,
                                                  1 + 2 * count, segments):
        return False
    t = _new_table(d, regs, s, reserved, elems)
    stack[sp + 1] = t
    regs[R_SP] = sp + 1
    for i in range(count):
        key = _obj_alloc(d, regs, s, reserved, STRING, sids[i])
        d[key * s + 1] = sids[i] & 0xFF
        d[key * s + 2] = (sids[i] >> 8) & 0xFF
        v = _obj_alloc(d, regs, s, reserved, INT, 0)
        d[v * s + 1] = values[i] & 0xFF
        d[v * s + 2] = (values[i] >> 8) & 0xFF
        _table_set(d, regs, t, key, v, s, elems)
    return True


# ---- the library's methods added to a table it made (neighbors.map/filter's result) ----
@_compile
def add_functions(d: Any, stack: Any, regs: Any, table: int, sids: Any, addresses: Any,
                  s: int, elems: int, reserved: int) -> bool:
    """``bbztable_add_function`` for each (string id, C closure address) in turn — push the
    table, ``pushs`` the name, push a (non-native) C closure of the address, ``tput`` — on its
    happy path: False, with nothing written, unless the stack has room for the three pushes
    and the heap for every object and segment. ``table`` is one the library made in this call
    (its segments its own, so a ``_table_set`` with room cannot fail). The three stack slots
    above the top keep the last pushes, as the pops leave them."""
    sp = regs[R_SP]
    count = len(sids)
    if sp + 3 >= regs[R_STACK_SIZE] or not _room(d, regs, s, reserved, elems, 2 * count,
                                                  count):
        return False
    for i in range(count):
        stack[sp + 1] = table
        key = _obj_alloc(d, regs, s, reserved, STRING, sids[i])
        d[key * s + 1] = sids[i] & 0xFF
        d[key * s + 2] = (sids[i] >> 8) & 0xFF
        stack[sp + 2] = key
        closure = _obj_alloc(d, regs, s, reserved, CLOSURE, 0)
        for j in range(s - 1):
            d[closure * s + 1 + j] = (addresses[i] >> (8 * j)) & 0xFF
        stack[sp + 3] = closure
        _table_set(d, regs, table, key, closure, s, elems)
    return True


# ---- the neighbors library's walks over an XTREME ring: a closure call per neighbour ----
# ``neighbors.foreach``/``reduce`` on a Kilobot build the neighbour's data table, call the
# Buzz closure and collect, per neighbour, from Python: ~60 µs a neighbour, which made a
# behaviour iterating its neighbours run at a fifth of the C library's speed.
# :func:`xtreme_walk` does those neighbours in machine code under the kernels' rule: before
# a neighbour's first side effect it checks that every push and allocation of it succeeds
# (stack room, a free gap for its objects and segment, ``self`` readable) and otherwise
# hands that neighbour, not started, to Python; a closure call that ``run_hosted`` leaves
# under way is handed back with its status (Python resumes it, ``VM._loop(resume=)``).
#: walk kinds: ``neighbors_foreach`` (f(key, data)), ``neighbors_reduce`` (f(key, data,
#: accumulator), the accumulator kept on the stack), ``neighbors_map`` and
#: ``neighbors_filter`` (f(key, data), its result or the data put in the returned table);
#: the table library's ``foreach``, ``map``, ``filter`` and ``reduce`` (``table_library``:
#: f(key, value), reduce's f(key, value, accumulator) with the accumulator kept in ``w``;
#: the table in self's place, a call leaving nothing is RET, no collection after a call;
#: map and filter put the result or the value under the element's own key)
WALK_FOREACH, WALK_REDUCE, WALK_MAP, WALK_FILTER = 0, 1, 2, 3
WALK_TABLE_FOREACH, WALK_TABLE_MAP, WALK_TABLE_FILTER, WALK_TABLE_REDUCE = 4, 5, 6, 7
#: results: every neighbour done; neighbour ``w[W_INDEX]`` not started (Python does it and
#: the rest); its call under way (status ``w[W_STATUS]``: Python resumes it, then ends the
#: neighbour); its call done but its end (pop or RET check, collections) left to Python
WALK_DONE, WALK_PYTHON, WALK_IN_CALL, WALK_AFTER_CALL = 0, 1, 2, 3
#: slots of the ``w`` array (``xtreme_walk``): the neighbour (row) reached, the run status,
#: the stack depth ``neighbors_reduce`` compares the depth after the call with
W_INDEX, W_STATUS, W_DEPTH = 0, 1, 2
#: slots of ``w``: the key and the data of the element whose call was made, and the table
#: library's reduce accumulator (in and out)
W_KEY, W_DATA, W_ACCUM = 6, 7, 8
#: ring columns: robot, distance, azimuth, elevation (rows newest first, as the walk visits)
NB_ROBOT, NB_DISTANCE = 0, 1
#: objects a neighbour allocates at most: its data table, three values, three field-name
#: strings (deduplicated when alive), the robot id and closure_call's argument count
_WALK_OBJECTS = 9
#: pushes at the deepest point of a neighbour: self, closure, key, data, (accumulator), count
_WALK_PUSHES = 5
#: string id of the data table's first field, ``distance`` (``azimuth``, ``elevation`` follow)
_FIRST_FIELD_SID = 21
#: a segment's next field meaning "none" (``SEG_NEXT``)
_NO_NEXT_SEGMENT = 0x3FFF


@_compile
def collect_on_registers(d: Any, stack: Any, regs: Any, info: Any, traversed: Any,
                         frames: Any, s: int, elems: int, reserved: int) -> None:
    """One collection (``fastgc.collect_with``) of the heap the registers describe, the
    registers updated (``fastloop.take_collection``); the caller counts it."""
    take_collection(regs, collect_with(
        d, stack, regs[R_SP], regs[R_RTOBJ], regs[R_LTSEG], info, traversed, frames, len(d),
        s, 4 * elems + 2, elems, reserved, regs[R_MARK_DEPTH]))


@_compile
def _collect(d: Any, stack: Any, regs: Any, info: Any, traversed: Any, frames: Any, s: int,
             elems: int, reserved: int) -> None:
    """``VM.gc`` in the fast mode (``collect_fast``) on the registers."""
    regs[R_GC_RUNS] += 1
    collect_on_registers(d, stack, regs, info, traversed, frames, s, elems, reserved)
    regs[R_OLD_CHANGED] = 1


@_compile
def end_of_call_collection(d: Any, stack: Any, regs: Any, info: Any, traversed: Any,
                           frames: Any, s: int, elems: int, reserved: int,
                           may_undo: bool) -> None:
    """The collection after a call returned and its result was taken: when ``may_undo``
    (the call began on a fixed point, ``fastloop.CALL_ON_FIXED_HEAP``, and its caller kept
    nothing it made) and since then no collection ran, no old ``info`` was rewritten
    (``R_OLD_CHANGED``) and no allocation took a reached slot (``R_REACHED``), the return
    to that fixed point (``fastloop.undo_to_fixed_point``); else a collection."""
    if may_undo and regs[R_OLD_CHANGED] == 0 and regs[R_REACHED] == 0:
        regs[R_GC_RUNS] += 1
        undo_to_fixed_point(d, regs, info, s, elems, reserved)
    else:
        _collect(d, stack, regs, info, traversed, frames, s, elems, reserved)


@_compile
def _table_set_sure(d: Any, t: int, s: int, elems: int) -> bool:
    """Would ``_table_set`` on table ``t`` take its path (every segment of the chain inside
    the heap, every key index too, a chain no longer than the heap)? The room for a new
    segment is the caller's check."""
    size = len(d)
    g = 4 * elems + 2
    nobj = size // s
    seg = _i(d[t * s + 1]) | (_i(d[t * s + 2]) << 8)
    for _ in range(size // g + 1):
        if (seg + 1) * g > size:
            return False
        o = size - (seg + 1) * g
        for k in range(elems):
            kw = _i(d[o + 2 * k]) | (_i(d[o + 2 * k + 1]) << 8)
            if kw & 0x8000 and kw & 0x7FFF >= nobj:
                return False
        seg = (_i(d[o + 4 * elems]) | (_i(d[o + 4 * elems + 1]) << 8)) & _NO_NEXT_SEGMENT
        if seg == _NO_NEXT_SEGMENT:
            return True
    return False


@_compile
def _end_of_call(d: Any, stack: Any, regs: Any, info: Any, traversed: Any, frames: Any,
                 s: int, elems: int, reserved: int, kind: int, result_table: int,
                 w: Any, fixed: bool) -> bool:
    """The end of an element's ``fun`` once its closure call returned: foreach's pop,
    reduce's RET check, map's and filter's put in ``result_table``; then the collection
    (none for the table library's foreach: its RET check and pop alone).
    False with nothing done when Python must do it (an error, no room, a method to bind,
    a result table ``_table_set`` would refuse). ``fixed``: the call began on a fixed point
    (``fastloop.CALL_ON_FIXED_HEAP``, ``R_OLD_CHANGED`` and ``R_REACHED`` cleared there);
    when nothing it made outlives it (foreach, or a filter that put nothing) and both are
    still clear, the collection is the return to that fixed point
    (:func:`end_of_call_collection`)."""
    sp = regs[R_SP]
    if kind >= WALK_TABLE_FOREACH:
        # call_and_take (RET when the call left nothing, pop), then map's, filter's or
        # reduce's use of the result
        if sp + 1 <= w[W_DEPTH]:
            return False
        ret = _i(stack[sp])
        nobj = len(d) // s
        if kind == WALK_TABLE_MAP or kind == WALK_TABLE_FILTER:
            if ret >= nobj:
                return False
            put = ret
            if kind == WALK_TABLE_FILTER:  # to_bool: a non-zero int keeps the value
                put = w[W_DATA] if _true(d, ret, s) else -1
            # table_set_quiet; a set _table_set refuses (e.g. no room) is Python's
            if put >= 0 and (result_table >= nobj or put >= nobj
                             or _i(d[result_table * s]) & 7 != TABLE
                             or not _table_set(d, regs, result_table, w[W_KEY], put, s,
                                               elems)):
                return False
        elif kind == WALK_TABLE_REDUCE:
            w[W_ACCUM] = ret
        regs[R_SP] = sp - 1
        return True
    kept_nothing = kind == WALK_FOREACH
    if kind == WALK_FOREACH:
        if sp < 0:
            return False
        regs[R_SP] = sp - 1
    elif sp + 1 <= w[W_DEPTH]:
        return False  # the closure left nothing: RET
    elif kind == WALK_MAP or kind == WALK_FILTER:
        g = 4 * elems + 2
        ret = _i(stack[sp])
        nobj = len(d) // s
        if (sp + 2 >= regs[R_STACK_SIZE] or regs[R_LTSEG] - regs[R_RTOBJ] < s + g
                or ret >= nobj or w[W_DATA] >= nobj or result_table >= nobj
                or _i(d[result_table * s]) & 7 != TABLE
                or not _table_set_sure(d, result_table, s, elems)):
            return False
        put = ret if kind == WALK_MAP else w[W_DATA]
        pm = _i(d[put * s])
        if pm & 7 == CLOSURE and pm & FLAG2:
            ar = _i(d[put * s + 2])
            if ar != NO_ACTREC and not _i(d[ar * s]) & FLAG2:
                return False  # tput would bind a method
        # ret popped; push ret_tbl, push_int(key); then put
        reached = regs[R_REACHED]
        key = _obj_alloc(d, regs, s, reserved, INT, 0)
        if _i(info[key]) & NEW:
            # the slot of the call's own record, which its return left marked: no slot the
            # fixed point's collection reached
            regs[R_REACHED] = reached
        kv = w[W_KEY]
        d[key * s + 1] = kv & 0xFF
        d[key * s + 2] = (kv >> 8) & 0xFF
        stack[sp] = result_table
        stack[sp + 1] = key
        if kind == WALK_MAP:
            stack[sp + 2] = ret
            _table_set(d, regs, result_table, key, ret, s, elems)
        elif _true(d, ret, s):
            stack[sp + 2] = w[W_DATA]
            _table_set(d, regs, result_table, key, w[W_DATA], s, elems)
        else:
            kept_nothing = True
        regs[R_SP] = sp - 1
    end_of_call_collection(d, stack, regs, info, traversed, frames, s, elems, reserved,
                           fixed and kept_nothing)
    return True


@_compile
def _call_element_fun(d: Any, stack: Any, bcode: Any, regs: Any, info: Any,
                      traversed: Any, rules: Any, s: int, elems: int, reserved: int,
                      sp: int, kind: int, self_obj: int, closure: int, key: int, data: int,
                      w: Any, hosts: Any, outq: Any, ctl: Any, latch: Any,
                      entry: int) -> int:
    """A walk's call of ``fun`` on one element (``sp``: the stack top, the accumulator on
    it for ``neighbors_reduce``): the accumulator popped, then self, closure, key, data,
    (the accumulator), the argument count pushed, ``w``'s depth, key and data noted for
    :func:`_end_of_call`, and :func:`call_pushed`'s status. The caller has checked the
    room for the pushes and the count."""
    accum = -1
    if kind == WALK_REDUCE:
        accum = _i(stack[sp])
        sp -= 1
    elif kind == WALK_TABLE_REDUCE:
        accum = w[W_ACCUM]
    w[W_DEPTH] = sp + 1
    w[W_KEY] = key
    w[W_DATA] = data
    stack[sp + 1] = self_obj
    stack[sp + 2] = closure
    stack[sp + 3] = key
    stack[sp + 4] = data
    sp += 4
    argc = 2
    if kind == WALK_REDUCE or kind == WALK_TABLE_REDUCE:
        sp += 1
        stack[sp] = accum
        argc = 3
    count = _obj_alloc(d, regs, s, reserved, INT, 0)
    d[count * s + 1] = argc
    d[count * s + 2] = 0
    sp += 1
    stack[sp] = count
    return call_pushed(d, stack, bcode, regs, info, traversed, rules, s, elems, reserved,
                       sp, hosts, outq, ctl, latch, entry)


@_compile_owning
def xtreme_walk(d: Any, stack: Any, bcode: Any, regs: Any, info: Any, traversed: Any,
                rules: Any, s: int, elems: int, reserved: int, ring: Any, start: int,
                kind: int, closure: int, result_table: int, floats: bool, w: Any,
                hosts: Any, outq: Any, ctl: Any, latch: Any) -> int:
    """Neighbours ``start``.. of ``ring`` as ``neighbors._neighborlike_foreach`` does them
    for ``neighbors_foreach``/``neighbors_reduce`` (``kind``): data table, robot id,
    the closure call, the collections; a ``WALK_*`` result (see above)."""
    g = 4 * elems + 2
    frames = np.empty((4, regs[R_MARK_DEPTH] + 2), np.int64)
    value_type = FLOAT if floats else INT
    # the heap is a fixed point of the collector once a neighbour's end collected: the
    # next neighbour's call may begin on it (fastloop.CALL_ON_FIXED_HEAP)
    fixed = False
    for j in range(start, len(ring)):
        w[W_INDEX] = j
        sp = regs[R_SP]
        lsyms = regs[R_LSYMS]
        self_obj = darray_get(d, lsyms, 0, s, elems)
        if (sp + _WALK_PUSHES >= regs[R_STACK_SIZE] or self_obj < 0
                or regs[R_LTSEG] - regs[R_RTOBJ] < _WALK_OBJECTS * s + g
                or (kind == WALK_REDUCE and sp < 0)):
            return WALK_PYTHON
        # ---- the data table (_push_data_table): table, then each field's value, its name
        regs[R_REACHED] = 0
        regs[R_OLD_CHANGED] = 0  # (a fixed point when ``fixed``; else the call collects)
        t = _new_table(d, regs, s, reserved, elems)
        sp += 1
        stack[sp] = t
        for f in range(3):
            v = _obj_alloc(d, regs, s, reserved, value_type, 0)
            bits = ring[j, NB_DISTANCE + f] & 0xFFFF
            d[v * s + 1] = bits & 0xFF
            d[v * s + 2] = bits >> 8
            sid = _FIRST_FIELD_SID + f
            k = _obj_alloc(d, regs, s, reserved, STRING, sid)
            d[k * s + 1] = sid & 0xFF
            d[k * s + 2] = sid >> 8
            stack[sp + 1] = k
            stack[sp + 2] = v
            _table_set(d, regs, t, k, v, s, elems)  # a fresh table: room in its segment
        sp -= 1  # data = top; pop
        key = _obj_alloc(d, regs, s, reserved, INT, 0)
        robot = ring[j, NB_ROBOT] & 0xFFFF
        d[key * s + 1] = robot & 0xFF
        d[key * s + 2] = robot >> 8
        # ---- the call, then the end of the neighbour's fun and the walk's collection
        status = _call_element_fun(d, stack, bcode, regs, info, traversed, rules, s,
                                   elems, reserved, sp, kind, self_obj, closure, key, t, w,
                                   hosts, outq, ctl, latch,
                                   CALL_ON_FIXED_HEAP if fixed else CALL)
        if status != EXIT:
            w[W_STATUS] = status
            return WALK_IN_CALL
        if not _end_of_call(d, stack, regs, info, traversed, frames, s, elems, reserved,
                            kind, result_table, w, fixed):
            return WALK_AFTER_CALL
        # the walk's own collection (``vm.gc()`` after ``fun``) follows the one that ended
        # ``fun``, on the same roots: a collection of a collected heap changes nothing (its
        # marks, ``info`` and ``traversed`` come out the same), so only its count is kept,
        # unless that collection was not a fixed point of itself (``fastgc.UNSETTLED``)
        if regs[R_UNSETTLED]:
            _collect(d, stack, regs, info, traversed, frames, s, elems, reserved)
        else:
            regs[R_GC_RUNS] += 1
        fixed = regs[R_UNSETTLED] == 0
    w[W_INDEX] = len(ring)
    return WALK_DONE


#: slots of ``w`` for :func:`table_walk`: the segment, slot and segment visit reached
W_SEGMENT, W_SLOT, W_VISIT = 3, 4, 5
#: slots in ``w``
WALK_SLOTS = 9


@_compile_owning
def table_walk(d: Any, stack: Any, bcode: Any, regs: Any, info: Any, traversed: Any,
               rules: Any, s: int, elems: int, reserved: int, kind: int, closure: int,
               result_table: int, w: Any, hosts: Any, outq: Any, ctl: Any,
               latch: Any) -> int:
    """``table_library.foreach_live`` over a table's segments from ``w``'s position, with
    the ``fun`` of ``kind`` per valid element: the neighbours' (``neighbors_foreach`` ...
    ``neighbors_filter``, the heap-table builds' walk, self in local 0) or the table
    library's (``WALK_TABLE_*``, the table in local 1 as self). The
    segments are read live, as the C loop reads them, between the calls; a ``WALK_*``
    result with ``w`` at the element reached."""
    size = len(d)
    g = 4 * elems + 2
    max_segments = size // g
    frames = np.empty((4, regs[R_MARK_DEPTH] + 2), np.int64)
    self_slot = 1 if kind >= WALK_TABLE_FOREACH else 0
    si = w[W_SEGMENT]
    first = w[W_SLOT]
    # foreach's element calls begin by returning to the previous one's first collection
    # when they may (fastloop.CALL_IN_WALK); the first one here collects
    entry = CALL_IN_WALK if kind == WALK_TABLE_FOREACH else CALL
    regs[R_LEFT_FRAME] = 0
    for visit in range(w[W_VISIT], max_segments + 1):
        if si >= max_segments:
            return WALK_DONE
        for i in range(first, elems):
            w[W_SEGMENT] = si
            w[W_SLOT] = i
            w[W_VISIT] = visit
            o = size - (si + 1) * g
            kw = _i(d[o + 2 * i]) | (_i(d[o + 2 * i + 1]) << 8)
            if not kw & 0x8000:
                continue
            key = kw & 0x7FFF
            vo = o + 2 * (i + elems)
            value = (_i(d[vo]) | (_i(d[vo + 1]) << 8)) & 0x7FFF
            sp = regs[R_SP]
            self_obj = darray_get(d, regs[R_LSYMS], self_slot, s, elems)
            if (sp + _WALK_PUSHES >= regs[R_STACK_SIZE] or self_obj < 0
                    or regs[R_LTSEG] - regs[R_RTOBJ] < s
                    or (kind == WALK_REDUCE and sp < 0)):
                return WALK_PYTHON
            if entry == CALL_IN_WALK:
                forget_left_frame(d, regs, info, s, elems)
            status = _call_element_fun(d, stack, bcode, regs, info, traversed, rules,
                                       s, elems, reserved, sp, kind, self_obj, closure,
                                       key, value, w, hosts, outq, ctl, latch, entry)
            if status != EXIT:
                w[W_STATUS] = status
                return WALK_IN_CALL
            if not _end_of_call(d, stack, regs, info, traversed, frames, s, elems,
                                reserved, kind, result_table, w, False):
                return WALK_AFTER_CALL
        first = 0
        o = size - (si + 1) * g + 4 * elems
        si = (_i(d[o]) | (_i(d[o + 1]) << 8)) & _NO_NEXT_SEGMENT
        if si == _NO_NEXT_SEGMENT:
            return WALK_DONE
    return WALK_DONE


# ---- the table library's foreach, walked where the call was met -------------------------------
# A control step that calls ``foreach(t, f)`` (an M300 flocking drone's walk over its
# neighbours' positions) left the swarm step's machine code there: Python made the call,
# the walk (:func:`table_walk`, re-entered from ``table_library``) and the rest of the
# step, ~70 µs a drone of Python around a ~200 µs walk. :func:`run_walking` makes that call
# itself. Its walk may stop at any element (an instruction or host function the kernels leave
# to Python, the budget, an error), and a walk half made cannot be handed over: the walk
# starts from copies of everything a kernel writes — heap, stack, the collector's arrays,
# registers, out-queue, control words, latches — and a walk that stops puts them all back,
# so Python makes the whole call, as it would have. The elements' calls run the host
# functions of ``hosts`` but a stigmergy's (their entries live outside those arrays) and a
# nested foreach: such an element stops the walk.


@_compile_owning
def _walk_hosts(hosts: Any) -> Any:
    """The rows of ``hosts`` an element's call may run in place: all but a stigmergy's."""
    kept = 0
    for r in range(len(hosts)):
        if hosts[r, H_KIND] != HOST_VSTIG_GET and hosts[r, H_KIND] != HOST_VSTIG_PUT:
            kept += 1
    rows = np.empty((kept, hosts.shape[1]), np.int64)
    k = 0
    for r in range(len(hosts)):
        if hosts[r, H_KIND] != HOST_VSTIG_GET and hosts[r, H_KIND] != HOST_VSTIG_PUT:
            rows[k] = hosts[r]
            k += 1
    return rows


@_compile_owning
def _foreach_in_place(d: Any, stack: Any, bcode: Any, regs: Any, info: Any, traversed: Any,
                      rules: Any, s: int, elems: int, reserved: int, hosts: Any, outq: Any,
                      ctl: Any, latch: Any) -> bool:
    """``table_library.table_foreach`` of the C closure whose call ``run`` set up
    (``HOST_CALL``, the closure in ``R_HOST``) when ``hosts`` maps it there: the walk, the
    ``ret0`` and ``VM._loop``'s end of that step (no skip rule: the next step collects).
    False with nothing changed when Python must make the call (see above)."""
    saved = regs[R_SAVED]
    budget = regs[R_BUDGET]
    n = regs[R_N]
    if saved == NONE or (budget != NONE and n + 1 > budget):
        return False  # the budget's error is Python's
    row = _host_row(d, regs[R_HOST], s, hosts)
    if row < 0 or hosts[row, H_KIND] != HOST_TABLE_FOREACH:
        return False
    lsyms = regs[R_LSYMS]
    if darray_size(d, lsyms, s, elems) != 3:
        return False  # LNUM: Python reports it
    nobj = len(d) // s
    t = darray_get(d, lsyms, 1, s, elems)
    closure = darray_get(d, lsyms, 2, s, elems)
    if not (0 <= t < nobj and _i(d[t * s]) & 7 == TABLE
            and 0 <= closure < nobj and _i(d[closure * s]) & 7 == CLOSURE):
        return False  # TYPE: Python reports it
    kept_regs = regs.copy()
    kept_heap = d.copy()
    kept_stack = stack.copy()
    kept_info = info.copy()
    kept_traversed = traversed.copy()
    kept_outq = outq.copy()
    kept_ctl = ctl.copy()
    kept_latch = latch.copy()
    # (each element's call sets its loop's registers, enter_call; its first collection
    # starts R_OLD_CHANGED and R_REACHED afresh, fastloop.CALL_IN_WALK)
    w = np.zeros(WALK_SLOTS, np.int64)
    w[W_SEGMENT] = _u16(d, t, s)
    result = table_walk(d, stack, bcode, regs, info, traversed, rules, s, elems, reserved,
                        WALK_TABLE_FOREACH, closure, -1, w, _walk_hosts(hosts), outq, ctl,
                        latch)
    sp = regs[R_SP]
    bp = regs[R_BP]
    if result == WALK_DONE and _ret_ok(d, stack, False, sp, bp, regs[R_LSYMS], len(bcode), s,
                                       elems):
        _ret(d, stack, regs, False, sp, bp, regs[R_LSYMS], len(bcode), s, elems)
        regs[R_SAVED] = saved
        regs[R_N] = n + 1
        regs[R_FIXED] = 0
        regs[R_PENDING] = -1
        regs[R_CALL_FIRST] = kept_regs[R_CALL_FIRST]
        regs[R_REACHED] |= kept_regs[R_REACHED]
        regs[R_OLD_CHANGED] = 1  # the walk's calls collected: the caller's fixed point is gone
        return True
    regs[:] = kept_regs
    d[:] = kept_heap
    stack[:] = kept_stack
    info[:] = kept_info
    traversed[:] = kept_traversed
    outq[:] = kept_outq
    ctl[:] = kept_ctl
    latch[:] = kept_latch
    return False


@_compile
def run_walking(d: Any, stack: Any, bcode: Any, regs: Any, info: Any, traversed: Any,
                rules: Any, s: int, elems: int, reserved: int, hosts: Any, outq: Any,
                ctl: Any, latch: Any) -> int:
    """:func:`run_hosted`, with the table library's ``foreach`` walked in place (see
    above); returns what ``run_hosted`` last returned."""
    while True:
        status = run_hosted(d, stack, bcode, regs, info, traversed, rules, s, elems,
                            reserved, hosts, outq, ctl, latch)
        if status != HOST_CALL or len(hosts) == 0 or not _foreach_in_place(
                d, stack, bcode, regs, info, traversed, rules, s, elems, reserved, hosts,
                outq, ctl, latch):
            return status
