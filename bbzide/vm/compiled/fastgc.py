"""Compiled heap kernels for the fast VM mode: the collector and the first-fit scans.

The reference collector (:mod:`bbzide.vm.gc`) is a line-by-line transcription of
``bbzheap_gc``: a recursive ``mark`` with a depth counter, run before every instruction.
Written in Python it costs ~80 µs a run, so it is the whole cost of the VM. This module
runs *the same algorithm* (same roots, same order, same depth rule, same sweep and pointer
retreat) as flat loops over the heap ``bytearray`` with no per-object Python objects, so
that numba can compile it to machine code (~1 µs a run). The recursion becomes an explicit
frame stack: one frame per table being marked (its current segment and word), at most
``gcmark_depth`` deep, which reproduces the reference's first-visit-wins order exactly
(a frame resumes its word loop after the child returns, as the C ``for`` loop does).

Equality with the reference is by test, not by argument alone:
``tests/vm/test_fast_vm_equivalence.py`` runs the corpus and generated programs in both
modes and compares every observable state. Without numba (import failure) the same
functions run as plain Python — correct, only slower.

Out-of-range indices (a stale table payload, a corrupt chain) would be undefined behaviour
in C; both collectors treat a segment whose bytes fall outside the heap as the end of its
chain and ignore an object index past the heap, and stop a chain after as many segments as
the heap can hold (a cyclic chain would hang the firmware).
"""

from __future__ import annotations

import hashlib
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

#: What the kernels' machine code is made of: their own sources and the model's layouts and
#: constants they import (numba freezes module-level constants into the code it compiles).
_MODEL_LAYOUTS = ("heap_layout.py", "message_layout.py", "packed_messages.py", "states.py")


def kernel_sources() -> list[Path]:
    """Every source the kernels are compiled from: this folder's modules and the model's
    layouts they read (the Makefile's KERNEL_SOURCES lists the same files)."""
    here = Path(__file__).parent
    return sorted(here.glob("*.py")) + [here.parent / name for name in _MODEL_LAYOUTS]


def _kernel_sources_digest() -> str:
    """A digest of every source the kernels are compiled from. numba's disk cache checks
    only the source file of each function it loads: a kernel that calls one from another file
    (every kernel calls into fastgc, most into fastloop) or reads another module's constant
    would keep its old machine code after that file changed. So the cache lives in a folder
    named by this digest: any change to those sources starts a new cache, and every kernel is
    compiled again, once."""
    digest = hashlib.sha256()
    for source in kernel_sources():
        digest.update(source.name.encode() + b"\0" + source.read_bytes())
    return digest.hexdigest()[:16]


try:  # numba is optional: the kernels are plain Python that numba compiles when present
    from numba import config as _numba_config
    from numba import njit as _njit
    from numba.core.types import unliteral as _unliteral

    # read by each kernel's cache when `_compile` creates it, below and in the other kernels
    _numba_config.CACHE_DIR = str(Path(__file__).parent / "__pycache__"
                                  / f"kernels-{_kernel_sources_digest()}")

    def _compile(fn: Callable[..., Any], owning: bool = False) -> Callable[..., Any]:
        """numba's dispatcher for `fn`, typed by its arguments' types only, never their values,
        and without numba's reference counting (NRT) unless `owning` (:func:`_compile_owning`).

        A kernel called from another with a constant argument (`_obj_alloc(..., 1, 0)`) would
        otherwise be compiled once more for every distinct constant (numba types a constant
        as a `Literal`): the set-up compiled 189 machine codes instead of 119, a quarter more
        time (scripts/warm_kernels.py: 88 s against 65 s), and the swarm and VM benchmarks,
        run alternately, are as fast with one code per kernel.
        `get_call_template` is where numba resolves a call made from compiled code.

        A kernel without NRT neither counts references to the arrays it is passed nor may it
        make one (numba refuses to compile an `np.empty`, or an array returned to it, there):
        the kernels are many small functions called per instruction, each of which counted
        its array arguments in and out; without that the kernel part of a step of 1,000
        Kilobots took 15.2-15.4 ms instead of 18.2-19.9 (three alternating runs)."""
        dispatcher = _njit(cache=True, nogil=True, _nrt=owning)(fn)
        typed_by_values = dispatcher.get_call_template

        def get_call_template(args: tuple[Any, ...], kws: dict[str, Any]) -> Any:
            return typed_by_values(tuple(_unliteral(arg) for arg in args),
                                   {name: _unliteral(arg) for name, arg in kws.items()})

        dispatcher.get_call_template = get_call_template
        return dispatcher

    def _compile_owning(fn: Callable[..., Any]) -> Callable[..., Any]:
        """:func:`_compile` for a kernel that owns arrays: it makes one (its scratch space, a
        view it returns) or is handed one a kernel made; numba counts its references."""
        return _compile(fn, owning=True)

    _i = np.int64  # numba's int() of a uint8 is unsigned: mixing it with int64 gives floats
    COMPILED = True
except ImportError:  # pragma: no cover - exercised only on machines without numba
    def _compile(fn: Callable[..., Any], owning: bool = False) -> Callable[..., Any]:
        return fn

    _compile_owning = _compile
    _i = int
    COMPILED = False

# Metadata bits (heap.py), repeated as literals so the compiled code sees constants.
_TYPE_MASK = 0x07
_INT, _FLOAT = 1, 2
_TABLE = 4
_CLOSURE = 5
_STRING = 3
_VALID = 0x08
_PERMANENT = 0x10
_GC_MARK = 0x20
_FLAG2 = 0x80
_NO_ACTREC = 0xFF
_SEG_MARK_HI = 0x40   # SEG_MARK (bit 14) in the high byte of the segment mdata word
_SEG_VALID_HI = 0x80  # SEG_VALID (bit 15) in the high byte
_SEG_NEXT = 0x3FFF
#: flag in a collect() ``info`` entry: first marked from a permanent root (depth < 64)
PERMANENT_PHASE = 64
#: ``info`` value of an int or float whose one reference is a slot of a table (a global's,
#: or any table's) walked from the permanent roots: a collection gives it to a number it
#: first marks as such a table's leaf, and takes it back if it meets the number again (the
#: marker meets every reference a reachable object has, unless the depth limit stopped a
#: walk; the heap is then ``TRUNCATED``, and no skip rule applies any more). The skip rules
#: keep it true between collections (``fastloop``: a push takes it back; overwriting that
#: slot frees the number, as the skipped collection would).
OWNED = 1 + PERMANENT_PHASE
#: flag in :func:`collect_with`'s result: the collection is not a fixed point of itself, so
#: the next one must run. It marked an object at or above the object end it left (an invalid
#: slot a stale reference reached, past which the end then retreated, or one already above
#: it): a second collection does not clear that object's mark bit (step 1 clears below the
#: end only), so it does not walk the object again, and the segment marks and children that
#: object alone reached come out different (a nest deeper than ``gcmark_depth`` leaves such
#: references).
UNSETTLED = 1 << 32
#: flag in :func:`collect_with`'s result: the depth limit stopped the marker short of an
#: unmarked object (a child of a table at ``gcmark_depth``, or a lambda's record past it),
#: which the sweep may free while that table still refers to it. From then on a freed slot
#: may have a word pointing at it whose collection will mark what is allocated there, so no
#: "fresh object" is sure to be unreferenced: the heap stays unsettled for the fast mode.
TRUNCATED = 1 << 33
#: :func:`collect_with`'s result from this bit up: the lowest object slot the sweep left
#: invalid (from ``reserved``; the object end's slot when none is), below which every slot is
#: valid, so the allocations after a collection need not scan the live objects for a free
#: one (an M300 drone's collection is followed by allocations that scanned ~40 slots each)
VALID_BELOW_SHIFT = 34


@_compile_owning
def collect(d: bytearray, stack: Any, top: int, rtobj: int, ltseg: int, info: Any,
            traversed: Any, size: int, s: int, g: int, elems: int, reserved: int,
            limit: int) -> int:
    """One ``bbzheap_gc`` on ``d``; ``stack[0..top]`` are the roots (an int buffer).
    See :func:`collect_with` (this one allocates its frame stack)."""
    frames = np.empty((4, limit + 2), np.int64)
    return collect_with(d, stack, top, rtobj, ltseg, info, traversed, frames, size, s, g,
                        elems, reserved, limit)


@_compile
def collect_with(d: bytearray, stack: Any, top: int, rtobj: int, ltseg: int, info: Any,
                 traversed: Any, frames: Any, size: int, s: int, g: int, elems: int,
                 reserved: int, limit: int) -> int:
    """One ``bbzheap_gc`` on ``d``; ``stack[0..top]`` are the roots (an int buffer);
    ``frames``: a 4 x (limit + 2) int64 scratch array for the mark stack (the compiled
    instruction kernel passes one it keeps, saving an allocation per collection).

    Also records how it marked, for the VM's skip rules: ``info[x]`` =
    the depth at which x was first marked (0: not marked) plus ``PERMANENT_PHASE`` if that
    happened while marking from the permanent roots; ``traversed[1..traversed[0]]`` = the
    tables whose elements were visited (first marked at a depth below the limit).
    Returns the new ``rtobj * 65536 + ltseg``, plus :data:`UNSETTLED` when a second
    collection would not be a no-op, :data:`TRUNCATED` when the depth limit stopped it and
    the lowest invalid slot shifted by :data:`VALID_BELOW_SHIFT` (numba returns one int
    fastest).
    """
    n = rtobj // s
    k = (size - ltseg) // g
    mo = 4 * elems
    nwords = 2 * elems
    max_chain = size // g + 1
    # the segments' words as little-endian u16s, one load each (-8 % per collection): a
    # segment starts at size - (seg + 1) * g, g even, so at an even offset from `odd`
    odd = size & 1
    words = d[odd:size].view(np.uint16)
    # 1. clear marks (segments k-1..0, objects n-1..0)
    for j in range(k):
        d[size - (j + 1) * g + mo + 1] &= 0xFF ^ _SEG_MARK_HI
    for i in range(n):
        d[i * s] &= 0xFF ^ _GC_MARK
    info[:] = 0
    traversed[0] = 0
    phase = PERMANENT_PHASE
    # frames of the explicit mark stack: segment, next word, depth, segments walked
    f_seg = frames[0]
    f_word = frames[1]
    f_depth = frames[2]
    f_walk = frames[3]
    nobj = size // s
    nroots = n + top + 1
    highest = -1  # the highest object index this collection marked
    truncated = False
    for r in range(nroots):
        # 2. permanent objects from n-1 down, 3. stack from top down
        if r < n:
            x = n - 1 - r
            if not _i(d[x * s]) & _PERMANENT:
                continue
        else:
            x = _i(stack[top - (r - n)])
            phase = 0
        # mark(x) at depth 2, then run frames until this root is done
        depth = 2
        fp = -1
        while True:
            # enter mark(x) at `depth` (a lambda's actrec is entered in this same loop)
            unmarked = 0 <= x < nobj and not _i(d[x * s]) & _GC_MARK
            if unmarked and depth > limit:
                truncated = True
            if not unmarked and 0 <= x < nobj and info[x] == OWNED:
                info[x] = depth + phase  # a second reference: a plain leaf
            if unmarked and depth <= limit:
                o = x * s
                d[o] |= _GC_MARK
                info[x] = depth + phase
                if x > highest:
                    highest = x
                m = _i(d[o])
                t = m & _TYPE_MASK
                if t == _TABLE:
                    if depth < limit:
                        traversed[0] += 1
                        traversed[traversed[0]] = x
                    seg = _i(d[o + 1]) | (_i(d[o + 2]) << 8)
                    if 0 <= seg and (seg + 1) * g <= size:
                        fp += 1
                        f_seg[fp] = seg
                        f_word[fp] = 0
                        f_depth[fp] = depth
                        f_walk[fp] = 1
                        d[size - (seg + 1) * g + mo + 1] |= _SEG_MARK_HI
                elif t == _CLOSURE and m & _FLAG2 and _i(d[o + 2]) != _NO_ACTREC:
                    x = _i(d[o + 2])
                    depth += 1
                    continue
            # resume the innermost frame: next valid word to mark, or next segment
            x = -1
            while fp >= 0:
                seg = f_seg[fp]
                base = size - (seg + 1) * g
                w = f_word[fp]
                fd = f_depth[fp]
                first_word = (base - odd) >> 1
                if fd >= limit:
                    # mark(y) would be past the depth limit: it only tells whether it stopped
                    while w < nwords:
                        word = _i(words[first_word + w])
                        w += 1
                        if word & 0x8000:
                            y = word & 0x7FFF
                            if y < nobj and not _i(d[y * s]) & _GC_MARK:
                                truncated = True
                            elif y < nobj and info[y] == OWNED:
                                info[y] = fd + 1 + phase  # a second reference
                else:
                    leaf_info = fd + 1 + phase
                    while w < nwords:
                        word = _i(words[first_word + w])
                        w += 1
                        if word & 0x8000:
                            y = word & 0x7FFF
                            if y < nobj:
                                o = y * s
                                my = _i(d[o])
                                if not my & _GC_MARK:
                                    ty = my & _TYPE_MASK
                                    if ty != _TABLE and not (
                                            ty == _CLOSURE and my & _FLAG2
                                            and _i(d[o + 2]) != _NO_ACTREC):
                                        # a leaf: mark(y) at depth fd + 1 marks it and
                                        # returns, done here without leaving the word loop
                                        # (most children are leaves: -25 % per collection)
                                        d[o] = my | _GC_MARK
                                        if phase and (ty == _INT or ty == _FLOAT):
                                            info[y] = OWNED  # until met again
                                        else:
                                            info[y] = leaf_info
                                        highest = max(highest, y)
                                        continue
                                    x = y
                                    break
                                if info[y] == OWNED:
                                    info[y] = leaf_info  # a second reference
                f_word[fp] = w
                if x >= 0:
                    depth = fd + 1
                    break
                nxt = (_i(d[base + mo]) | (_i(d[base + mo + 1]) << 8)) & _SEG_NEXT
                if nxt == _SEG_NEXT or (nxt + 1) * g > size or f_walk[fp] >= max_chain:
                    fp -= 1
                    continue
                f_seg[fp] = nxt
                f_word[fp] = 0
                f_walk[fp] += 1
                d[size - (nxt + 1) * g + mo + 1] |= _SEG_MARK_HI
            if x < 0:
                break
    # 4. sweep n-1 down to 0
    valid_below = n
    for i in range(n - 1, -1, -1):
        o = i * s
        m = _i(d[o])
        if not m & _VALID:
            if i >= reserved:
                valid_below = i
        elif not m & _GC_MARK:
            d[o] = m & (0xFF ^ _VALID)
            if i >= reserved:
                valid_below = i
            if m & _TYPE_MASK == _TABLE:
                seg = _i(d[o + 1]) | (_i(d[o + 2]) << 8)
                if (seg + 1) * g <= size and \
                        not _i(d[size - (seg + 1) * g + mo + 1]) & _SEG_MARK_HI:
                    walked = 0
                    while True:
                        mb = size - (seg + 1) * g + mo
                        d[mb + 1] &= 0xFF ^ _SEG_VALID_HI
                        walked += 1
                        nxt = (_i(d[mb]) | (_i(d[mb + 1]) << 8)) & _SEG_NEXT
                        if nxt == _SEG_NEXT or (nxt + 1) * g > size or walked >= max_chain:
                            break
                        seg = nxt
    # 5-6. retreat both pointers over invalid slots
    low = reserved * s
    while rtobj > low and not _i(d[rtobj - s]) & _VALID:
        rtobj -= s
    while ltseg < size and not _i(d[ltseg + mo + 1]) & _SEG_VALID_HI:
        ltseg += g
    result = (rtobj << 16) | ltseg | (valid_below << VALID_BELOW_SHIFT)
    if highest * s >= rtobj:
        result |= UNSETTLED
    if truncated:
        result |= TRUNCATED
    return result


@_compile
def first_free(d: bytearray, rtobj: int, s: int, reserved: int, typ: int, sid: int) -> int:
    """``bbzheap_obj_alloc``'s scan: the first invalid slot from R, or -1 if none below rtobj.

    For a STRING, a valid string with id ``sid`` met before the first free slot is returned
    as ``-2 - index`` (deduplication).
    """
    n = rtobj // s
    lo = sid & 0xFF
    hi = (sid >> 8) & 0xFF
    for i in range(reserved, n):
        o = i * s
        m = _i(d[o])
        if not m & _VALID:
            return i
        if typ == _STRING and m & _TYPE_MASK == _STRING and _i(d[o + 1]) == lo \
                and _i(d[o + 2]) == hi:
            return -2 - i
    return -1


@_compile
def first_free_segment(d: bytearray, ltseg: int, size: int, g: int, elems: int) -> int:
    """``bbzheap_tseg_alloc``'s scan: the first invalid segment slot, or -1."""
    k = (size - ltseg) // g
    mo = 4 * elems
    for j in range(k):
        if not _i(d[size - (j + 1) * g + mo + 1]) & _SEG_VALID_HI:
            return j
    return -1

