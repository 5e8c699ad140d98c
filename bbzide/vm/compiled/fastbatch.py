"""Compiled control step of one robot (fast VM mode): receive, in-queue, ``step``, out-queue.

``Robot.receive_all`` + ``Robot.control_step`` are four phases, each already compiled on
its own (:mod:`fastreceive`, :mod:`fastinbox`, :mod:`fasthost`); called one by one from
Python, with the queues packed and unpacked for each, the Python between them cost as much
as the machine code (benchmarks/world_bench.py). :func:`robot_step` runs the whole control
step of one robot in one call, on the robot's packed queues and ring (:mod:`packed_queues`,
which stay packed between steps):

1. receive the robot's rows of the step's deliveries (as :func:`fastreceive.receive_all`;
   a profile with the neighbor data in the heap through
   :func:`fastreceive.neighbors_add_heap`, while it has room: else ``P_RECEIVE``);
2. ``bbzvm_process_inmsgs`` (:func:`fastinbox.process_broadcasts`, and
   :func:`fastvstig.process_vstigs` for the stigmergy records among them, on the packed
   entries);
3. ``step`` (:func:`fastinbox.call_global`, and the ``pop`` of the firmware loop "pop");
4. ``bbzvm_process_outmsgs``: the neighbor-data GC countdown, the XTREME ring's data GC
   (``neighbors.data_gc``, ``bringToTop`` quirk included) or the heap's
   (:func:`fastreceive.data_gc_heap`, when it can tell every entry's fate: else
   ``P_OUTMSGS``);
5. the out-queue drained into the step's outbox rows (``messages.serialize``).

Each phase keeps the kernel's rule: what it does not cover it hands back **before any side
effect it cannot hand over**, and the call returns the phase it stopped in (``P_*``) with
what Python needs to go on exactly from there (``io``): the reference routines then finish
that robot's control step (``swarm_batch_fast``). Host functions of ``step`` and of the
listeners run in place when :mod:`fasthost` covers them (``hosts``), latched ones writing
the robot's latch slots (the return value has :data:`LATCHED` set then).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from bbzide.vm.compiled.fastgc import COMPILED, _compile, _compile_owning, _i
from bbzide.vm.compiled.fasthost import HOST_COLUMNS, clear_stale_readings
from bbzide.vm.compiled.fastinbox import (
    CALLED,
    DONE,
    NOT_DEFINED,
    PYTHON_MESSAGE,
    Q_COLLECTED,
    Q_COUNT,
    Q_END,
    Q_EXTRACTED,
    Q_INNER,
    Q_LISTENERS,
    Q_MAX,
    Q_RECORD,
    Q_SLOTS,
    Q_START,
    QUEUE_SLOTS,
    call_global,
    process_broadcasts,
)
from bbzide.vm.compiled.fastloop import R_NIL, R_SP, R_TWIN_END, R_UNSETTLED, R_VALID_BELOW
from bbzide.vm.compiled.fastreceive import (
    NB_MARK,
    _inmsg_append,
    _neighbors_add,
    _to_u8,
    data_gc_heap,
    neighbors_add_heap,
    room_for_heap_add,
    situated_value,
)
from bbzide.vm.compiled.fastring import ring_size
from bbzide.vm.compiled.fastviews import view_i32, view_i64, view_i64_rows, view_u8, view_u16
from bbzide.vm.compiled.fastvstig import (
    OTHER,
    STATE_SLOTS,
    V_COLLECTED,
    V_COUNT,
    V_END,
    V_ENTRIES,
    V_HPOS,
    V_MAX,
    V_OUT_END,
    V_OUT_SLOTS,
    V_OUT_START,
    V_RECORD,
    V_ROBOT,
    V_SLOTS,
    V_START,
    V_TAKEN,
    V_THRESHOLD,
    process_vstigs,
)
from bbzide.vm.compiled.packed_queues import (
    CLEAR_COUNTER,
    CLEAR_PERIOD,
    FLOATS,
    HPOS,
    IN_END,
    IN_SLOTS,
    IN_START,
    LAMPORT,
    LATCH_ARGS,
    LATCH_SLOTS,
    LISTENERS,
    MARK_TIME,
    MSG_MAX,
    NB_END,
    NB_SLOTS,
    NB_START,
    OUT_END,
    OUT_SLOTS,
    OUT_START,
    RECORD,
    RING_COLUMNS,
    ROBOT,
    VSTIG_COLUMNS,
    VSTIG_HPOS,
    VSTIG_ROWS,
    XTREME,
)
from bbzide.vm.heap_layout import TABLE
from bbzide.vm.message_layout import (
    BC_TOPIC,
    BC_VALUE,
    BROADCAST,
    PAYLOAD_SIZE,
    RID,
    TYPE,
    VS_DATA,
    VS_KEY,
    VS_LAMPORT,
    VSTIG_PUT,
    VSTIG_QUERY,
)

__all__ = ["COMPILED", "robot_step", "end_of_step", "P_DONE", "P_INMSGS", "P_STEP", "P_OUTMSGS",
           "P_RECEIVE", "LATCHED"]

# Phases a call stopped in (its return value, plus LATCHED when a latch slot was written).
P_DONE = 0      # everything asked for is done
P_INMSGS = 1    # the in-queue: io[IO_STATUS] is process_broadcasts' (or process_vstigs')
#                 status (PYTHON_MESSAGE or IN_CALL), io[IO_COUNT] / io[IO_COLLECTED] /
#                 io[IO_INNER] its state
P_STEP = 2      # ``step``: io[IO_STATUS] is call_global's status (PYTHON_MESSAGE: nothing
#                 done; CALLED with a stack it cannot pop; CALL_UNDER_WAY + run's status)
P_OUTMSGS = 3   # process_outmsgs needs the heap (a non-XTREME data GC): Python from there
P_RECEIVE = 4   # a heap profile's receive stopped at row io[IO_RECEIVED] (no room, see
#                 fastreceive.room_for_heap_add): Python receives from there, then steps
LATCHED = 8
# Flags of a call.
F_RECEIVE, F_STEP, F_POP = 1, 2, 4
# ``io`` slots.
IO_STATUS, IO_COUNT, IO_COLLECTED, IO_INNER, IO_ROWS = range(5)
#: the heap neighbor entries the receive added less those the data GC removed
#: (``vm.neighbors.count`` is Python's: it adds them, mod 256), and the row a P_RECEIVE
#: stopped at
IO_ADDED, IO_RECEIVED = 5, 6
IO_SLOTS = 7

_STR_STEP = 5
#: ``neighbors.MARK``: the refreshed-since-the-last-data-GC bit of a ring entry
_MARK = 0x01


@_compile_owning
def _receive(d: Any, stack: Any, regs: Any, s: int, elems: int, reserved: int, inq: Any,
             ring: Any, ctl: Any, payloads: Any, lengths: Any, distances: Any,
             azimuths: Any, elevations: Any, first: int, last: int, io: Any) -> int:
    """``Robot.receive`` of rows ``first:last`` (fastreceive.receive_all, row by row; the
    heap profiles' broadcasts through ``fastreceive.neighbors_add_heap``, counted in
    ``io[IO_ADDED]``). Returns the row it stopped at: ``last``, or the first broadcast
    whose heap add Python must make (``fastreceive.room_for_heap_add``)."""
    spare = np.empty(len(inq), np.uint8)
    scratch = np.empty(1, np.float32)
    size = ctl[RECORD]
    mark = ctl[CLEAR_COUNTER] < ctl[MARK_TIME]
    xtreme = ctl[XTREME] != 0
    floats = ctl[FLOATS] != 0
    hpos = ctl[HPOS]
    added = 0
    for k in range(first, last):
        n = min(lengths[k], PAYLOAD_SIZE)
        row = payloads[k]
        if n >= 3 and row[0] == BROADCAST:
            rid = _i(row[1]) | (_i(row[2]) << 8)
            if xtreme:
                _neighbors_add(ring, ctl, rid, _to_u8(distances[k]), _to_u8(azimuths[k]),
                               _to_u8(elevations[k]), mark)
            else:
                if not room_for_heap_add(d, regs, s, elems, reserved, hpos):
                    io[IO_ADDED] = added
                    return k
                neighbors_add_heap(d, stack, regs, s, elems, reserved, hpos, rid,
                                   situated_value(distances[k], floats, scratch),
                                   situated_value(azimuths[k], floats, scratch),
                                   situated_value(elevations[k], floats, scratch),
                                   floats, mark)
                added += 1
        _inmsg_append(inq, ctl, size, row, 0, n, spare)
    io[IO_ADDED] = added
    return last


@_compile
def _data_gc(ring: Any, ctl: Any) -> None:
    """``neighbors.data_gc`` on the XTREME ring: unmarked entries brought to the top (the
    firmware's ``bringToTop``: a u8 position counting up until it wraps) and popped."""
    start = ctl[NB_START]
    slots = ctl[NB_SLOTS]
    unmarked = 0
    i = 0
    while i < ring_size(start, ctl[NB_END], slots):
        k = ((i + start) & 0xFF) % slots
        if not ring[k, NB_MARK] & _MARK:
            pos = i
            while pos > 0:
                a = ((((pos - 1) & 0xFF) + start) & 0xFF) % slots
                b = ((pos + start) & 0xFF) % slots
                for j in range(ring.shape[1]):
                    t = ring[a, j]
                    ring[a, j] = ring[b, j]
                    ring[b, j] = t
                pos = (pos + 1) & 0xFF
            unmarked += 1
        else:
            ring[k, NB_MARK] &= 0xFF ^ _MARK
        i = (i + 1) & 0xFF
    for _ in range(unmarked):
        if start != ctl[NB_END]:
            start = ((start + 1) & 0xFF) % slots
    ctl[NB_START] = start


@_compile
def _drain(outq: Any, ctl: Any, index: int, out_payloads: Any, out_lengths: Any,
           out_robots: Any, io: Any) -> None:
    """``messages.drain_outbox``: every queued record serialised (``serialize``) into the
    outbox rows from ``io[IO_ROWS]`` on, head first."""
    size = ctl[RECORD]
    slots = ctl[OUT_SLOTS]
    start = ctl[OUT_START]
    end = ctl[OUT_END]
    row = io[IO_ROWS]
    while start != end:
        o = start * size
        out = out_payloads[row]
        for j in range(PAYLOAD_SIZE):
            out[j] = 0
        t = _i(outq[o])
        out[0] = t
        out[1] = outq[o + RID]
        out[2] = outq[o + RID + 1]
        n = 3
        if t == BROADCAST:
            if _i(outq[o + BC_VALUE]) & 7 != TABLE:
                out[3] = outq[o + BC_TOPIC]
                out[4] = outq[o + BC_TOPIC + 1]
                for j in range(3):
                    out[5 + j] = outq[o + BC_VALUE + j]
                n = 8
        elif t == VSTIG_PUT or t == VSTIG_QUERY:
            if _i(outq[o + VS_DATA]) & 7 != TABLE:
                out[3] = outq[o + VS_KEY]
                out[4] = outq[o + VS_KEY + 1]
                for j in range(3):
                    out[5 + j] = outq[o + VS_DATA + j]
                out[8] = outq[o + VS_LAMPORT]
                n = 9
        out_lengths[row] = n
        out_robots[row] = index
        row += 1
        start = ((start + 1) & 0xFF) % slots
    ctl[OUT_START] = start
    io[IO_ROWS] = row


@_compile
def _stigmergy_head(inq: Any, q: Any) -> bool:
    """Is the in-queue's head a stigmergy record?"""
    head = ((q[Q_START] & 0xFF) % q[Q_SLOTS]) * q[Q_RECORD]
    typ = _i(inq[head + TYPE])
    return typ == VSTIG_PUT or typ == VSTIG_QUERY


@_compile_owning
def _process_vstigs(d: Any, stack: Any, regs: Any, info: Any, traversed: Any, s: int,
                    elems: int, reserved: int, inq: Any, q: Any, ctl: Any, vstig: Any,
                    outq: Any) -> int:
    """:func:`fastvstig.process_vstigs` from the head (collected for: ``V_TAKEN``) on the
    packed queues and stigmergy entries, with the in-queue loop's state ``q``; returns
    its status (``DONE``, ``PYTHON_MESSAGE`` or ``OTHER``)."""
    state = np.zeros(STATE_SLOTS, np.int64)
    state[V_START] = q[Q_START]
    state[V_END] = q[Q_END]
    state[V_SLOTS] = q[Q_SLOTS]
    state[V_RECORD] = q[Q_RECORD]
    state[V_COUNT] = q[Q_COUNT]
    state[V_MAX] = q[Q_MAX]
    state[V_COLLECTED] = q[Q_COLLECTED]
    state[V_TAKEN] = 1
    state[V_ROBOT] = ctl[ROBOT]
    state[V_THRESHOLD] = ctl[LAMPORT]
    state[V_HPOS] = ctl[VSTIG_HPOS]
    state[V_ENTRIES] = ctl[VSTIG_ROWS]
    state[V_OUT_START] = ctl[OUT_START]
    state[V_OUT_END] = ctl[OUT_END]
    state[V_OUT_SLOTS] = ctl[OUT_SLOTS]
    status = process_vstigs(d, stack, regs, info, traversed, s, elems, reserved, inq, state,
                            vstig, outq)
    q[Q_START] = state[V_START]
    q[Q_COUNT] = state[V_COUNT]
    q[Q_COLLECTED] = state[V_COLLECTED]
    ctl[VSTIG_ROWS] = state[V_ENTRIES]
    ctl[OUT_START] = state[V_OUT_START]
    ctl[OUT_END] = state[V_OUT_END]
    return status


@_compile
def end_of_step(d: Any, regs: Any, s: int, elems: int, reserved: int, outq: Any, ring: Any,
                ctl: Any, index: int, out_payloads: Any, out_lengths: Any, out_robots: Any,
                io: Any) -> bool:
    """The end of a control step on the packed queues: ``process_outmsgs`` (the neighbor-
    data GC countdown, u8, then the data GC: the ring's, or the heap's with the entries it
    deleted taken off ``io[IO_ADDED]``), then ``drain_outbox`` into the outbox rows from
    ``io[IO_ROWS]`` on. False with nothing done when the heap's data GC is Python's."""
    was = ctl[CLEAR_COUNTER]
    removed = 0
    if was == 0 and not ctl[XTREME]:
        removed = data_gc_heap(d, regs, s, elems, reserved, ctl[HPOS], regs[R_NIL])
    if removed < 0:
        return False
    ctl[CLEAR_COUNTER] = (was - 1) & 0xFF
    if was == 0:
        ctl[CLEAR_COUNTER] = ctl[CLEAR_PERIOD]
        if ctl[XTREME]:
            _data_gc(ring, ctl)
        else:
            io[IO_ADDED] -= removed
    _drain(outq, ctl, index, out_payloads, out_lengths, out_robots, io)
    return True


@_compile_owning
def robot_step(d: Any, stack: Any, bcode: Any, regs: Any, info: Any, traversed: Any,
               rules: Any, s: int, elems: int, reserved: int, inq: Any, outq: Any,
               ring: Any, ctl: Any, latch: Any, hosts: Any, vstig: Any, payloads: Any,
               lengths: Any,
               distances: Any, azimuths: Any, elevations: Any, first: int, last: int,
               flags: int, index: int, out_payloads: Any, out_lengths: Any,
               out_robots: Any, io: Any) -> int:
    """One robot's receive (``F_RECEIVE``) and control step (``F_STEP``; ``F_POP``: the
    firmware loop pops ``step``'s result) on its packed queues; the VM must be READY.
    Returns the phase it stopped in (``P_*``), plus :data:`LATCHED` when a latch slot was
    written; ``regs`` then holds the VM's registers (see the module comment). What it
    sends goes to the outbox rows from ``io[IO_ROWS]`` on, as robot ``index``'s."""
    if flags & F_RECEIVE:
        stopped = _receive(d, stack, regs, s, elems, reserved, inq, ring, ctl, payloads,
                           lengths, distances, azimuths, elevations, first, last, io)
        if stopped < last:
            io[IO_RECEIVED] = stopped
            return P_RECEIVE
    if not flags & F_STEP:
        return P_DONE
    latched = latch[:LATCH_SLOTS, 0].any()
    phase = P_DONE
    # ---- process_inmsgs
    q = np.zeros(QUEUE_SLOTS, np.int64)
    q[Q_START] = ctl[IN_START]
    q[Q_END] = ctl[IN_END]
    q[Q_SLOTS] = ctl[IN_SLOTS]
    q[Q_RECORD] = ctl[RECORD]
    q[Q_MAX] = ctl[MSG_MAX]
    q[Q_LISTENERS] = ctl[LISTENERS]
    status = DONE
    if q[Q_START] != q[Q_END]:
        status = process_broadcasts(d, stack, bcode, regs, info, traversed, rules, s, elems,
                                    reserved, inq, q, hosts, outq, ctl, latch)
        # a stigmergy record at the head, collected for: the stigmergy loop goes on from
        # its extraction, and the broadcast loop from the next record it leaves (OTHER)
        # (a record it hands back, PYTHON_MESSAGE, is Python's: the loop ends)
        while status == PYTHON_MESSAGE and _stigmergy_head(inq, q):
            status = _process_vstigs(d, stack, regs, info, traversed, s, elems, reserved,
                                     inq, q, ctl, vstig, outq)
            if status != OTHER:
                break
            status = process_broadcasts(d, stack, bcode, regs, info, traversed, rules, s,
                                        elems, reserved, inq, q, hosts, outq, ctl, latch)
        ctl[IN_START] = q[Q_START]
        q[Q_EXTRACTED] = 0
    if status != DONE:
        io[IO_STATUS] = status
        io[IO_COUNT] = q[Q_COUNT]
        io[IO_COLLECTED] = q[Q_COLLECTED]
        io[IO_INNER] = q[Q_INNER]
        phase = P_INMSGS
    else:
        # ---- step, and the firmware loop's pop of its result
        status = call_global(d, stack, bcode, regs, info, traversed, rules, s, elems,
                             reserved, _STR_STEP, hosts, outq, ctl, latch,
                             status == DONE and q[Q_COLLECTED] == 1)
        if status == CALLED and flags & F_POP and regs[R_SP] >= 0:
            regs[R_SP] -= 1
        elif status != NOT_DEFINED and (status != CALLED or flags & F_POP):
            io[IO_STATUS] = status
            phase = P_STEP
    if phase == P_DONE and not end_of_step(d, regs, s, elems, reserved, outq, ring, ctl,
                                           index, out_payloads, out_lengths, out_robots, io):
        phase = P_OUTMSGS
    if latched or latch[:LATCH_SLOTS, 0].any():
        return phase | LATCHED
    return phase


__all__ += ["F_RECEIVE", "F_STEP", "F_POP", "IO_STATUS", "IO_COUNT", "IO_COLLECTED",
            "IO_INNER", "IO_ROWS", "IO_ADDED", "IO_RECEIVED", "IO_SLOTS", "PYTHON_MESSAGE"]


# ---- a whole swarm's control step: robot_step for each robot, in one call ---------------------
#: columns of ``dynamic``: the VM registers Python keeps as attributes (``VM``/``Heap``),
#: copied in before a robot's step and out after it
D_PC, D_SP, D_BP, D_RTOBJ, D_LTSEG, D_LSYMS, D_GC_RUNS, D_EXECUTED, D_PEAK, D_BUDGET = range(10)
D_TRUNCATED = 10
DYNAMIC = 11
#: ``fastloop``'s register slot of each ``dynamic`` column
_DYNAMIC_REGISTER = (0, 1, 2, 3, 4, 5, 6, 7, 11, 15, 29)
# Columns of ``addresses``/``sizes``: a robot's arrays (swarm_batch_fast._SwarmTables).
A_HEAP, A_STACK, A_BCODE, A_INFO, A_TRAVERSED, A_INQ, A_OUTQ = range(7)
A_RING, A_CTL, A_LATCH, A_HOSTS, A_VSTIG = 7, 8, 9, 10, 11
ARRAYS = 12
# Columns of ``geometry``: the heap geometry of each robot.
G_OBJ, G_ELEMS, G_RESERVED = range(3)
# Columns of a ``latched`` row: the latch group (see swarm_batch_fast), target, arguments.
L_GROUP, L_TARGET, L_ARGS = 0, 1, 2


@_compile_owning
def swarm_step(addresses: Any, sizes: Any, geometry: Any, registers: Any, dynamic: Any,
               todo: Any, flags: Any, rules: Any, payloads: Any, lengths: Any,
               distances: Any, azimuths: Any, elevations: Any, bounds: Any,
               out_payloads: Any, out_lengths: Any, out_robots: Any, cursor: Any, ios: Any,
               phases: Any, groups: Any, targets: Any, latched: Any) -> int:
    """:func:`robot_step` of robot ``i`` for each ``i`` in ``todo``: its arrays are views
    made from ``addresses[i, A_*]`` and ``sizes[i, A_*]`` (:mod:`fastviews`; lengths, or
    rows for the 2-D ones), ``registers[i]`` its register row with the constant slots
    filled, ``dynamic[i]`` the rest in and out, ``flags[i]`` its flags, its deliveries
    ``bounds[i]:bounds[i + 1]``. Its phase goes to ``phases[i]`` (without
    :data:`LATCHED`) and its hand-over state to ``ios[i]``; the outbox rows are filled
    from ``cursor[0]`` on (and ``cursor[0]`` moved past them). Written latch slots are
    cleared and listed as rows of ``latched`` (``groups[i, slot]``, ``targets[i, slot]``,
    the arguments). Returns the number of latched rows."""
    rows = cursor[0]
    count = 0
    for i in todo:
        a = addresses[i]
        n = sizes[i]
        heap = view_u8(a[A_HEAP], n[A_HEAP])
        stack = view_u16(a[A_STACK], n[A_STACK])
        bcode = view_u8(a[A_BCODE], n[A_BCODE])
        info = view_u8(a[A_INFO], n[A_INFO])
        traversed = view_i32(a[A_TRAVERSED], n[A_TRAVERSED])
        inq = view_u8(a[A_INQ], n[A_INQ])
        outq = view_u8(a[A_OUTQ], n[A_OUTQ])
        ring = view_i64_rows(a[A_RING], n[A_RING], RING_COLUMNS)
        ctl = view_i64(a[A_CTL], n[A_CTL])
        latch = view_i64_rows(a[A_LATCH], n[A_LATCH], 1 + LATCH_ARGS)
        hosts = view_i64_rows(a[A_HOSTS], n[A_HOSTS], HOST_COLUMNS)
        vstig = view_i64_rows(a[A_VSTIG], n[A_VSTIG], VSTIG_COLUMNS)
        regs = registers[i]
        dyn = dynamic[i]
        for k in range(DYNAMIC):
            regs[_DYNAMIC_REGISTER[k]] = dyn[k]
        regs[R_VALID_BELOW] = 0  # Python may have freed objects since its last step
        regs[R_TWIN_END] = 0  # or made strings
        regs[R_UNSETTLED] = 1  # (or collected): no fixed point until a collection here
        io = ios[i]
        io[IO_ROWS] = rows
        g = geometry[i]
        phase = robot_step(heap, stack, bcode, regs, info, traversed, rules, g[G_OBJ],
                           g[G_ELEMS], g[G_RESERVED], inq, outq, ring, ctl, latch, hosts, vstig,
                           payloads, lengths, distances, azimuths, elevations, bounds[i],
                           bounds[i + 1], flags[i], i, out_payloads, out_lengths,
                           out_robots, io)
        rows = io[IO_ROWS]
        for k in range(DYNAMIC):
            dyn[k] = regs[_DYNAMIC_REGISTER[k]]
        if phase & LATCHED:
            phase ^= LATCHED
            for slot in range(LATCH_SLOTS):
                if latch[slot, 0]:
                    latch[slot, 0] = 0
                    clear_stale_readings(hosts, latch, slot)
                    latched[count, L_GROUP] = groups[i, slot]
                    latched[count, L_TARGET] = targets[i, slot]
                    for a in range(latch.shape[1] - 1):
                        latched[count, L_ARGS + a] = latch[slot, 1 + a]
                    count += 1
        phases[i] = phase
    cursor[0] = rows
    return count


__all__ += ["swarm_step", "ARRAYS", "DYNAMIC", "D_BUDGET", "D_TRUNCATED", "G_OBJ", "G_ELEMS",
            "G_RESERVED", "L_GROUP", "L_TARGET", "L_ARGS"]
