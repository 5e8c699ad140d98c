"""Read-only views of a VM (and a Robot) for the IDE's inspector (never mutates anything).

Everything is derived from the heap bytes and the VM record, so what the IDE shows is
exactly what the robot's RAM holds. Darray ``size`` is NOT used (it has a side effect);
darray elements are walked directly.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING

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

if TYPE_CHECKING:
    from bbzide.vm.robot import Robot

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


# ---- runtime records (stigmergy, neighbors, swarms, queues) and the whole robot ---------
@dataclass(frozen=True)
class StigmergyEntryView:
    key: str            # the key's name from the string table (``#sid`` when unknown)
    key_id: int
    value_index: int    # heap index of the stored value
    value: str          # the value as the harness prints it
    timestamp: int      # Lamport clock (u8)
    robot: int          # who wrote it


@dataclass(frozen=True)
class NeighborView:
    robot: int
    distance: object    # int (Kilobot) or float
    azimuth: object
    elevation: object
    marked: bool        # refreshed since the last neighbor-data collection


@dataclass(frozen=True)
class SwarmView:
    member_of: tuple[int, ...]        # swarm ids this robot belongs to
    membership_bits: int              # ``my_swarmlist``
    executing: tuple[int, ...]        # the swarm stack, outermost first (``swarm.id()``)


@dataclass(frozen=True)
class QueueView:
    incoming: tuple[bytes, ...]       # queued wire payloads, next to process first
    outgoing: tuple[bytes, ...]       # queued payloads, next to send first
    in_capacity: int
    out_capacity: int


@dataclass(frozen=True)
class StackView:
    depth: int                        # entries in use (grows by one per step in the robot loop)
    capacity: int
    entries: tuple[int, ...]          # heap indices, bottom first
    blockptr: int


@dataclass
class RobotView:
    """Everything the IDE's inspector shows for one robot, read between two steps."""

    robot_id: int
    state: str
    pc: int
    memory: MemoryView
    stack: StackView
    frames: list[FrameView]
    globals: dict[str, str]
    stigmergy: list[StigmergyEntryView]
    neighbors: list[NeighborView]
    neighbor_data_gc_in: int          # process_outmsgs calls until the next neighbor GC
    swarms: SwarmView
    queues: QueueView
    last_error: str | None            # "REASON at file:line:col: message" or None


def value_text(vm: VM, index: int, strings: list[str]) -> str:
    from bbzide.vm.dump import format_value

    return format_value(vm, index, strings)


def stigmergy_entries(vm: VM, strings: list[str]) -> list[StigmergyEntryView]:
    out = []
    for e in vm.vstig.entries:
        name = strings[e.key] if e.key < len(strings) else f"#{e.key}"
        out.append(StigmergyEntryView(name, e.key, e.value, value_text(vm, e.value, strings),
                                      e.timestamp, e.robot))
    return out


def neighbor_entries(vm: VM) -> list[NeighborView]:
    """XTREME: the ring buffer (oldest first); otherwise the heap sub-table under string 44."""
    from bbzide.compiler import bbzfloat
    from bbzide.vm.neighbors import MARK, STR_AZIMUTH, STR_DATA, STR_DISTANCE, STR_ELEVATION

    if vm.profile.xtreme:
        return [NeighborView(e.robot, e.distance, e.azimuth, e.elevation, bool(e.mark & MARK))
                for e in vm.neighbors.entries()]
    h = vm.heap

    def key_sid(k: int) -> int | None:
        return h.u16(k) if h.obj_type(k) == 3 else None

    sub = next((v for k, v in table_contents(vm, vm.neighbors.hpos) if key_sid(k) == STR_DATA),
               None)
    if sub is None or h.obj_type(sub) != TABLE:
        return []
    out = []
    for robot, data in table_contents(vm, sub):
        fields: dict[int, object] = {}
        marked = False
        if h.obj_type(data) == TABLE:
            for k, v in table_contents(vm, data):
                sid = key_sid(k)
                if sid is None:
                    marked = True  # the mark: key int 0 -> int 0
                    continue
                t = h.obj_type(v)
                fields[sid] = bbzfloat.to_float(h.u16(v)) if t == 2 else h.int_value(v)
        out.append(NeighborView(h.int_value(robot), fields.get(STR_DISTANCE),
                                fields.get(STR_AZIMUTH), fields.get(STR_ELEVATION), marked))
    return out


def swarm_view(vm: VM) -> SwarmView:
    bits = vm.swarm.my_swarmlist
    executing = tuple(vm.heap.int_value(i) for _, i in table_contents(vm, vm.swarm.swarmstack))
    return SwarmView(tuple(k for k in range(8) if bits >> k & 1), bits, executing)


def queue_view(vm: VM) -> QueueView:
    q = vm.queues
    return QueueView(tuple(q.in_messages()), tuple(q.out_messages()), q.in_capacity,
                     q.out_capacity)


def stack_view(vm: VM) -> StackView:
    return StackView(vm.stackptr + 1, vm.stack_size, tuple(vm.stack[:vm.stackptr + 1]),
                     vm.blockptr)


def inspect_robot(robot: Robot) -> RobotView:
    """The whole inspector snapshot of a Robot (read-only; call between two steps)."""
    vm = robot.vm
    strings = robot.program.strings
    failure = robot.failure
    return RobotView(
        robot_id=robot.robot_id,
        state=vm.state.name,
        pc=vm.pc,
        memory=memory(vm),
        stack=stack_view(vm),
        frames=stack_frames(vm),
        globals={name: value_text(vm, v, strings)
                 for name, v in globals_by_name(vm, strings).items()},
        stigmergy=stigmergy_entries(vm, strings),
        neighbors=neighbor_entries(vm),
        neighbor_data_gc_in=vm.neighbors.clear_counter + 1,
        swarms=swarm_view(vm),
        queues=queue_view(vm),
        last_error=str(failure) if failure is not None else None,
    )
