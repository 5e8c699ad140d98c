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
"""

from __future__ import annotations

import math
from array import array
from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

import numpy as np

from bbzide.vm.compiled.fastgc import COMPILED, _compile, _i
from bbzide.vm.compiled.fastring import ring_size, sort_ring_by_type
from bbzide.vm.heap_layout import VALID
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
#: ``neighbors.MARK``: the refreshed-since-the-last-data-GC bit
_MARK = 0x01
#: the most a u8 situated value can be (``robot._to_u8``)
_U8_MAX = 255


@_compile
def _to_u8(x: float) -> int:
    """``robot._to_u8``: round half to even, clamp to 0..255; NaN and infinities -> 255."""
    if not math.isfinite(x):
        return _U8_MAX
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
        if n < 5:
            return
        records[m + BC_TOPIC] = payload[p + 3]
        records[m + BC_TOPIC + 1] = payload[p + 4]
        if n < 6:
            return
        _read_object(records, m, BC_VALUE, payload, p, n)
        if n < 8:
            return
    elif t == VSTIG_PUT or t == VSTIG_QUERY:
        if n < 5:
            return
        records[m + VS_KEY] = payload[p + 3]
        records[m + VS_KEY + 1] = payload[p + 4]
        if n < 6:
            return
        _read_object(records, m, VS_DATA, payload, p, n)
        if n < 9:
            return
        records[m + VS_LAMPORT] = payload[p + 8]
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


@_compile
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


@_compile
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
