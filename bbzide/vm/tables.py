"""Tables and darrays laid out in heap segments (spec §E.6, §E.7).

A table object's payload is the index of its first segment; segments chain through the
14-bit ``next`` field of their mdata word. A table segment holds E key words and E value
words; a darray segment uses the same 2E words as values. Element words carry bit 15 =
valid, bits 0-14 = heap index. Every function here mirrors one ``bbztable_*``/
``bbzdarray_*`` routine, including its quirks (darray ``size`` unlinks trailing segments,
``pop`` leaves an empty trailing segment until the next pop).
The four hottest readers (``table_get``, ``darray_get/set/size``) run in the fast mode as
compiled loops (``fasttables``, through the seam :mod:`bbzide.vm.kernels`); a heap of the
reference mode (``heap.reference``) reads through the plain walks below, so the reference
shares no code with the kernels it checks. Both stop where C would read outside the heap
(a stale payload, a corrupt chain): a segment whose bytes fall outside the heap counts as
absent, and a walk stops after as many segments as the heap holds (a cyclic chain would
hang the firmware).
"""

from __future__ import annotations

from bbzide.vm.heap import (
    CLOSURE,
    ELEM_INDEX,
    ELEM_VALID,
    FLAG1,
    FLAG2,
    FLOAT,
    INT,
    NIL,
    SEG_NEXT,
    SEG_VALID,
    STRING,
    TABLE,
    TYPE_MASK,
    USERDATA,
    VALID,
    Heap,
    HeapFull,
)
from bbzide.vm.kernels import fasttables


def compare(heap: Heap, a: int, b: int) -> int:
    """``bbztype_cmp``: -1/0/1; never an error (spec §D.6)."""
    ta = heap.obj_type(a)
    tb = heap.obj_type(b)
    if ta == NIL or tb == NIL:
        if ta == tb:
            return 0
        return -1 if ta == NIL else 1
    if ta == INT and tb == INT:
        x, y = heap.int_value(a), heap.int_value(b)
    elif (ta == FLOAT and tb in (INT, FLOAT)) or (tb == FLOAT and ta == INT):
        x, y = heap.u16(a), heap.u16(b)
    elif ta == tb and ta in (STRING, TABLE):
        x, y = heap.u16(a), heap.u16(b)
    elif ta == tb == USERDATA:
        x, y = heap.ptr_value(a), heap.ptr_value(b)
    else:
        return -1
    return (x > y) - (x < y)


# ---- tables ---------------------------------------------------------------------------
def table_get(heap: Heap, t: int, k: int) -> int | None:
    """``bbztable_get``: the value index stored under key object ``k``, or None (absent or
    not a table)."""
    if heap.reference:
        return _table_get_reference(heap, t, k)
    v = fasttables.table_lookup(heap.view, t, k, heap.obj_size, heap.elems)
    return None if v < 0 else v


def _segment_in_heap(heap: Heap, seg: int) -> bool:
    """Do segment ``seg``'s bytes lie inside the heap? (A stale or corrupt index may not.)"""
    return (seg + 1) * heap.seg_size <= heap.size


def _object_in_heap(heap: Heap, i: int) -> bool:
    return 0 <= i < heap.size // heap.obj_size


def _table_get_reference(heap: Heap, t: int, k: int) -> int | None:
    """``bbztable_get`` walked in Python (spec §E.6): the chain in order, each segment's
    E slots in order; a valid key comparing equal to ``k`` (``bbztype_cmp`` = 0) wins."""
    if not (_object_in_heap(heap, t) and _object_in_heap(heap, k)) \
            or heap.obj_type(t) != TABLE:
        return None
    seg = heap.u16(t)
    for _ in range(heap.size // heap.seg_size + 1):  # at most every segment once
        if not _segment_in_heap(heap, seg):
            return None
        for slot in range(heap.elems):
            key = heap.word(seg, slot)
            if key & ELEM_VALID and _object_in_heap(heap, key & ELEM_INDEX) \
                    and compare(heap, key & ELEM_INDEX, k) == 0:
                return heap.word(seg, slot + heap.elems) & ELEM_INDEX
        seg = heap.seg_next(seg)
        if seg == SEG_NEXT:
            return None
    return None


def table_set(heap: Heap, t: int, k: int, v: int) -> bool:
    """``bbztable_set``; False when not a table. Raises HeapFull when a segment is needed."""
    if heap.obj_type(t) != TABLE:
        return False
    E = heap.elems
    v_is_nil = heap.obj_type(v) == NIL
    first = heap.u16(t)
    seg = first
    prev = -1
    free_seg = -1
    free_slot = -1
    while True:
        match = -1
        for s in range(E):
            kw = heap.word(seg, s)
            if kw & ELEM_VALID:
                if match < 0 and compare(heap, kw & ELEM_INDEX, k) == 0:
                    match = s
            elif free_seg < 0:
                free_seg, free_slot = seg, s
        if match >= 0:
            if not v_is_nil:
                heap.set_word(seg, match + E, v | ELEM_VALID)
                return True
            heap.set_word(seg, match, 0)
            heap.set_word(seg, match + E, 0)
            if not any(heap.word(seg, s) & ELEM_VALID for s in range(E)):
                nxt = heap.seg_next(seg)
                if seg == first:
                    if nxt != SEG_NEXT:
                        heap.set_u16(t, nxt)
                        heap.set_seg_mdata(seg, 0)
                else:
                    heap.set_seg_next(prev, nxt)
                    heap.set_seg_mdata(seg, 0)
            return True
        nxt = heap.seg_next(seg)
        if nxt == SEG_NEXT:
            break
        prev, seg = seg, nxt
    if v_is_nil:
        return True
    if free_seg < 0:
        new = heap.seg_alloc()
        heap.set_seg_next(seg, new)
        free_seg, free_slot = new, 0
    heap.set_word(free_seg, free_slot, k | ELEM_VALID)
    heap.set_word(free_seg, free_slot + E, v | ELEM_VALID)
    return True


def table_items(heap: Heap, t: int) -> list[tuple[int, int]]:
    """(key, value) indices in ``foreach`` order: chain order, slot order."""
    E = heap.elems
    out: list[tuple[int, int]] = []
    for seg in heap.segment_chain(heap.u16(t)):
        for s in range(E):
            kw = heap.word(seg, s)
            if kw & ELEM_VALID:
                out.append((kw & ELEM_INDEX, heap.word(seg, s + E) & ELEM_INDEX))
    return out


def table_size(heap: Heap, t: int) -> int:
    return len(table_items(heap, t))


# ---- darrays --------------------------------------------------------------------------
def is_darray(heap: Heap, d: int) -> bool:
    m = heap.mdata(d)
    return m & TYPE_MASK == TABLE and bool(m & FLAG1)


def darray_new(heap: Heap) -> int:
    d = heap.obj_alloc(TABLE)
    heap.set_mdata(d, (heap.mdata(d) | FLAG1) & ~FLAG2)
    return d


def _last_segment(heap: Heap, d: int) -> int:
    seg = heap.u16(d)
    while True:
        nxt = heap.seg_next(seg)
        if nxt == SEG_NEXT:
            return seg
        seg = nxt


def darray_push(heap: Heap, d: int, v: int) -> None:
    n = 2 * heap.elems
    seg = _last_segment(heap, d)
    p = 0
    while p < n and heap.word(seg, p) & ELEM_VALID:
        p += 1
    if p == n:
        new = heap.seg_alloc()
        heap.set_seg_next(seg, new)
        seg, p = new, 0
    heap.set_word(seg, p, v | ELEM_VALID)


def darray_pop(heap: Heap, d: int) -> bool:
    n = 2 * heap.elems
    first = heap.u16(d)
    if heap.seg_next(first) == SEG_NEXT and not heap.word(first, 0) & ELEM_VALID:
        return False
    prev = -1
    seg = first
    while heap.seg_next(seg) != SEG_NEXT:
        prev, seg = seg, heap.seg_next(seg)
    p = 0
    while p < n and heap.word(seg, p) & ELEM_VALID:
        p += 1
    if p > 0:
        heap.set_word(seg, p - 1, heap.word(seg, p - 1) & ~ELEM_VALID)
    else:
        heap.set_word(prev, n - 1, heap.word(prev, n - 1) & ~ELEM_VALID)
        heap.set_seg_mdata(seg, heap.seg_mdata(seg) & ~SEG_VALID)
        heap.set_seg_next(prev, SEG_NEXT)
    return True


def _darray_slot(heap: Heap, d: int, i: int) -> tuple[int, int] | None:
    """(segment, word) of darray ``d``'s element ``i`` (spec §E.7: follow ⌊i/2E⌋ links,
    reached only if the chain is long enough), or None (not a darray, out of the chain)."""
    n = 2 * heap.elems
    if i < 0 or not _object_in_heap(heap, d):
        return None
    mdata = heap.mdata(d)
    if mdata & TYPE_MASK != TABLE or not mdata & FLAG1:
        return None
    seg = heap.u16(d)
    if not _segment_in_heap(heap, seg):
        return None
    for _ in range(i // n):
        seg = heap.seg_next(seg)
        if seg == SEG_NEXT or not _segment_in_heap(heap, seg):
            return None
    return seg, i % n


def darray_get(heap: Heap, d: int, i: int) -> int | None:
    """``bbzdarray_get``: element ``i``'s object index, or None (absent or invalid)."""
    if heap.reference:
        found = _darray_slot(heap, d, i)
        if found is None:
            return None
        word = heap.word(*found)
        return word & ELEM_INDEX if word & ELEM_VALID else None
    v = fasttables.darray_get(heap.view, d, i, heap.obj_size, heap.elems)
    return None if v < 0 else v


def darray_set(heap: Heap, d: int, i: int, v: int) -> bool:
    """``bbzdarray_set``: overwrite an already-valid element (a darray cannot grow so)."""
    if heap.reference:
        found = _darray_slot(heap, d, i)
        if found is None or not heap.word(*found) & ELEM_VALID:
            return False
        heap.set_word(*found, v | ELEM_VALID)
        return True
    return fasttables.darray_set(heap.view, d, i, v, heap.obj_size, heap.elems)


def darray_size(heap: Heap, d: int) -> int:
    """``bbzdarray_size``: count valid elements up to the first invalid one; that element's
    segment gets next := none, unlinking what follows (quirk, spec §E.7). Like the firmware
    it reads the payload as a segment index without checking the type."""
    if not heap.reference:
        return fasttables.darray_size(heap.view, d, heap.obj_size, heap.elems)
    if not _object_in_heap(heap, d):
        return 0
    seg = heap.u16(d)
    count = 0
    for _ in range(heap.size // heap.seg_size + 1):  # at most every segment once
        if not _segment_in_heap(heap, seg):
            return count
        for p in range(2 * heap.elems):
            if not heap.word(seg, p) & ELEM_VALID:
                heap.set_seg_next(seg, SEG_NEXT)
                return count
            count += 1
        seg = heap.seg_next(seg)
        if seg == SEG_NEXT:
            return count
    return count


def darray_elements(heap: Heap, d: int) -> list[int]:
    """Element indices walking while valid (no side effect)."""
    n = 2 * heap.elems
    out: list[int] = []
    seg = heap.u16(d)
    while True:
        for p in range(n):
            w = heap.word(seg, p)
            if not w & ELEM_VALID:
                return out
            out.append(w & ELEM_INDEX)
        nxt = heap.seg_next(seg)
        if nxt == SEG_NEXT:
            return out
        seg = nxt


class CloneFailed(HeapFull):
    """``bbzdarray_clone`` ran out of memory after choosing the new object's slot: the C
    has already written that index to its output (``vm->lsyms`` in ``callc``)."""

    def __init__(self, index: int) -> None:
        super().__init__(index)
        self.index = index


#: mdata of a table object whose first segment could not be allocated (valid, unmarked)
_FRESH_TABLE = TABLE | VALID


def darray_clone(heap: Heap, d: int) -> int:
    """``bbzdarray_clone``; raises CloneFailed(index) when the slot was taken but a segment
    was missing, HeapFull when not even an object slot was free."""
    rtobj = heap.rtobj
    try:
        c = darray_new(heap)
    except HeapFull:
        if heap.rtobj != rtobj:
            raise CloneFailed(rtobj // heap.obj_size) from None
        # first fit took the first free slot, now marked valid with no segment: right after
        # a collection it is the first valid, unmarked, non-permanent table slot
        s = heap.obj_size
        for i in range(heap.reserved, heap.rtobj // s):
            if heap.data[i * s] == _FRESH_TABLE:
                raise CloneFailed(i) from None
        raise
    for e in darray_elements(heap, d):
        try:
            darray_push(heap, c, e)
        except HeapFull:
            raise CloneFailed(c) from None
    return c


def darray_find(heap: Heap, d: int, x: int) -> int:
    elems = darray_elements(heap, d)
    for pos, e in enumerate(elems):
        if heap.is_valid(e) and compare(heap, e, x) == 0:
            return pos
    return len(elems)


def darray_destroy(heap: Heap, d: int) -> None:
    for seg in heap.segment_chain(heap.u16(d)):
        heap.set_seg_mdata(seg, heap.seg_mdata(seg) & ~SEG_VALID)
    heap.set_mdata(d, heap.mdata(d) & ~VALID)


def lambda_alloc(heap: Heap, src: int) -> tuple[int, bool]:
    """``bbzdarray_lambda_alloc``: a reserved-slot darray holding a copy of ``src``.

    Returns (index, ok). index is -1 when no reserved slot is free; ok is False when the
    slot was taken but its first segment could not be allocated (it stays valid). Pushes
    that run out of segments are ignored, as in the firmware.
    """
    for i in range(heap.reserved):
        m = heap.mdata(i)
        if not m & VALID:
            heap.set_mdata(i, ((m | VALID) & ~TYPE_MASK & ~FLAG2 & 0xFF) | TABLE | FLAG1)
            try:
                seg = heap.seg_alloc()
            except HeapFull:
                return i, False
            heap.set_u16(i, seg)
            n = darray_size(heap, src)
            for k in range(n):
                e = darray_get(heap, src, k)
                try:
                    darray_push(heap, i, e if e is not None else 0)
                except HeapFull:
                    pass
            return i, True
    return -1, False


__all__ = [
    "CLOSURE", "compare", "table_get", "table_set", "table_items", "table_size",
    "is_darray", "darray_new", "darray_push", "darray_pop", "darray_get", "darray_set",
    "darray_size", "darray_elements", "darray_clone", "darray_find", "darray_destroy",
    "lambda_alloc", "HeapFull",
]
