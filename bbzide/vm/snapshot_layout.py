"""A VM's and a robot's snapshot as flat bytes: a header of integers, then raw sections.

Design: the recorder keyframes every robot about every 150 steps, and pickling the VM's state
(`snapshot_pickle`) spent most of a keyframe walking Python structure: ~100 us for a Kilobot
whose state is 2.8 KB, ~290 us for an M300 drone's 68 KB, plus ~20 us to unpack the
compiled step's arrays (packed_queues.py) into the Python records first. Nearly all of that
state is already flat: the heap and the stack are byte buffers, the message queues are
records of one size, and the XTREME neighbor ring is an int64 array while the compiled step
holds the truth. So a snapshot is one fixed header of int64s (every scalar register and record
field, and the length of every section) followed by the sections back to back:

    heap bytes | stack (u16) | inbox records | outbox records | neighbor ring (5 x i64 a row)
    | bytecode | stigmergy entries (4 x i64 each) | error events (i64 pc, u32 length, name)

written straight from the live buffers, and from the packed arrays when they hold the truth
(nothing is unpacked). The fixed-size sections come first, so between two keyframes of a robot
the heap and the rest keep their offsets (keyframe deltas, recording/keyframes.py). All
little-endian. Equal states give equal bytes: every byte follows from a value of the state,
whichever form (packed or Python records) holds it.

The header's last field, ``heap_flags``, holds the fast mode's two notes on the heap
(`Heap.unsettled`, `Heap.truncated`: which of its collections may be skipped), so that a
restored robot skips no collection its heap forbids; snapshots written before it (magic
`VM_MAGIC_WITHOUT_FLAGS`) are still read, with neither flag set.

A state outside this shape — a record of another class, an attribute beyond a record's
fields, a value that is not an int (or does not fit in an int64) — is not written here:
`vm_bytes` returns None and `VM.snapshot` pickles it (`snapshot_pickle`), as every snapshot
was before. Restoring reads both: these bytes start with `VM_MAGIC`/`ROBOT_MAGIC`, a pickle
with 0x80. A robot's snapshot wraps its VM's (`ROBOT_MAGIC`, steps done, booted, the VM
bytes, then the failure if any); it is only written when its VM's is flat, so a flat robot
snapshot holds no pickle at all. A recording is untrusted input: decoding never runs code,
checks every length against the bytes, and reports any mismatch as a `SnapshotError`.

`decode_vm` gives the state as the tuple the pickled layout holds (the same records,
freshly built), so `VM.restore` and `Robot.comparable` treat both layouts alike.

Measured (25 robots, right after a simulation step, i.e. with cold caches, as the recorder
calls it): a Kilobot's `Robot.snapshot()` ~30-45 us (pickled: ~100-160), an M300 SAR drone's
~200 us (pickled: ~290 and more); restoring an M300 keyframe ~0.11 ms (pickled: ~0.31).
"""

from __future__ import annotations

import gc
import struct
import sys
from array import array
from collections.abc import Callable
from itertools import starmap
from operator import attrgetter, countOf
from typing import TYPE_CHECKING, Any

from bbzide.diagnostics import SourceLocation
from bbzide.vm.messages import MessageQueues, RingBuffer, record_size
from bbzide.vm.neighbors import NeighborEntry, NeighborsState
from bbzide.vm.states import Error, State
from bbzide.vm.swarm import SwarmState
from bbzide.vm.vstig import VstigEntry, VstigStore

if TYPE_CHECKING:
    from bbzide.vm.robot import Robot
    from bbzide.vm.vm import VM

#: first bytes of a flat VM / robot snapshot (a pickle starts with 0x80, protocol 2+)
VM_MAGIC = b"BZV\x02"
ROBOT_MAGIC = b"BZR\x01"
#: a flat VM snapshot written before the header held ``heap_flags`` (read as flags 0)
VM_MAGIC_WITHOUT_FLAGS = b"BZV\x01"
VM_MAGICS = (VM_MAGIC, VM_MAGIC_WITHOUT_FLAGS)

#: the header's int64 fields, in order
VM_FIELDS = (
    "heap_bytes", "rtobj", "ltseg", "peak_used", "gc_runs",
    "stack_entries", "stackptr", "blockptr", "pc", "state", "error", "lsyms", "gsyms", "nil",
    "dflt_actrec", "flist", "robot", "instructions_executed",
    "swarm_hpos", "swarmstack", "my_swarmlist",
    "vstig_hpos", "vstig_entries",
    "neighbors_hpos", "listeners", "clear_counter", "neighbors_count",
    "ring_capacity", "ring_start", "ring_end", "ring_records",
    "in_capacity", "out_capacity", "obj_size", "record_bytes",
    "inbox_capacity", "inbox_start", "inbox_end", "inbox_records",
    "outbox_capacity", "outbox_start", "outbox_end", "outbox_records",
    "bcode_bytes", "error_events", "heap_flags",
)
_VM_HEAD = struct.Struct(f"<4s{len(VM_FIELDS)}q")
_VM_HEAD_WITHOUT_FLAGS = struct.Struct(f"<4s{len(VM_FIELDS) - 1}q")
#: ``heap_flags``' bits: the fast mode's `Heap.unsettled` and `Heap.truncated` (which rules
#: its collections may skip; the reference never sets them)
HEAP_UNSETTLED, HEAP_TRUNCATED = 1, 2
#: magic, steps done, booted, failed, VM snapshot bytes
_ROBOT_HEAD = struct.Struct("<4sqBBI")
#: a failure: pc, then (has location, line, column), then reason, message, file as strings
_FAILURE_HEAD = struct.Struct("<qBqq")
_LENGTH = struct.Struct("<I")
_EVENT = struct.Struct("<qI")

#: fields of the records written as int64 rows
_RING_FIELDS = ("robot", "distance", "azimuth", "elevation", "mark")
_VSTIG_FIELDS = ("key", "value", "timestamp", "robot")
_ring_row = attrgetter(*_RING_FIELDS)
_vstig_row = attrgetter(*_VSTIG_FIELDS)
_RING_ROW = struct.Struct(f"<{len(_RING_FIELDS)}q")
_VSTIG_ROW = struct.Struct(f"<{len(_VSTIG_FIELDS)}q")
#: `gc.get_referents` of the seven container records (swarm, vstig, neighbors, queues, three
#: rings) when each holds exactly its attributes as inline values: one per attribute plus its
#: class each (see snapshot_pickle._exactly; a made `__dict__` or an extra attribute differs)
_CONTAINER_REFERENTS = (3 + 1) + (2 + 1) + (5 + 1) + (5 + 1) + 3 * (4 + 1)
_LITTLE = sys.byteorder == "little"


class SnapshotError(ValueError):
    """Bytes that are not a snapshot of this layout (a corrupt or crafted recording)."""


def _le(buffer: Any) -> Any:
    """`buffer` (an array or numpy array of ints) as little-endian bytes-like."""
    if _LITTLE:
        return buffer
    if isinstance(buffer, array):
        swapped = array(buffer.typecode, buffer)
        swapped.byteswap()  # in place
        return swapped
    return buffer.byteswap()  # numpy: a swapped copy


def _only_ints(values: Any) -> bool:
    """Whether every value is exactly an int (a bool or an int enum would come back as one)."""
    return countOf(map(type, values), int) == len(values)


def _rows(records: list[Any], cls: type, get: Callable[[Any], Any], row: struct.Struct,
          width: int) -> bytes | None:
    """The records' `width` fields as int64 rows, or None when any record is not exactly a
    `cls` holding those fields as ints (then the snapshot is pickled).

    The checks, cheapest first: every record's class is `cls`; then `gc.get_referents` of all
    records at once: each record's inline values followed by its class (a made `__dict__`
    shows as one dict instead). `width + 1` objects a record, with the class at every
    `width + 1`-th place, means every record holds exactly `width` attributes (a record with
    fewer or more would shift the classes off those places); `width` ints a record means they
    are all ints and there is no dict. Like `snapshot_pickle._exactly`, this counts attributes
    and reads them by name, so a record that lost a field that has a class default (`mark`)
    and gained another attribute would pass: nothing does that to the VM's records.
    """
    if not records:
        return b""
    count = len(records)
    if set(map(type, records)) != {cls}:
        return None
    held = gc.get_referents(*records)
    if len(held) != (width + 1) * count or countOf(held[width::width + 1], cls) != count \
            or countOf(map(type, held), int) != width * count:
        return None
    if countOf(held, 0) == width * count:
        # all zero, e.g. the ring of a non-XTREME profile (its neighbors live in the heap and
        # the ring stays as built: 65 records of an M300 drone): no need to read them by name
        return bytes(row.size * count)
    try:
        return b"".join(starmap(row.pack, map(get, records)))
    except (AttributeError, struct.error):
        return None


#: the classes of (swarm, vstig, neighbors, queues, inbox, outbox, ring, state, error,
#: bytecode, stack, stigmergy entries, ring records, inbox records, outbox records)
_SHAPE = (SwarmState, VstigStore, NeighborsState, MessageQueues, RingBuffer, RingBuffer,
          RingBuffer, State, Error, bytes, array, list, list, list, list)


def vm_parts(vm: VM) -> tuple[list[Any], int] | None:
    """The VM's state in this layout as bytes-like parts to join, and their total length;
    None when it has another shape (see the module). Written for speed: a keyframe is one
    call, on the simulation's thread, with the caches cold from the step before."""
    swarm, vstig = vm.swarm, vm._vstig
    queues, neighbors = vm._queues, vm._neighbors
    inbox, outbox, ring = queues.inbox, queues.outbox, neighbors.ring
    heap, stack, bcode, entries = vm.heap, vm.stack, vm.bcode, vstig.entries
    if ((type(swarm), type(vstig), type(neighbors), type(queues), type(inbox), type(outbox),
         type(ring), type(vm.state), type(vm.error), type(bcode), type(stack), type(entries),
         type(ring.records), type(inbox.records), type(outbox.records)) != _SHAPE
            or stack.typecode != "H"
            or len(gc.get_referents(swarm, vstig, neighbors, queues, inbox, outbox, ring))
            != _CONTAINER_REFERENTS):
        return None
    record = record_size(queues.obj_size)
    in_count, out_count = len(inbox.records), len(outbox.records)
    packed = vm._packed if vm._packed_live else None
    if packed is not None:
        # the arrays hold the truth: read them as `PackedQueues.unpack` would write them back
        in_start, in_end, ring_start, ring_end, out_start, out_end, clear_counter = \
            packed.indices()
        inq, outq = packed.inq, packed.outq
        if packed.record != record or (packed.xtreme and len(packed.ring) != len(ring.records)):
            return None
        ring_rows = _le(packed.ring) if packed.xtreme else None
        packed_entries = packed.vstig_in_use()
        rows, entry_count = _le(packed_entries), len(packed_entries)
    else:
        in_start, in_end, out_start, out_end = inbox.start, inbox.end, outbox.start, outbox.end
        ring_start, ring_end, clear_counter = ring.start, ring.end, neighbors.clear_counter
        for records in (inbox.records, outbox.records):
            if set(map(type, records)) - {bytearray} or set(map(len, records)) - {record}:
                return None
        inq, outq = b"".join(inbox.records), b"".join(outbox.records)
        ring_rows = None
        rows = _rows(entries, VstigEntry, _vstig_row, _VSTIG_ROW, len(_VSTIG_FIELDS))
        entry_count = len(entries)
    if ring_rows is None:
        ring_rows = _rows(ring.records, NeighborEntry, _ring_row, _RING_ROW, len(_RING_FIELDS))
    if ring_rows is None or rows is None:
        return None
    events = vm.error_events
    tail: list[bytes] = []
    if events:
        if type(events) is not list:
            return None
        for event in events:
            if type(event) is not tuple or len(event) != 2 or type(event[0]) is not str:
                return None
            name, pc = event
            try:
                encoded = name.encode()
                tail += (_EVENT.pack(pc, len(encoded)), encoded)
            except (struct.error, UnicodeEncodeError):
                return None
    ring_count = len(ring.records)
    values = (
        len(heap.data), heap.rtobj, heap.ltseg, heap.peak_used, heap.gc_runs,
        len(stack), vm.stackptr, vm.blockptr, vm.pc, int(vm.state), int(vm.error), vm.lsyms,
        vm.gsyms, vm.nil, vm.dflt_actrec, vm.flist, vm.robot, vm.instructions_executed,
        swarm.hpos, swarm.swarmstack, swarm.my_swarmlist,
        vstig.hpos, entry_count,
        neighbors.hpos, neighbors.listeners, clear_counter, neighbors.count,
        ring.capacity, ring_start, ring_end, ring_count,
        queues.in_capacity, queues.out_capacity, queues.obj_size, record,
        inbox.capacity, in_start, in_end, in_count,
        outbox.capacity, out_start, out_end, out_count,
        len(bcode), len(events),
        HEAP_UNSETTLED * heap.unsettled + HEAP_TRUNCATED * heap.truncated,
    )
    if not _only_ints(values) or (tail and not _only_ints([e[1] for e in events])):
        return None
    try:
        head = _VM_HEAD.pack(VM_MAGIC, *values)
    except struct.error:
        return None
    length = (_VM_HEAD.size + values[0] + 2 * values[5] + record * (in_count + out_count)
              + 8 * (len(_RING_FIELDS) * ring_count + len(_VSTIG_FIELDS) * entry_count)
              + len(bcode) + sum(map(len, tail)))
    return [head, heap.data, _le(stack), inq, outq, ring_rows, bcode, rows, *tail], length


def vm_bytes(vm: VM) -> bytes | None:
    """The VM's state in this layout, or None when it has another shape (see the module)."""
    found = vm_parts(vm)
    return None if found is None else b"".join(found[0])


class _Reader:
    """Consumes `data` section by section; any overrun is a `SnapshotError`."""

    def __init__(self, data: bytes, at: int) -> None:
        self.data, self.at = data, at

    def take(self, count: int) -> bytes:
        if count < 0 or self.at + count > len(self.data):
            raise SnapshotError("snapshot shorter than its header says")
        start, self.at = self.at, self.at + count
        return self.data[start:self.at]

    def ints(self, count: int, typecode: str = "q") -> list[int]:
        values = array(typecode)
        values.frombytes(self.take(count * values.itemsize))
        if not _LITTLE:
            values.byteswap()
        return values.tolist()

    def string(self) -> str:
        (length,) = _LENGTH.unpack(self.take(_LENGTH.size))
        return self.take(length).decode()


def decode_vm(data: bytes, at: int = 0, end: int | None = None) -> tuple[Any, ...]:
    """`vm_bytes`' state (from `data[at:end]`) as the tuple of the pickled layout."""
    try:
        return _decode_vm(data, at, len(data) if end is None else end)
    except (struct.error, UnicodeDecodeError, TypeError) as error:
        raise SnapshotError(f"damaged VM snapshot ({error})") from None


def _decode_vm(data: bytes, at: int, end: int) -> tuple[Any, ...]:
    magic = data[at:at + len(VM_MAGIC)]
    if magic not in VM_MAGICS:
        raise SnapshotError("not a flat VM snapshot")
    head, fields = (_VM_HEAD, VM_FIELDS) if magic == VM_MAGIC else \
        (_VM_HEAD_WITHOUT_FLAGS, VM_FIELDS[:-1])
    magic, *values = head.unpack_from(data, at)
    f = dict(zip(fields, values, strict=True))
    flags = f.get("heap_flags", 0)
    if not 0 <= flags <= HEAP_UNSETTLED | HEAP_TRUNCATED:
        raise SnapshotError("unknown heap flags")
    reader = _Reader(data[:end], at + head.size)
    heap = (reader.take(f["heap_bytes"]), f["rtobj"], f["ltseg"], f["peak_used"], f["gc_runs"],
            bool(flags & HEAP_UNSETTLED), bool(flags & HEAP_TRUNCATED))
    stack = reader.ints(f["stack_entries"], "H")
    record = f["record_bytes"]
    if record != record_size(f["obj_size"]) or f["obj_size"] <= 0:
        # (a record of 0 bytes would make any record count fit the bytes present)
        raise SnapshotError("message record size does not match the object size")
    # built attribute by attribute, in field order, as unpickling does: the constructor would
    # allocate capacity-many records, and the capacities are not checked yet
    queues = MessageQueues.__new__(MessageQueues)
    queues.in_capacity, queues.out_capacity = f["in_capacity"], f["out_capacity"]
    queues.obj_size = f["obj_size"]
    for box in ("inbox", "outbox"):
        count = f[f"{box}_records"]
        raw = reader.take(count * record)
        buffer = RingBuffer([bytearray(raw[k * record:(k + 1) * record]) for k in range(count)],
                            f[f"{box}_capacity"])
        buffer.start, buffer.end = f[f"{box}_start"], f[f"{box}_end"]
        setattr(queues, box, buffer)
    width = len(_RING_FIELDS)
    flat = reader.ints(f["ring_records"] * width)
    ring = RingBuffer([NeighborEntry(*flat[k:k + width]) for k in range(0, len(flat), width)],
                      f["ring_capacity"])
    ring.start, ring.end = f["ring_start"], f["ring_end"]
    neighbors = NeighborsState(f["neighbors_hpos"], f["listeners"], f["clear_counter"],
                               f["neighbors_count"], ring)
    bcode = reader.take(f["bcode_bytes"])
    width = len(_VSTIG_FIELDS)
    flat = reader.ints(f["vstig_entries"] * width)
    vstig = VstigStore(f["vstig_hpos"],
                       [VstigEntry(*flat[k:k + width]) for k in range(0, len(flat), width)])
    events = []
    for _ in range(max(f["error_events"], 0)):
        pc, length = _EVENT.unpack(reader.take(_EVENT.size))
        # interned like the live names (`Error.X.name`, one object per name)
        events.append((sys.intern(reader.take(length).decode()), pc))
    if reader.at != end or f["error_events"] < 0:
        raise SnapshotError("snapshot length does not match its header")
    swarm = SwarmState(f["swarm_hpos"], f["swarmstack"], f["my_swarmlist"])
    try:
        state, error = State(f["state"]), Error(f["error"])
    except ValueError:
        raise SnapshotError("unknown VM state or error number") from None
    return (heap, stack, f["stackptr"], f["blockptr"], f["pc"], state, error, f["lsyms"],
            f["gsyms"], f["nil"], f["dflt_actrec"], f["flist"], f["robot"], events,
            f["instructions_executed"], (swarm, vstig, neighbors, queues), bcode)


#: a robot's failure as plain values: (reason, pc, location or None, message)
Failure = tuple[str, int, SourceLocation | None, str]


def robot_bytes(robot: Robot, failure_type: type) -> bytes | None:
    """A robot's snapshot in this layout (its VM's flat snapshot inside), or None when the
    VM's state or the robot's bookkeeping has another shape (then the robot's is pickled).
    ``failure_type``: `robot.RobotFailure` (passed in: the robot module imports this one)."""
    steps_done, booted, failure = robot.steps_done, robot.booted, robot.failure
    if type(steps_done) is not int or type(booted) is not bool:
        return None
    found = vm_parts(robot.vm)
    if found is None:
        return None
    parts, length = found
    try:
        head = _ROBOT_HEAD.pack(ROBOT_MAGIC, steps_done, booted, failure is not None, length)
        if failure is not None:
            location = failure.location
            if type(failure) is not failure_type \
                    or type(location) not in (SourceLocation, type(None)) \
                    or not _only_ints((failure.pc, *((location.line, location.col)
                                                     if location else ()))):
                return None
            parts.append(_FAILURE_HEAD.pack(failure.pc, location is not None,
                                            location.line if location else 0,
                                            location.col if location else 0))
            for text in (failure.reason, failure.message, location.file if location else ""):
                if type(text) is not str:
                    return None
                encoded = text.encode()
                parts += (_LENGTH.pack(len(encoded)), encoded)
    except (struct.error, UnicodeEncodeError):
        return None
    return b"".join((head, *parts))


def decode_robot(data: bytes) -> tuple[tuple[Any, ...], Failure | None, int, bool]:
    """`robot_bytes`' robot: (the VM's state tuple, failure, steps done, booted)."""
    try:
        magic, steps_done, booted, failed, vm_length = _ROBOT_HEAD.unpack_from(data)
        if magic != ROBOT_MAGIC or booted > 1 or failed > 1:
            raise SnapshotError("not a flat robot snapshot")
        end = _ROBOT_HEAD.size + vm_length
        if end > len(data):
            raise SnapshotError("robot snapshot shorter than its header says")
        vm_state = decode_vm(data, _ROBOT_HEAD.size, end)
        failure: Failure | None = None
        reader = _Reader(data, end)
        if failed:
            pc, located, line, col = _FAILURE_HEAD.unpack(reader.take(_FAILURE_HEAD.size))
            reason, message, file = reader.string(), reader.string(), reader.string()
            failure = (reason, pc, SourceLocation(file, line, col) if located else None,
                       message)
        if reader.at != len(data):
            raise SnapshotError("robot snapshot length does not match its header")
    except (struct.error, UnicodeDecodeError) as error:
        raise SnapshotError(f"damaged robot snapshot ({error})") from None
    return vm_state, failure, steps_done, bool(booted)
