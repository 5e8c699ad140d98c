"""Ring-buffer kernels shared by the compiled message paths (receive, out-queue, whole swarm).

The packed form of ``messages.RingBuffer`` (``bbzringbuf``): records of ``size`` bytes at
``k * size`` in one byte array, ``start``/``end`` indices moved with BittyBuzz's u8
arithmetic (``((i + start) & 0xFF) % slots``), one slot always unused. The in-queue, the
out-queue and the XTREME neighbor ring all use it, from three kernel files
(:mod:`fastreceive`, :mod:`fasthost`, :mod:`fastbatch`), so the size and the sort live here,
once. Equality with the Python ``RingBuffer`` is by the equivalence tests of those paths.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from bbzide.vm.compiled.fastgc import _compile, _compile_owning


@_compile
def ring_size(start: int, end: int, slots: int) -> int:
    """Records queued between ``start`` and ``end`` (``bbzringbuf_size``)."""
    return end - start if end >= start else slots - (start - end)


@_compile
def out_template(records: Any, start: int, end: int, slots: int, size: int) -> tuple[int, int]:
    """``outmsg_queue_append_template`` (``messages._out_template``): the slot the next
    out-message is written into and the queue's new end. A full queue keeps its end and
    gets its unused record copied over its last one, the firmware's overflow bug."""
    m = (end & 0xFF) % slots
    if ring_size(start, end, slots) + 1 == slots:
        last = ((end - 1 + slots) & 0xFF) % slots
        for j in range(size):
            records[last * size + j] = records[m * size + j]
        return m, end
    return m, ((end + 1) & 0xFF) % slots


@_compile
def _slot(start: int, i: int, slots: int) -> int:
    """The slot of the ``i``-th queued record: ``((i + start) & 0xFF) % slots``, the
    division skipped when the wrapped index is already below ``slots``."""
    u = (i + start) & 0xFF
    return u if u < slots else u % slots


@_compile_owning
def sort_ring_by_type(records: Any, start: int, end: int, slots: int, size: int,
                      spare: Any) -> None:
    """``RingBuffer.sort_by_type``: a stable sort of the queued records by their type byte
    (the first of each record), as an insertion sort from the first record out of order:
    a queue is sorted after every append, so an append costs one pass over the types and
    the moves of its own record (a full 255-record out-queue was re-sorted whole on every
    append). ``spare`` is scratch room for one record; when it is shorter (pass an empty
    slice) a buffer is allocated, only if a record is out of order."""
    count = ring_size(start, end, slots)
    first = 1
    previous = records[_slot(start, 0, slots) * size] if count else 0
    while first < count:
        typ = records[_slot(start, first, slots) * size]
        if previous > typ:
            break
        previous = typ
        first += 1
    if first >= count:
        return
    if len(spare) < size:
        spare = np.empty(size, np.uint8)
    for i in range(first, count):
        k = _slot(start, i, slots) * size
        typ = records[k]
        j = i
        below = _slot(start, j - 1, slots) * size
        if records[below] <= typ:
            continue
        for b in range(size):
            spare[b] = records[k + b]
        while True:  # move the greater records up one slot, stably
            for b in range(size):
                records[k + b] = records[below + b]
            k = below
            j -= 1
            if j == 0:
                break
            below = _slot(start, j - 1, slots) * size
            if records[below] <= typ:
                break
        for b in range(size):
            records[k + b] = spare[b]
