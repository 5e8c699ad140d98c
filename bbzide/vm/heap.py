"""The BittyBuzz heap: one fixed byte buffer shared by objects and table segments.

Layout (spec §E.3)::

    data[0 .. size-1]
     [obj 0 .. obj R-1]   reserved lambda activation records
     [obj R .. obj n-1]   objects, growing right  -> rtobj = n*S  (BittyBuzz "rtobj", ROP)
     ...... free ......
     [seg k-1] ... [seg 0] segments, growing left -> ltseg = size - k*G  ("ltseg", LSP)

The model is byte-faithful: every write the firmware does is done here and no other, so
stale bytes survive exactly as on the robot (spec §E.2, corpus README §4 "Stale bytes").
Object byte 0 is the metadata (type bits 0-2, valid 3, permanent 4, GC mark 5, type flags
6-7); the payload follows little-endian. A segment is E u16 keys, E u16 values, u16 mdata.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from bbzide.vm.heap_layout import (  # noqa: F401 - the layout's names, re-exported
    CLOSURE,
    ELEM_INDEX,
    ELEM_VALID,
    FLAG1,
    FLAG2,
    FLOAT,
    GC_MARK,
    INT,
    NIL,
    NO_ACTREC,
    PERMANENT,
    SEG_MARK,
    SEG_NEXT,
    SEG_VALID,
    STRING,
    TABLE,
    TYPE_MASK,
    USERDATA,
    VALID,
)
from bbzide.vm.kernels import fastgc
from bbzide.vm.profiles import Profile

#: byte translation table of an object's metadata byte: 1 for a free slot (VALID clear)
_INVALID_FLAG = bytes(int(not b & VALID) for b in range(256))


class HeapFull(Exception):
    """An allocation found no room (the VM turns it into BBZVM_ERROR_MEM)."""


class Heap:
    """The heap buffer and its two pointers (``rtobj``/``ltseg`` are byte offsets)."""

    def __init__(self, profile: Profile, reference: bool = False) -> None:
        self.profile = profile
        #: the reference mode: first-fit scans and table reads in plain Python (this file,
        #: tables.py), not the compiled kernels; set by the VM with its ``stress_gc``
        self.reference = reference
        self.size = profile.heap_size
        self.obj_size = profile.obj_size
        self.seg_size = profile.tseg_size
        self.elems = profile.elems_per_tseg
        self.reserved = profile.rsv_actrec
        # The firmware's heap is a zero-initialised static array.
        self.data = bytearray(self.size)
        #: the same bytes as a numpy array: what the compiled kernels take (one numba
        #: specialisation for every caller instead of one for bytearray and one for arrays)
        self.view = np.frombuffer(self.data, np.uint8)
        self.rtobj = self.reserved * self.obj_size
        self.ltseg = self.size
        self.peak_used = 0
        self.gc_runs = 0
        #: metadata byte the slot returned by the last obj_alloc held before it (the fast
        #: VM's skip rule for new leaves needs to know whether the marker reached it)
        self.prior_mdata = 0
        #: the last compiled collection was not a fixed point of the collector
        #: (``fastgc.UNSETTLED``): the fast mode must run the next one, not skip it
        self.unsettled = False
        #: a compiled collection of this heap stopped at the depth limit
        #: (``fastgc.TRUNCATED``): from then on every collection leaves it unsettled
        self.truncated = False
        #: how the last compiled collection marked (fastgc.collect's info/traversed)
        nobj = self.objects = self.size // self.obj_size  # object slots the heap can hold
        self.gc_info = np.zeros(nobj, np.uint8)
        self.gc_traversed = np.zeros(nobj + 1, np.int32)

    # ---- whole-heap operations -------------------------------------------------------
    def clear(self) -> None:
        """``bbzheap_clear``: reset both pointers, zero bytes 0..(R-1)*S inclusive only."""
        self.rtobj = self.reserved * self.obj_size
        self.ltseg = self.size
        end = (self.reserved - 1) * self.obj_size + 1
        self.data[0:end] = bytes(end)

    @property
    def object_count(self) -> int:
        """Number of object slots below rtobj (reserved ones included)."""
        return self.rtobj // self.obj_size

    @property
    def segment_count(self) -> int:
        return (self.size - self.ltseg) // self.seg_size

    def used_bytes(self) -> int:
        return self.rtobj + (self.size - self.ltseg)

    def _note_usage(self) -> None:
        used = self.rtobj + (self.size - self.ltseg)
        if used > self.peak_used:
            self.peak_used = used

    # ---- objects ----------------------------------------------------------------------
    def mdata(self, i: int) -> int:
        return self.data[i * self.obj_size]

    def set_mdata(self, i: int, value: int) -> None:
        self.data[i * self.obj_size] = value

    def obj_type(self, i: int) -> int:
        return self.data[i * self.obj_size] & TYPE_MASK

    def is_valid(self, i: int) -> bool:
        return bool(self.data[i * self.obj_size] & VALID)

    def u16(self, i: int) -> int:
        """Payload bytes 1-2 as an unsigned 16-bit value."""
        o = i * self.obj_size
        d = self.data
        return d[o + 1] | (d[o + 2] << 8)

    def set_u16(self, i: int, value: int) -> None:
        o = i * self.obj_size
        self.data[o + 1] = value & 0xFF
        self.data[o + 2] = (value >> 8) & 0xFF

    def int_value(self, i: int) -> int:
        v = self.u16(i)
        return v - 0x10000 if v & 0x8000 else v

    def set_int(self, i: int, value: int) -> None:
        self.set_u16(i, value & 0xFFFF)

    def ptr_value(self, i: int) -> int:
        o = i * self.obj_size + 1
        return int.from_bytes(self.data[o:o + self.obj_size - 1], "little")

    def set_ptr(self, i: int, value: int) -> None:
        """Write a pointer-sized payload (C closure, native closure pc, userdata)."""
        o = i * self.obj_size + 1
        n = self.obj_size - 1
        self.data[o:o + n] = (value & ((1 << (8 * n)) - 1)).to_bytes(n, "little")

    def obj_alloc(self, typ: int, string_id: int = 0) -> int:
        """``bbzheap_obj_alloc`` (spec §E.5): first free slot from R, string dedupe, grow.

        Raises :class:`HeapFull`. A table whose first segment cannot be allocated is left
        valid (garbage) and HeapFull is raised, as the firmware does.
        """
        d = self.data
        s = self.obj_size
        if self.reference:
            found = self._first_free_object(typ, string_id)
        else:  # the same scan compiled: fastgc.first_free
            found = fastgc.first_free(self.view, self.rtobj, s, self.reserved, typ, string_id)
        if found < -1:
            self.prior_mdata = d[(-2 - found) * s]
            return -2 - found
        if found < 0:
            if self.rtobj + s > self.ltseg:
                raise HeapFull
            found = self.rtobj // s
            self.rtobj += s
            self._note_usage()
        o = found * s
        self.prior_mdata = d[o]
        d[o] = typ | VALID
        if typ == TABLE:
            seg = self.seg_alloc()
            d[o + 1] = seg & 0xFF
            d[o + 2] = seg >> 8
        elif typ == CLOSURE:
            d[o + 2] = NO_ACTREC
        return found

    def _first_free_object(self, typ: int, string_id: int) -> int:
        """``bbzheap_obj_alloc``'s scan (spec §E.5): the first invalid slot from R below
        rtobj, or -1; for a STRING, a valid string of the same id met before it is returned
        as ``-2 - index`` (deduplication)."""
        d = self.data
        s = self.obj_size
        if typ != STRING:  # no deduplication: the first metadata byte without VALID
            found = d[self.reserved * s:self.rtobj:s].translate(_INVALID_FLAG).find(1)
            return -1 if found < 0 else self.reserved + found
        for i in range(self.reserved, self.rtobj // s):
            mdata = d[i * s]
            if not mdata & VALID:
                return i
            if typ == STRING and mdata & TYPE_MASK == STRING \
                    and d[i * s + 1] | (d[i * s + 2] << 8) == string_id & 0xFFFF:
                return -2 - i
        return -1

    def new_int(self, value: int) -> int:
        i = self.obj_alloc(INT)
        self.set_u16(i, value & 0xFFFF)
        return i

    def new_float(self, bits: int) -> int:
        i = self.obj_alloc(FLOAT)
        self.set_u16(i, bits)
        return i

    def new_string(self, string_id: int) -> int:
        i = self.obj_alloc(STRING, string_id)
        self.set_u16(i, string_id)
        return i

    def new_table(self) -> int:
        return self.obj_alloc(TABLE)

    def new_closure(self, value: int) -> int:
        """``bbzclosure_new``: a C closure (or native, after the caller sets FLAG1)."""
        i = self.obj_alloc(CLOSURE)
        self.set_ptr(i, value)
        return i

    def new_userdata(self, value: int) -> int:
        i = self.obj_alloc(USERDATA)
        self.set_ptr(i, value)
        return i

    # ---- segments ---------------------------------------------------------------------
    def seg_offset(self, j: int) -> int:
        return self.size - (j + 1) * self.seg_size

    def seg_mdata(self, j: int) -> int:
        o = self.size - (j + 1) * self.seg_size + 4 * self.elems
        return self.data[o] | (self.data[o + 1] << 8)

    def set_seg_mdata(self, j: int, value: int) -> None:
        o = self.size - (j + 1) * self.seg_size + 4 * self.elems
        self.data[o] = value & 0xFF
        self.data[o + 1] = (value >> 8) & 0xFF

    def seg_next(self, j: int) -> int:
        return self.seg_mdata(j) & SEG_NEXT

    def set_seg_next(self, j: int, nxt: int) -> None:
        self.set_seg_mdata(j, (self.seg_mdata(j) & ~SEG_NEXT) | (nxt & SEG_NEXT))

    def word(self, j: int, k: int) -> int:
        """Element word k (0..2E-1) of segment j: keys are 0..E-1, values E..2E-1."""
        o = self.size - (j + 1) * self.seg_size + 2 * k
        return self.data[o] | (self.data[o + 1] << 8)

    def set_word(self, j: int, k: int, value: int) -> None:
        o = self.size - (j + 1) * self.seg_size + 2 * k
        self.data[o] = value & 0xFF
        self.data[o + 1] = (value >> 8) & 0xFF

    def seg_alloc(self) -> int:
        """``bbzheap_tseg_alloc``: first invalid segment slot, else grow left."""
        if self.reference:
            found = self._first_free_segment()
        else:  # the same scan compiled: fastgc.first_free_segment
            found = fastgc.first_free_segment(self.view, self.ltseg, self.size, self.seg_size,
                                              self.elems)
        if found < 0:
            if self.ltseg - self.seg_size < self.rtobj:
                raise HeapFull
            found = (self.size - self.ltseg) // self.seg_size
            self.ltseg -= self.seg_size
            self._note_usage()
        o = self.seg_offset(found)
        g = self.seg_size
        self.data[o:o + g - 2] = bytes(g - 2)
        self.data[o + g - 2] = 0xFF
        self.data[o + g - 1] = 0xFF
        return found

    def _first_free_segment(self) -> int:
        """``bbzheap_tseg_alloc``'s scan (spec §E.5): the first invalid segment slot, or -1."""
        for j in range(self.segment_count):
            if not self.seg_mdata(j) & SEG_VALID:
                return j
        return -1

    def segment_chain(self, first: int) -> list[int]:
        """Segment indices of a table chain starting at ``first``."""
        chain = [first]
        nxt = self.seg_next(first)
        limit = self.size // self.seg_size
        # a next index whose bytes lie outside the heap ends the chain (see gc.py)
        while nxt != SEG_NEXT and (nxt + 1) * self.seg_size <= self.size \
                and len(chain) <= limit:
            chain.append(nxt)
            nxt = self.seg_next(nxt)
        return chain

    # ---- snapshots --------------------------------------------------------------------
    def snapshot(self) -> tuple[bytes, int, int, int, int, bool, bool]:
        return (bytes(self.data), self.rtobj, self.ltseg, self.peak_used, self.gc_runs,
                self.unsettled, self.truncated)

    def restore(self, snap: tuple[Any, ...]) -> None:
        """Take over a `snapshot()`, or one of the five values a snapshot held before it held
        the two flags (neither set then)."""
        data, self.rtobj, self.ltseg, self.peak_used, self.gc_runs = snap[:5]
        self.unsettled, self.truncated = snap[5:] or (False, False)
        self.data[:] = data
