"""The BittyBuzz mark-and-sweep garbage collector (spec §E.9).

Faithful to ``bbzheap_gc``: roots are the permanent objects (scanned from the highest
index down, validity not checked) and then the stack from top to bottom. Marking is
depth-limited: a counter starts at 1 and is incremented on entry of ``mark``; an object
is marked only while the counter is ≤ ``gcmark_depth``, so roots sit at level 2 and only
``depth - 1`` levels are traversed — deeper reachable objects ARE freed, as on the robot.
Traversal order matters (first visit wins), so the order below is the reference order.
Mark bits stay set after a collection (they are visible in the heap bytes).

Where C would read outside the heap (a stale table payload, a corrupt or cyclic chain) this
model stops instead: a segment whose bytes fall outside the heap ends its chain, an object
index past the heap is ignored, and a chain stops after as many segments as the heap holds
(the firmware would loop forever). :mod:`bbzide.vm.compiled.fastgc` does exactly the same.
"""

from __future__ import annotations

import struct
from collections.abc import Sequence

from bbzide.vm.heap import (
    CLOSURE,
    ELEM_INDEX,
    ELEM_VALID,
    FLAG2,
    GC_MARK,
    NO_ACTREC,
    PERMANENT,
    SEG_MARK,
    SEG_NEXT,
    SEG_VALID,
    TABLE,
    TYPE_MASK,
    VALID,
    Heap,
)

#: the types whose objects refer to others (a table's elements, a closure's activation record)
REFERRING = (TABLE, CLOSURE)
#: byte translation table clearing the GC mark bit of every metadata byte
_CLEAR_MARK = bytes(b & ~GC_MARK & 0xFF for b in range(256))


def collect(heap: Heap, stack: Sequence[int], stack_top: int) -> None:
    """Run one collection. ``stack[0..stack_top]`` are the live stack words."""
    d = heap.data
    s = heap.obj_size
    n = heap.rtobj // s
    k = (heap.size - heap.ltseg) // heap.seg_size
    size = heap.size
    g = heap.seg_size
    mo = 4 * heap.elems          # offset of the mdata word inside a segment
    nwords = 2 * heap.elems
    depth_limit = heap.profile.gcmark_depth
    nobj = size // s
    max_chain = size // g + 1
    # a segment's 2 * elems little-endian 16-bit words (its keys, then its values)
    unpack_words = struct.Struct(f"<{nwords}H").unpack_from
    heap.gc_runs += 1

    # 1. clear marks
    for j in range(k - 1, -1, -1):
        d[size - (j + 1) * g + mo + 1] &= ~(SEG_MARK >> 8) & 0xFF
    d[0:n * s:s] = d[0:n * s:s].translate(_CLEAR_MARK)

    depth = 1

    def mark(x: int) -> None:
        nonlocal depth
        depth += 1
        o = x * s
        if 0 <= x < nobj and depth <= depth_limit and not d[o] & GC_MARK:
            d[o] |= GC_MARK
            m = d[o]
            t = m & TYPE_MASK
            if t == TABLE:
                seg = d[o + 1] | (d[o + 2] << 8)
                walked = 0
                # a child is marked only below the depth limit (the same for every word)
                children = depth < depth_limit
                while (seg + 1) * g <= size and walked < max_chain:
                    walked += 1
                    base = size - (seg + 1) * g
                    d[base + mo + 1] |= SEG_MARK >> 8
                    if children:
                        for word in unpack_words(d, base):  # the keys, then the values
                            child = word & ELEM_INDEX
                            if not word & ELEM_VALID or child >= nobj:
                                continue
                            cm = d[child * s]
                            if cm & GC_MARK:
                                continue  # mark would do nothing (hot path: no call)
                            if cm & TYPE_MASK in REFERRING:
                                mark(child)
                            else:  # a leaf: its mark bit is all that mark would set
                                d[child * s] = cm | GC_MARK
                    seg = (d[base + mo] | (d[base + mo + 1] << 8)) & SEG_NEXT
                    if seg == SEG_NEXT:
                        break
            elif t == CLOSURE and m & FLAG2 and d[o + 2] != NO_ACTREC:
                mark(d[o + 2])
        depth -= 1

    # 2. permanent roots, 3. stack roots
    for i in range(n - 1, -1, -1):
        if d[i * s] & PERMANENT:
            mark(i)
    for j in range(stack_top, -1, -1):
        mark(stack[j])

    # 4. sweep
    for i in range(n - 1, -1, -1):
        o = i * s
        m = d[o]
        if not m & GC_MARK and m & VALID:
            d[o] = m & ~VALID & 0xFF
            if m & TYPE_MASK == TABLE:
                seg = d[o + 1] | (d[o + 2] << 8)
                if (seg + 1) * g <= size and not heap.seg_mdata(seg) & SEG_MARK:
                    for sj in heap.segment_chain(seg):
                        heap.set_seg_mdata(sj, heap.seg_mdata(sj) & ~SEG_VALID)

    # 5-6. shrink both ends over invalid slots
    low = heap.reserved * s
    while heap.rtobj > low and not d[heap.rtobj - s] & VALID:
        heap.rtobj -= s
    while heap.ltseg < size and not d[heap.ltseg + mo + 1] & (SEG_VALID >> 8):
        heap.ltseg += g
