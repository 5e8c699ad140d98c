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

from bbzide.vm.compiled.fastgc import _compile


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
def sort_ring_by_type(records: Any, start: int, end: int, slots: int, size: int,
                      spare: Any) -> None:
    """``RingBuffer.sort_by_type``: a stable sort of the queued records by their type byte
    (the first of each record). ``spare`` is scratch room for the moved copies; when it is
    shorter than the queue (pass an empty slice) a buffer is allocated, only if the records
    are out of order — they rarely are, and most queues hold 0 or 1 record."""
    count = ring_size(start, end, slots)
    ordered = True
    for i in range(1, count):
        a = ((i - 1 + start) & 0xFF) % slots
        b = ((i + start) & 0xFF) % slots
        if records[a * size] > records[b * size]:
            ordered = False
            break
    if ordered:
        return
    if len(spare) < count * size:
        spare = np.empty(count * size, np.uint8)
    for i in range(count):
        k = ((i + start) & 0xFF) % slots
        for j in range(size):
            spare[i * size + j] = records[k * size + j]
    placed = 0
    for typ in range(256):  # types are bytes: a counting pass per type keeps the order
        for i in range(count):
            if spare[i * size] == typ:
                k = ((placed + start) & 0xFF) % slots
                for j in range(size):
                    records[k * size + j] = spare[i * size + j]
                placed += 1
        if placed == count:
            break
