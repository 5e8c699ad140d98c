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

#: byte translation table clearing the GC mark bit of every metadata byte
_CLEAR_MARK = bytes(b & ~GC_MARK & 0xFF for b in range(256))


def _swept(b: int) -> bool:
    """Whether the sweep frees an object of metadata byte ``b``: valid and not marked."""
    return bool(b & VALID) and not b & GC_MARK


#: byte translation table of a metadata byte: 1 for a permanent object (a root)
_PERMANENT_FLAG = bytes(int(bool(b & PERMANENT)) for b in range(256))
#: byte translation table clearing the mark bit of a segment's mdata high byte
_CLEAR_SEGMENT_MARK = bytes(b & ~(SEG_MARK >> 8) & 0xFF for b in range(256))
#: byte translation tables of the sweep: a metadata byte after it, and 1 for a table it frees
_SWEEP = bytes(b & ~VALID & 0xFF if _swept(b) else b for b in range(256))
_FREED_TABLE = bytes(int(_swept(b) and b & TYPE_MASK == TABLE) for b in range(256))


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

    # 1. clear marks: the high byte of each of the k segments' mdata word, g bytes apart
    segment_flags = slice(size - k * g + mo + 1, size, g)
    d[segment_flags] = d[segment_flags].translate(_CLEAR_SEGMENT_MARK)
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
                        # the keys, then the values: each valid word names a child
                        for child in [word & ELEM_INDEX for word in unpack_words(d, base)
                                      if word & ELEM_VALID]:
                            if child >= nobj:
                                continue
                            co = child * s
                            cm = d[co]
                            if cm & GC_MARK:
                                continue  # mark would do nothing (hot path: no call)
                            ct = cm & TYPE_MASK
                            if ct == TABLE or (ct == CLOSURE and cm & FLAG2
                                               and d[co + 2] != NO_ACTREC):
                                mark(child)
                            else:  # its mark bit is all that mark would set
                                d[co] = cm | GC_MARK
                    seg = (d[base + mo] | (d[base + mo + 1] << 8)) & SEG_NEXT
                    if seg == SEG_NEXT:
                        break
            elif t == CLOSURE and m & FLAG2 and d[o + 2] != NO_ACTREC:
                mark(d[o + 2])
        depth -= 1

    # 2. permanent roots, 3. stack roots, in this order; a root's mark sits at depth 2, so
    # a leaf root (or a closure without a record) is marked without the call where the
    # limit allows depth 2
    permanent = d[0:n * s:s].translate(_PERMANENT_FLAG)
    roots = []
    i = permanent.rfind(1)
    while i >= 0:
        roots.append(i)
        i = permanent.rfind(1, 0, i)
    roots += [stack[j] for j in range(stack_top, -1, -1)]
    leaf_roots_marked = depth_limit >= 2
    for x in roots:
        if 0 <= x < nobj and leaf_roots_marked:
            m = d[x * s]
            if m & GC_MARK:
                continue  # mark would do nothing
            t = m & TYPE_MASK
            if t != TABLE and not (t == CLOSURE and m & FLAG2 and d[x * s + 2] != NO_ACTREC):
                d[x * s] = m | GC_MARK
                continue
        mark(x)

    # 4. sweep: every valid object left unmarked becomes invalid, and so does the segment
    # chain of such a table unless the chain's first segment was marked (through another
    # table). Only SEG_VALID bits change, never a SEG_MARK bit or a next index, so the
    # tables may be freed in any order.
    metadata = d[0:n * s:s]
    d[0:n * s:s] = metadata.translate(_SWEEP)
    freed = metadata.translate(_FREED_TABLE)
    i = freed.find(1)
    while i >= 0:
        o = i * s
        seg = d[o + 1] | (d[o + 2] << 8)
        if (seg + 1) * g <= size and not heap.seg_mdata(seg) & SEG_MARK:
            for sj in heap.segment_chain(seg):
                heap.set_seg_mdata(sj, heap.seg_mdata(sj) & ~SEG_VALID)
        i = freed.find(1, i + 1)

    # 5-6. shrink both ends over invalid slots
    low = heap.reserved * s
    while heap.rtobj > low and not d[heap.rtobj - s] & VALID:
        heap.rtobj -= s
    while heap.ltseg < size and not d[heap.ltseg + mo + 1] & (SEG_VALID >> 8):
        heap.ltseg += g
