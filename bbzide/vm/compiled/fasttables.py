"""Compiled table and darray reads (``bbztable_get``, ``bbzdarray_get/set/size``).

These four routines run for nearly every instruction (global lookups walk ``gsyms``, every
local access walks the activation-record darray), and written with one Python call per heap
word they were a third of the interpreter's time. Here they are flat loops over the heap
``bytearray``, compiled by numba when it is installed (see :mod:`fastgc`), and
:mod:`bbzide.vm.tables` calls them in the fast mode; the reference mode walks the same
chains in plain Python there, so the two modes share no code. Each mirrors the routine named
in its docstring word for word; the geometry comes from the heap itself (``size = len(d)``,
``G = 4E + 2``).

Where C would read outside the heap (a stale payload, a corrupt chain) these stop: a
segment whose bytes fall outside the heap counts as absent, and a walk stops after as many
segments as the heap holds (a cyclic chain would hang the firmware).
"""

from __future__ import annotations

from bbzide.vm.compiled.fastgc import _compile, _i

_NIL = 0
_INT = 1
_FLOAT = 2
_STRING = 3
_TABLE = 4
_USERDATA = 6
_DARRAY = 0x40       # FLAG1 on a table
_VALID_WORD = 0x8000
_NO_NEXT = 0x3FFF


@_compile
def table_lookup(d: bytearray, t: int, k: int, s: int, elems: int) -> int:
    """``bbztable_get``: the value index under key object ``k``; -1 if absent/not a table.

    A key matches when ``bbztype_cmp(key, k) == 0`` (spec §D.6). ``k``'s type and payload
    are read once, before the walk, and each valid key is compared with them in the loop
    (a call per key was a tenth of a Kilobot's kernel time), by the cases that can compare
    equal: nil with nil; int or float with int or float, same 16 payload bits; string with
    string and table with table, same payload; userdata with userdata, every payload byte.
    A closure (or a key index past the heap) equals nothing."""
    size = len(d)
    g = 4 * elems + 2
    nobj = size // s
    if not 0 <= t < nobj or _i(d[t * s]) & 7 != _TABLE:
        return -1
    if not 0 <= k < nobj:
        return -1
    ok = k * s
    tk = _i(d[ok]) & 7
    uk = _i(d[ok + 1]) | (_i(d[ok + 2]) << 8)
    numeric = tk == _INT or tk == _FLOAT
    if not (tk == _NIL or numeric or tk == _STRING or tk == _TABLE or tk == _USERDATA):
        return -1
    seg = _i(d[t * s + 1]) | (_i(d[t * s + 2]) << 8)
    for _ in range(size // g + 1):
        if (seg + 1) * g > size:
            return -1
        base = size - (seg + 1) * g
        for slot in range(elems):
            kw = _i(d[base + 2 * slot]) | (_i(d[base + 2 * slot + 1]) << 8)
            a = kw & 0x7FFF
            if not kw & _VALID_WORD or a >= nobj:
                continue
            oa = a * s
            ta = _i(d[oa]) & 7
            if tk == _NIL:
                hit = ta == _NIL
            elif numeric:
                hit = (ta == _INT or ta == _FLOAT) and \
                    (_i(d[oa + 1]) | (_i(d[oa + 2]) << 8)) == uk
            elif tk == _USERDATA:
                hit = ta == _USERDATA
                for j in range(1, s):
                    if d[oa + j] != d[ok + j]:
                        hit = False
                        break
            else:
                hit = ta == tk and (_i(d[oa + 1]) | (_i(d[oa + 2]) << 8)) == uk
            if hit:
                vo = base + 2 * (slot + elems)
                return (_i(d[vo]) | (_i(d[vo + 1]) << 8)) & 0x7FFF
        seg = (_i(d[base + 4 * elems]) | (_i(d[base + 4 * elems + 1]) << 8)) & _NO_NEXT
        if seg == _NO_NEXT:
            return -1
    return -1


@_compile
def _darray_word_offset(d: bytearray, a: int, i: int, s: int, elems: int) -> int:
    """Byte offset of darray ``a``'s element ``i`` (walk ⌊i/2E⌋ links), or -1."""
    size = len(d)
    g = 4 * elems + 2
    n = 2 * elems
    if i < 0 or not 0 <= a < size // s:
        return -1
    m = _i(d[a * s])
    if m & 7 != _TABLE or not m & _DARRAY:
        return -1
    seg = _i(d[a * s + 1]) | (_i(d[a * s + 2]) << 8)
    if (seg + 1) * g > size:
        return -1
    for _ in range(i // n):
        base = size - (seg + 1) * g
        seg = (_i(d[base + 4 * elems]) | (_i(d[base + 4 * elems + 1]) << 8)) & _NO_NEXT
        if seg == _NO_NEXT or (seg + 1) * g > size:
            return -1
    return size - (seg + 1) * g + 2 * (i % n)


@_compile
def darray_get(d: bytearray, a: int, i: int, s: int, elems: int) -> int:
    """``bbzdarray_get``: element ``i``'s object index, or -1."""
    o = _darray_word_offset(d, a, i, s, elems)
    if o < 0:
        return -1
    w = _i(d[o]) | (_i(d[o + 1]) << 8)
    return w & 0x7FFF if w & _VALID_WORD else -1


@_compile
def darray_set(d: bytearray, a: int, i: int, v: int, s: int, elems: int) -> bool:
    """``bbzdarray_set``: overwrite an already-valid element; False otherwise."""
    o = _darray_word_offset(d, a, i, s, elems)
    if o < 0 or not d[o + 1] & 0x80:
        return False
    w = v | _VALID_WORD
    d[o] = w & 0xFF
    d[o + 1] = (w >> 8) & 0xFF
    return True


@_compile
def darray_size(d: bytearray, a: int, s: int, elems: int) -> int:
    """``bbzdarray_size``: valid elements up to the first invalid one; that element's
    segment gets next := none (the firmware's unlinking side effect)."""
    size = len(d)
    g = 4 * elems + 2
    n = 2 * elems
    if not 0 <= a < size // s:
        return 0
    seg = _i(d[a * s + 1]) | (_i(d[a * s + 2]) << 8)
    count = 0
    for _ in range(size // g + 1):
        if (seg + 1) * g > size:
            return count
        base = size - (seg + 1) * g
        mo = base + 4 * elems
        for p in range(n):
            if not d[base + 2 * p + 1] & 0x80:
                d[mo] = 0xFF
                d[mo + 1] = d[mo + 1] | 0x3F
                return count
            count += 1
        seg = (_i(d[mo]) | (_i(d[mo + 1]) << 8)) & _NO_NEXT
        if seg == _NO_NEXT:
            return count
    return count
