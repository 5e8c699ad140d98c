"""Compiled receive path of the fast VM mode: a Kilobot's received messages of one step, at once.

The Kilobot receive handler does, per message, ``bbzneighbors_add`` (a BROADCAST's sender
into the XTREME neighbor ring, with its distance as a u8) and ``bbzinmsg_queue_append``
(decode into the scratch record, replace a queued broadcast of the same type, sender and
topic, or queue it; then the insertion sort by type). Written as Python over ``bytearray``
records and ``NeighborEntry`` objects that was ~20 µs a message, the largest cost of a
swarm once the in-queue was compiled (:mod:`fastinbox`). :func:`receive_messages` does
the same for all the messages a robot receives in a step, in one compiled call: the
in-queue records and the neighbor ring are packed into arrays, processed message by
message exactly as ``messages.inmsg_append`` and ``neighbors.add`` do, and copied back.

Only for profiles with the XTREME ring and u8 situated data (the Kilobot): there neither
routine touches the heap, so the VM's state cannot change and no error can happen; every
other profile (and the reference mode) keeps the per-message Python routines. The u8
conversion is ``robot._to_u8``: Python's ``round`` (ties to even), clamped to 0..255, 255
for NaN and infinities. Equality with the reference is by test
(``tests/vm/test_fast_inbox_equivalence.py``, ``tests/worlds/test_fast_swarm_equivalence.py``).

Profiles with the neighbor data in the heap (Crazyflie, M300): :func:`neighbors_add_heap`
is ``neighbors.add``'s heap branch for the compiled swarm step (:mod:`fastbatch`), the same
allocations, stack writes and table stores in the same order. It allocates, so it runs only
when nothing can go wrong (:func:`room_for_heap_add`: room for every object and segment it
may take, stack room, the ``neighbors`` table and its data sub-table well formed); else the
step hands the rest of the robot's messages to ``Robot.receive_all``. Likewise
:func:`data_gc_heap` is ``neighbors.data_gc``'s heap branch, run when every entry's fate
can be read beforehand (else the step hands ``process_outmsgs`` to Python).
"""

from __future__ import annotations

import math
from array import array
from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

import numpy as np

from bbzide.vm.compiled.fastgc import COMPILED, _compile, _compile_owning, _i
from bbzide.vm.compiled.fastloop import (
    R_LTSEG,
    R_RTOBJ,
    R_SP,
    R_STACK_SIZE,
    _obj_alloc,
    _seg_alloc,
    _table_set,
)
from bbzide.vm.compiled.fastring import ring_size, sort_ring_by_type
from bbzide.vm.compiled.fasttables import table_lookup
from bbzide.vm.heap_layout import (
    ELEM_INDEX,
    ELEM_VALID,
    FLOAT,
    INT,
    SEG_NEXT,
    STRING,
    TABLE,
    TYPE_MASK,
    VALID,
)
from bbzide.vm.message_layout import (
    BC_TOPIC,
    BC_VALUE,
    BROADCAST,
    PAYLOAD_RING_CAPACITY,
    PAYLOAD_SIZE,
    RID,
    TYPE,
    VS_DATA,
    VS_KEY,
    VS_LAMPORT,
    VSTIG_PUT,
    VSTIG_QUERY,
)

if TYPE_CHECKING:
    from bbzide.vm.vm import VM

# Slots of the ``rings`` array: the in-queue's and the neighbor ring's start/end/slots.
__all__ = ["COMPILED", "receive_all", "receive_messages"]

IN_START, IN_END, IN_SLOTS, NB_START, NB_END, NB_SLOTS = range(6)
#: columns of a packed neighbor record (``NeighborEntry``'s fields, in order)
NB_ROBOT, NB_DISTANCE, NB_AZIMUTH, NB_ELEVATION, NB_MARK = range(5)
RING_COLUMNS = 5
NB_FIELDS = 5

#: bytes compared to find a queued duplicate: type, rid, topic (offsets 0 ... 4)
_BROADCAST_KEY = 5
#: a broadcast's payload bytes: type, rid (2), topic (2), value (metadata, 2 payload bytes)
_BROADCAST_LENGTH = 8
#: a stigmergy record's payload bytes: type, rid (2), key (2), data (3), lamport clock
_STIGMERGY_LENGTH = 9
#: ``lamport_at`` of a record without a lamport clock (a broadcast)
_NO_LAMPORT = -1
#: ``neighbors.MARK``: the refreshed-since-the-last-data-GC bit
_MARK = 0x01
#: the most a u8 situated value can be (``robot._to_u8``)
_U8_MAX = 255


@_compile
def _to_u8(x: float) -> int:
    """``robot._to_u8``: round half to even, clamp to 0..255; NaN and infinities -> 255."""
    if not math.isfinite(x) or x >= _U8_MAX + 1:
        return _U8_MAX  # (clamped before the floor: numba's floor of a huge x is no int64)
    if x <= 0.0:
        return 0
    r = math.floor(x)
    frac = x - r  # exact for a double minus its floor
    if frac > 0.5 or (frac == 0.5 and r % 2 == 1):
        r += 1
    return int(min(_U8_MAX, max(0.0, r)))


@_compile
def _read_object(records: Any, m: int, at: int, payload: Any, p: int, n: int) -> None:
    """``messages._read_object``: metadata and (when present) 2 payload bytes, valid bit."""
    records[m + at] = payload[p + 5]
    if n >= 8:
        records[m + at + 1] = payload[p + 6]
        records[m + at + 2] = payload[p + 7]
    records[m + at] = _i(records[m + at]) | VALID


@_compile
def _read_keyed_record(records: Any, m: int, key_at: int, object_at: int, lamport_at: int,
                       length: int, payload: Any, p: int, n: int) -> bool:
    """The part of ``messages.inmsg_append`` after the sender that a broadcast (topic,
    value) and a stigmergy record (key, data, lamport) share: ``payload[p:p + n]``'s key
    (bytes 3-4) and object (from byte 5) copied to the scratch record ``m``'s ``key_at``
    and ``object_at``, then (``lamport_at`` >= 0) byte ``length - 1`` to ``lamport_at``.
    False when ``n`` cuts the record short of ``length`` bytes: it is dropped, with what
    was read before the cut left in the scratch record, as on the robot."""
    if n < 5:
        return False
    records[m + key_at] = payload[p + 3]
    records[m + key_at + 1] = payload[p + 4]
    if n < 6:
        return False
    _read_object(records, m, object_at, payload, p, n)
    if n < length:
        return False
    if lamport_at != _NO_LAMPORT:
        records[m + lamport_at] = payload[p + length - 1]
    return True


@_compile
def _inmsg_append(records: Any, rings: Any, size: int, payload: Any, p: int, n: int,
                  spare: Any) -> None:
    """``messages.inmsg_append`` of ``payload[p:p + n]`` (n already cut to the ring's)."""
    slots = rings[IN_SLOTS]
    m = slots * size  # the scratch record (records[capacity])
    records[m + TYPE] = 0
    if n < 1:
        return
    t = _i(payload[p])
    records[m + TYPE] = t
    if n < 3:
        return
    records[m + RID] = payload[p + 1]
    records[m + RID + 1] = payload[p + 2]
    if t == BROADCAST:
        if not _read_keyed_record(records, m, BC_TOPIC, BC_VALUE, _NO_LAMPORT,
                                  _BROADCAST_LENGTH, payload, p, n):
            return
    elif t == VSTIG_PUT or t == VSTIG_QUERY:
        if not _read_keyed_record(records, m, VS_KEY, VS_DATA, VS_LAMPORT,
                                  _STIGMERGY_LENGTH, payload, p, n):
            return
    else:
        return
    start = rings[IN_START]
    end = rings[IN_END]
    if t == BROADCAST:
        for i in range(ring_size(start, end, slots)):
            k = (((i + start) & 0xFF) % slots) * size
            same = True
            for j in range(_BROADCAST_KEY):
                if records[k + j] != records[m + j]:
                    same = False
                    break
            if same:
                for j in range(size):
                    records[k + j] = records[m + j]
                return
    if ring_size(start, end, slots) + 1 == slots:  # full: overwrite the last one
        k = ((end - 1 + slots) & 0xFF) % slots
    else:  # makeslot
        k = end
        rings[IN_END] = ((end + 1) & 0xFF) % slots
    for j in range(size):
        records[k * size + j] = records[m + j]
    sort_ring_by_type(records, rings[IN_START], rings[IN_END], rings[IN_SLOTS], size,
                      spare)


@_compile_owning
def _neighbors_add(ring: Any, rings: Any, robot: int, distance: int, azimuth: int,
                   elevation: int, mark: bool) -> None:
    """``neighbors.add`` on the XTREME ring (rows of ``ring``: NeighborEntry fields)."""
    start = rings[NB_START]
    end = rings[NB_END]
    slots = rings[NB_SLOTS]
    count = ring_size(start, end, slots)
    i = count
    while i:
        i -= 1
        k = ((i + start) & 0xFF) % slots
        if ring[k, NB_ROBOT] == robot:
            ring[k, NB_DISTANCE] = distance
            ring[k, NB_AZIMUTH] = azimuth
            ring[k, NB_ELEVATION] = elevation
            if mark:
                ring[k, NB_MARK] |= _MARK
            # the entry moves last, the ones after it shift down one place
            moved = ring[k].copy()
            for j in range(i, count - 1):
                a = ((j + start) & 0xFF) % slots
                b = ((j + 1 + start) & 0xFF) % slots
                ring[a] = ring[b]
            ring[((count - 1 + start) & 0xFF) % slots] = moved
            return
    k = end  # makeslot
    if count + 1 != slots:
        rings[NB_END] = ((end + 1) & 0xFF) % slots
    else:
        rings[NB_END] = start
        rings[NB_START] = ((start + 1) & 0xFF) % slots
    ring[k, NB_ROBOT] = robot
    ring[k, NB_DISTANCE] = distance
    ring[k, NB_AZIMUTH] = azimuth
    ring[k, NB_ELEVATION] = elevation
    if mark:
        ring[k, NB_MARK] |= _MARK


@_compile_owning
def receive_all(records: Any, ring: Any, rings: Any, size: int, payloads: Any,
                lengths: Any, situated: Any, mark: bool) -> None:
    """Message ``i`` (the next ``lengths[i]`` bytes of ``payloads``, at most the wire's)
    with its distance, azimuth and elevation (``situated[i]``, ``situated[count + i]``,
    ``situated[2 * count + i]``): the neighbor ring for a broadcast, then the in-queue —
    as ``Robot.receive`` does, message after message."""
    spare = np.empty(len(records), np.uint8)
    count = len(lengths)
    p = 0
    for i in range(count):
        n = min(_i(lengths[i]), PAYLOAD_RING_CAPACITY - 1)
        if n >= 3 and payloads[p] == BROADCAST:
            rid = _i(payloads[p + 1]) | (_i(payloads[p + 2]) << 8)
            _neighbors_add(ring, rings, rid, _to_u8(situated[i]),
                           _to_u8(situated[count + i]), _to_u8(situated[2 * count + i]),
                           mark)
        _inmsg_append(records, rings, size, payloads, p, n, spare)
        p += _i(lengths[i])


def receive_messages(vm: VM, deliveries: Sequence[tuple[Any, bytes, float, float, float]]
                     ) -> bool:
    """Run :func:`receive_all` for the engine's deliveries (``(sender, payload, distance,
    azimuth, elevation)`` each). False, with nothing changed, when a delivery is not what
    the wire carries (the caller then takes them one by one, the reference way)."""
    if not deliveries:
        return True
    try:
        payloads = [bytes(d[1][:PAYLOAD_SIZE]) for d in deliveries]
        situated = array("d", [d[2] for d in deliveries] + [d[3] for d in deliveries]
                         + [d[4] for d in deliveries])
    except (TypeError, ValueError, IndexError, OverflowError):  # e.g. an int past a double
        return False
    q = vm.queues.inbox
    in_records = q.records
    size = len(in_records[0])
    packed = bytearray().join(in_records)
    nb = vm.neighbors
    entries = nb.ring.records
    # one flat int list through array('q'): a third of np.array(list of tuples)'s time
    flat: list[int] = []
    for e in entries:
        flat += (e.robot, e.distance, e.azimuth, e.elevation, e.mark)
    ring = np.frombuffer(array("q", flat), np.int64).reshape(len(entries), RING_COLUMNS)
    rings = np.array((q.start, q.end, q.capacity, nb.ring.start, nb.ring.end,
                      nb.ring.capacity), np.int64)
    receive_all(np.frombuffer(packed, np.uint8), ring, rings, size,
                np.frombuffer(b"".join(payloads), np.uint8),
                np.frombuffer(bytes([len(p) for p in payloads]), np.uint8),
                np.frombuffer(situated, np.float64),
                nb.clear_counter < vm.profile.neighbors_mark_time)
    for k, record in enumerate(in_records):
        record[:] = packed[k * size:(k + 1) * size]
    for e, row in zip(entries, ring.tolist(), strict=True):
        e.robot, e.distance, e.azimuth, e.elevation, e.mark = row
    q.start, q.end, _slots, nb.ring.start, nb.ring.end, _nb_slots = rings.tolist()
    return True


# ---- neighbors.add for the profiles that keep the neighbor data in the heap ---------------
#: ``neighbors.STR_DATA``, ``STR_DISTANCE``, ``STR_AZIMUTH``, ``STR_ELEVATION``: the string
#: ids of the data sub-table's key and of a data table's three keys (base strings)
_STR_DATA, _STR_DISTANCE, _STR_AZIMUTH, _STR_ELEVATION = 44, 21, 22, 23
#: objects one add may allocate: the sub-table's key string, the robot id, the data table,
#: three values and their three key strings, and the mark's two int 0 (strings usually
#: deduplicate, so this is the worst case)
HEAP_ADD_OBJECTS = 11
#: segments one add may allocate: the data table's first, one more when its four entries
#: (three values and the mark) do not fit one segment, one for the sub-table's new entry
HEAP_ADD_SEGMENTS = 3
#: stack slots one add uses above the stack pointer (sub-table, id, data table, key, value)
HEAP_ADD_PUSHES = 5
#: float32 exponent bias minus the bbzfloat bias, and bbzfloat's infinity (bbzfloat.py)
_FLOAT32_OFFSET = 96
_BBZ_INFINITY = 63 << 9


@_compile
def _bbzfloat_of(x: float, scratch: Any) -> int:
    """``bbzfloat.from_float``: rounded to float32 (C's conversion, inf on overflow), then
    the float32 bits encoded (``from_float32_bits``: truncated mantissa, NaN's low bits)."""
    scratch[0] = x
    bits = _i(scratch.view(np.uint32)[0])
    sign = (bits >> 31) & 1
    exponent = (bits >> 23) & 0xFF
    mantissa = bits & 0x7FFFFF
    if exponent == 0:
        return sign << 15
    if exponent == 0xFF:
        return (sign << 15) | _BBZ_INFINITY | (mantissa & 0x1FF)
    if _FLOAT32_OFFSET < exponent < _FLOAT32_OFFSET + 62:
        return (sign << 15) | ((exponent - _FLOAT32_OFFSET) << 9) | (mantissa >> 14)
    return (sign << 15) | _BBZ_INFINITY


@_compile
def situated_value(x: float, floats: bool, scratch: Any) -> int:
    """``Robot.neighbor_entry``'s conversion: bbzfloat bits, or the u8 of int builds."""
    if floats:
        return _bbzfloat_of(x, scratch)
    return _to_u8(x)


@_compile
def _u16_at(d: Any, i: int, s: int) -> int:
    return _i(d[i * s + 1]) | (_i(d[i * s + 2]) << 8)


@_compile
def _chain_ok(d: Any, t: int, s: int, elems: int) -> bool:
    """Table ``t``'s chain is one ``fastloop._table_set`` walks to its end: every segment
    inside the heap, every valid key inside the heap, no longer than the heap holds."""
    size = len(d)
    g = 4 * elems + 2
    nobj = size // s
    seg = _u16_at(d, t, s)
    for _ in range(size // g + 1):
        if (seg + 1) * g > size:
            return False
        base = size - (seg + 1) * g
        for slot in range(elems):
            kw = _i(d[base + 2 * slot]) | (_i(d[base + 2 * slot + 1]) << 8)
            if kw & ELEM_VALID and (kw & ELEM_INDEX) >= nobj:
                return False
        seg = (_i(d[base + 4 * elems]) | (_i(d[base + 4 * elems + 1]) << 8)) & SEG_NEXT
        if seg == SEG_NEXT:
            return True
    return False


@_compile
def _data_subtable(d: Any, hpos: int, s: int, elems: int) -> int:
    """``table_get(neighbors, string 44)`` without allocating the key (a string key
    compares equal to another string of the same id); -1 when ``neighbors`` is not a
    well-formed table or the value is not one."""
    size = len(d)
    nobj = size // s
    g = 4 * elems + 2
    if not 0 <= hpos < nobj or _i(d[hpos * s]) & TYPE_MASK != TABLE:
        return -1
    seg = _u16_at(d, hpos, s)
    for _ in range(size // g + 1):
        if (seg + 1) * g > size:
            return -1
        base = size - (seg + 1) * g
        for slot in range(elems):
            kw = _i(d[base + 2 * slot]) | (_i(d[base + 2 * slot + 1]) << 8)
            k = kw & ELEM_INDEX
            if kw & ELEM_VALID and k < nobj and _i(d[k * s]) & TYPE_MASK == STRING \
                    and _u16_at(d, k, s) == _STR_DATA:
                vo = base + 2 * (slot + elems)
                v = (_i(d[vo]) | (_i(d[vo + 1]) << 8)) & ELEM_INDEX
                if v >= nobj or _i(d[v * s]) & TYPE_MASK != TABLE:
                    return -1
                return v
        seg = (_i(d[base + 4 * elems]) | (_i(d[base + 4 * elems + 1]) << 8)) & SEG_NEXT
        if seg == SEG_NEXT:
            return -1
    return -1


@_compile
def _room(d: Any, regs: Any, s: int, reserved: int, objects: int, segments: int,
          g: int) -> bool:
    """``segments`` segments grown and ``objects`` objects allocated (free slots below
    rtobj, or grown) would all succeed. (Strict: a string that deduplicates or a segment
    reused needs no room; harmless.)"""
    rtobj = regs[R_RTOBJ]
    gap = regs[R_LTSEG] - rtobj - segments * g
    if gap < 0:
        return False
    free = gap // s
    i = reserved
    while free < objects and i < rtobj // s:
        if not _i(d[i * s]) & VALID:
            free += 1
        i += 1
    return free >= objects


@_compile
def room_for_heap_add(d: Any, regs: Any, s: int, elems: int, reserved: int,
                      hpos: int) -> bool:
    """Would :func:`neighbors_add_heap` run without an error and without a case the
    kernels leave to Python? Room for :data:`HEAP_ADD_OBJECTS` objects and
    :data:`HEAP_ADD_SEGMENTS` segments, the stack room, and the ``neighbors`` table's
    data sub-table found and well formed."""
    if regs[R_SP] + HEAP_ADD_PUSHES >= regs[R_STACK_SIZE]:
        return False
    if not _room(d, regs, s, reserved, HEAP_ADD_OBJECTS, HEAP_ADD_SEGMENTS, 4 * elems + 2):
        return False
    sub = _data_subtable(d, hpos, s, elems)
    return sub >= 0 and _chain_ok(d, sub, s, elems)


@_compile
def _new_value(d: Any, regs: Any, s: int, reserved: int, typ: int, value: int) -> int:
    """``bbzint_new`` / ``bbzfloat_new`` / ``bbzstring_get`` (room checked by the caller)."""
    i = _obj_alloc(d, regs, s, reserved, typ, value if typ == STRING else 0)
    d[i * s + 1] = value & 0xFF
    d[i * s + 2] = (value >> 8) & 0xFF
    return i


@_compile
def _push(stack: Any, regs: Any, v: int) -> None:
    sp = regs[R_SP] + 1
    regs[R_SP] = sp
    stack[sp] = v


@_compile
def neighbors_add_heap(d: Any, stack: Any, regs: Any, s: int, elems: int, reserved: int,
                       hpos: int, robot: int, distance: int, azimuth: int, elevation: int,
                       floats: bool, mark: bool) -> None:
    """``neighbors.add``'s heap branch, statement by statement (after
    :func:`room_for_heap_add`): push ``neighbors``, ``tget`` its data sub-table, push the
    robot id and a new {distance, azimuth, elevation} table (each value allocated before
    its key string), the mark entry (value int allocated first: ``_MARK_VALUE_FIRST``),
    then ``tput``. The stack slots above the final pointer keep what the pushes wrote, as
    in the model. (``vm.neighbors.count`` is the caller's.)"""
    value_type = FLOAT if floats else INT
    _push(stack, regs, hpos)
    _push(stack, regs, _new_value(d, regs, s, reserved, STRING, _STR_DATA))
    regs[R_SP] -= 2  # op_tget: the table and the key popped, the sub-table pushed
    _push(stack, regs, _data_subtable(d, hpos, s, elems))
    _push(stack, regs, _new_value(d, regs, s, reserved, INT, robot & 0xFFFF))
    table = _obj_alloc(d, regs, s, reserved, TABLE, 0)
    seg = _seg_alloc(d, regs, elems)
    d[table * s + 1] = seg & 0xFF
    d[table * s + 2] = seg >> 8
    _push(stack, regs, table)
    for field in range(3):
        sid = _STR_DISTANCE + field
        bits = distance if field == 0 else (azimuth if field == 1 else elevation)
        value = _new_value(d, regs, s, reserved, value_type, bits)
        _push(stack, regs, _new_value(d, regs, s, reserved, STRING, sid))
        _push(stack, regs, value)
        key = stack[regs[R_SP] - 1]
        regs[R_SP] -= 3  # tput
        _table_set(d, regs, table, _i(key), value, s, elems)
        _push(stack, regs, table)
    if mark:
        v = _new_value(d, regs, s, reserved, INT, 0)
        k = _new_value(d, regs, s, reserved, INT, 0)
        _table_set(d, regs, table, k, v, s, elems)
    sp = regs[R_SP]
    regs[R_SP] = sp - 3  # tput: sub-table[robot id] = data table
    _table_set(d, regs, _i(stack[sp - 2]), _i(stack[sp - 1]), table, s, elems)


@_compile
def _has_zero_key(d: Any, t: int, s: int, elems: int) -> bool:
    """``table_get(t, int 0) is not None`` without allocating the key: ``t`` a table with
    a valid key that compares equal to int 0 (an int 0, or a float whose bits are 0)."""
    size = len(d)
    nobj = size // s
    g = 4 * elems + 2
    if not 0 <= t < nobj or _i(d[t * s]) & TYPE_MASK != TABLE:
        return False
    seg = _u16_at(d, t, s)
    for _ in range(size // g + 1):
        if (seg + 1) * g > size:
            return False
        base = size - (seg + 1) * g
        for slot in range(elems):
            kw = _i(d[base + 2 * slot]) | (_i(d[base + 2 * slot + 1]) << 8)
            k = kw & ELEM_INDEX
            if kw & ELEM_VALID and k < nobj:
                kind = _i(d[k * s]) & TYPE_MASK
                if (kind == INT or kind == FLOAT) and _u16_at(d, k, s) == 0:
                    return True
        seg = (_i(d[base + 4 * elems]) | (_i(d[base + 4 * elems + 1]) << 8)) & SEG_NEXT
        if seg == SEG_NEXT:
            return False
    return False


@_compile
def _data_gc_plan(d: Any, regs: Any, s: int, elems: int, reserved: int, hpos: int) -> int:
    """The data sub-table when :func:`data_gc_heap` may run: every entry's fate known
    beforehand (no segment of the sub-table left empty by its deletions, which would
    send ``foreach`` on through segment 0), the chains well formed, room for every int
    it allocates; else -1 (Python runs ``neighbors.data_gc``)."""
    size = len(d)
    g = 4 * elems + 2
    sub = _data_subtable(d, hpos, s, elems)
    if sub < 0 or not _chain_ok(d, sub, s, elems):
        return -1
    entries = 0
    seg = _u16_at(d, sub, s)
    for _ in range(size // g + 1):
        base = size - (seg + 1) * g
        valid = 0
        kept = 0
        for slot in range(elems):
            kw = _i(d[base + 2 * slot]) | (_i(d[base + 2 * slot + 1]) << 8)
            if kw & ELEM_VALID:
                valid += 1
                vo = base + 2 * (slot + elems)
                value = (_i(d[vo]) | (_i(d[vo + 1]) << 8)) & ELEM_INDEX
                if _has_zero_key(d, value, s, elems):
                    if not _chain_ok(d, value, s, elems):
                        return -1
                    kept += 1
        if valid > 0 and kept == 0:
            return -1
        entries += valid
        seg = (_i(d[base + 4 * elems]) | (_i(d[base + 4 * elems + 1]) << 8)) & SEG_NEXT
        if seg == SEG_NEXT:
            break
    # the key string, then per entry one int 0, and one more for a marked entry
    if not _room(d, regs, s, reserved, 1 + 2 * entries, 0, g):
        return -1
    return sub


@_compile
def data_gc_heap(d: Any, regs: Any, s: int, elems: int, reserved: int, hpos: int,
                 nil: int) -> int:
    """``neighbors.data_gc``'s heap branch, statement by statement: the key string
    allocated, then ``foreach`` over the data sub-table, live (each entry's int 0
    allocated; an unmarked entry deleted, a marked one unmarked with another int 0).
    Returns the entries deleted (``vm.neighbors.count`` is the caller's to lower), or -1
    with nothing done when Python must run it (:func:`_data_gc_plan`)."""
    sub = _data_gc_plan(d, regs, s, elems, reserved, hpos)
    if sub < 0:
        return -1
    size = len(d)
    g = 4 * elems + 2
    max_segments = size // g
    _new_value(d, regs, s, reserved, STRING, _STR_DATA)
    removed = 0
    seg = _u16_at(d, sub, s)
    for _ in range(max_segments + 1):
        if seg >= max_segments:
            break
        base = size - (seg + 1) * g
        for slot in range(elems):
            kw = _i(d[base + 2 * slot]) | (_i(d[base + 2 * slot + 1]) << 8)
            if kw & ELEM_VALID:
                vo = base + 2 * (slot + elems)
                value = (_i(d[vo]) | (_i(d[vo + 1]) << 8)) & ELEM_INDEX
                zero = _new_value(d, regs, s, reserved, INT, 0)
                if table_lookup(d, value, zero, s, elems) < 0:
                    removed += 1
                    _table_set(d, regs, sub, kw & ELEM_INDEX, nil, s, elems)
                else:
                    _table_set(d, regs, value, _new_value(d, regs, s, reserved, INT, 0), nil,
                               s, elems)
        seg = (_i(d[base + 4 * elems]) | (_i(d[base + 4 * elems + 1]) << 8)) & SEG_NEXT
        if seg == SEG_NEXT:
            break
    return removed
