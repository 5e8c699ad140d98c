"""Read-only views of a VM for the IDE's heap inspector (never mutates the VM).

Everything is derived from the heap bytes and the VM record, so what the IDE shows is
exactly what the robot's RAM holds. Darray ``size`` is NOT used (it has a side effect);
darray elements are walked directly.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from bbzide.vm.heap import (
    CLOSURE,
    ELEM_INDEX,
    ELEM_VALID,
    FLAG1,
    FLAG2,
    GC_MARK,
    PERMANENT,
    SEG_MARK,
    SEG_NEXT,
    SEG_VALID,
    TABLE,
    TYPE_MASK,
    VALID,
)
from bbzide.vm.vm import VM

TYPE_NAMES = ("nil", "int", "float", "string", "table", "closure", "userdata", "type7")


@dataclass(frozen=True)
class ObjectView:
    index: int
    type: str            # nil int float string table darray closure lambda native userdata
    valid: bool
    permanent: bool
    marked: bool
    mdata: int
    value: object        # int, float bits, string id, first segment, (ref, actrec), pointer


@dataclass(frozen=True)
class SegmentView:
    index: int
    offset: int
    valid: bool
    marked: bool
    next: int | None
    words: tuple[int, ...]


@dataclass
class MemoryView:
    heap_size: int
    rightmost_object_ptr: int   # rtobj (ROP), bytes
    leftmost_segment_ptr: int   # ltseg (LSP), bytes
    used_bytes: int
    free_bytes: int
    peak_bytes: int
    gc_runs: int
    objects: list[ObjectView] = field(default_factory=list)
    segments: list[SegmentView] = field(default_factory=list)


def object_view(vm: VM, i: int) -> ObjectView:
    h = vm.heap
    m = h.mdata(i)
    t = m & TYPE_MASK
    name = TYPE_NAMES[t]
    value: object
    if t == TABLE:
        name = "darray" if m & FLAG1 else "table"
        value = h.u16(i)
    elif t == CLOSURE:
        if m & FLAG2:
            name = "lambda"
            value = (h.data[i * h.obj_size + 1], h.data[i * h.obj_size + 2])
        else:
            name = "native" if m & FLAG1 else "closure"
            value = h.ptr_value(i)
    elif t == 1:
        value = h.int_value(i)
    elif t == 6:
        value = h.ptr_value(i)
    else:
        value = h.u16(i)
    return ObjectView(i, name, bool(m & VALID), bool(m & PERMANENT), bool(m & GC_MARK), m,
                      value)


def memory(vm: VM) -> MemoryView:
    h = vm.heap
    used = h.used_bytes()
    view = MemoryView(h.size, h.rtobj, h.ltseg, used, h.size - used, h.peak_used, h.gc_runs)
    view.objects = [object_view(vm, i) for i in range(h.object_count)]
    for j in range(h.segment_count):
        md = h.seg_mdata(j)
        nxt = md & SEG_NEXT
        view.segments.append(SegmentView(
            j, h.seg_offset(j), bool(md & SEG_VALID), bool(md & SEG_MARK),
            None if nxt == SEG_NEXT else nxt,
            tuple(h.word(j, k) for k in range(2 * h.elems))))
    return view


def table_contents(vm: VM, t: int) -> list[tuple[int, int]]:
    """(key, value) heap indices of a table, or (position, value) of a darray."""
    h = vm.heap
    out: list[tuple[int, int]] = []
    seen = 0
    seg = h.u16(t)
    darray = bool(h.mdata(t) & FLAG1)
    pos = 0
    while seen <= h.size // h.seg_size:
        seen += 1
        if darray:
            for k in range(2 * h.elems):
                w = h.word(seg, k)
                if w & ELEM_VALID:
                    out.append((pos, w & ELEM_INDEX))
                pos += 1
        else:
            for k in range(h.elems):
                kw = h.word(seg, k)
                if kw & ELEM_VALID:
                    out.append((kw & ELEM_INDEX, h.word(seg, k + h.elems) & ELEM_INDEX))
        nxt = h.seg_next(seg)
        if nxt == SEG_NEXT:
            break
        seg = nxt
    return out


def globals_by_name(vm: VM, strings: list[str]) -> dict[str, int]:
    """Global symbol name (from the program's string table) → value heap index."""
    out: dict[str, int] = {}
    for k, v in table_contents(vm, vm.gsyms):
        sid = vm.heap.u16(k)
        out[strings[sid] if sid < len(strings) else f"#{sid}"] = v
    return out


@dataclass(frozen=True)
class FrameView:
    return_pc: int
    saved_lsyms: int
    saved_blockptr: int
    base: int


def stack_frames(vm: VM) -> list[FrameView]:
    """Call frames from the innermost: [return pc][old lsyms][old blockptr] at blockptr."""
    frames = []
    bp = vm.blockptr
    h = vm.heap
    while bp >= 2 and len(frames) < vm.stack_size:
        frames.append(FrameView(h.int_value(vm.stack[bp - 2]), vm.stack[bp - 1],
                                h.int_value(vm.stack[bp]), bp))
        nbp = h.int_value(vm.stack[bp])
        if nbp >= bp:
            break
        bp = nbp
    return frames


def last_error(vm: VM) -> tuple[str, int] | None:
    """(error name, pc of the failing instruction) or None."""
    if vm.state.name != "ERROR":
        return None
    return vm.error.name, vm.pc
