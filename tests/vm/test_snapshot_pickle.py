"""`VM.pickled_snapshot()` (the pickled layout: states outside the flat layout's shape, old
recordings) pickles the VM's records without turning their attributes into dicts (which would
slow the live VM down for the rest of the run), and the bytes restore exactly."""

from __future__ import annotations

import gc
import pickle

from bbzide import compiler
from bbzide.vm import snapshot_pickle
from bbzide.vm.messages import RingBuffer
from bbzide.vm.profiles import PROFILES
from bbzide.vm.robot import Robot

SCRIPT = """
s = stigmergy.create(1)
function init() { s.put(3, 7) }
function step() { neighbors.broadcast("x", id) }
"""


def records(robot: Robot) -> list[object]:
    vm = robot.vm
    return [vm.swarm, vm.vstig, vm.neighbors, vm.neighbors.ring, vm.queues, vm.queues.inbox,
            vm.queues.outbox, *vm.vstig.entries]


def has_dict(obj: object) -> bool:
    return any(isinstance(held, dict) for held in gc.get_referents(obj))


def booted() -> Robot:
    program = compiler.compile_source(
        SCRIPT, "<test>", string_table=compiler.bittybuzz_string_table([])).to_bbo()
    robot = Robot(program, PROFILES["kilobot"], 4)
    robot.boot()
    robot.receive(b"\x00\x02\x00\x01\x00\x05\x00\x00\x00", 12.0)
    robot.control_step()
    return robot


def test_snapshots_leave_the_live_records_as_they_were_and_restore_exactly() -> None:
    robot = booted()
    assert not any(has_dict(r) for r in records(robot))
    snapshot = robot.pickled_snapshot()
    assert not any(has_dict(r) for r in records(robot))  # no attribute dict was made
    other = booted()
    other.control_step()
    other.restore(snapshot)
    assert other.pickled_snapshot() == snapshot
    assert not any(has_dict(r) for r in records(other))
    flat = robot.snapshot()  # the flat layout reads the records without making dicts either
    assert not any(has_dict(r) for r in records(robot))
    other.restore(flat)
    assert other.snapshot() == flat and not any(has_dict(r) for r in records(other))


def test_an_object_with_unknown_attributes_is_pickled_the_plain_way() -> None:
    ring = RingBuffer([b"a", b"b"], 2)
    ring.extra = "not one of the known names"  # type: ignore[attr-defined]
    copy = pickle.loads(snapshot_pickle.dumps(ring))
    assert (copy.records, copy.capacity) == ([b"a", b"b"], 2)
    assert copy.extra == "not one of the known names"


def test_a_record_with_a_made_dict_or_a_missing_attribute_still_round_trips() -> None:
    ring = RingBuffer([b"a"], 1)
    ring.__dict__  # noqa: B018 - makes the attribute dict, as plain pickle would
    copy = pickle.loads(snapshot_pickle.dumps(ring))
    assert (copy.records, copy.capacity, copy.start, copy.end) == (
        ring.records, ring.capacity, ring.start, ring.end)
    short = RingBuffer([b"a"], 1)
    del short.end  # one of the known names missing: plain pickling, which keeps it missing
    copy = pickle.loads(snapshot_pickle.dumps(short))
    assert not hasattr(copy, "end") and copy.records == [b"a"]


def test_lists_of_records_are_written_as_rows_unless_something_else_holds_them() -> None:
    from bbzide.vm.neighbors import NeighborEntry

    ring = RingBuffer([NeighborEntry(i, 10 + i, 20, 30) for i in range(4)], 3)
    data = snapshot_pickle.dumps(ring)
    assert b"_rebuild_rows" in data  # the flat form is used...
    copy = pickle.loads(data)
    assert copy.records == ring.records and not any(has_dict(e) for e in copy.records)
    # ...but a list or a record that another object also holds keeps that sharing
    held_list = RingBuffer([NeighborEntry(1, 2, 3, 4)], 1)
    ring_copy, list_copy = pickle.loads(snapshot_pickle.dumps((held_list, held_list.records)))
    assert ring_copy.records is list_copy
    entry = NeighborEntry(5, 6, 7, 8)
    held_entry = RingBuffer([NeighborEntry(1, 2, 3, 4), entry], 2)
    ring_copy, entry_copy = pickle.loads(snapshot_pickle.dumps((held_entry, entry)))
    assert ring_copy.records[1] is entry_copy


def test_equal_states_give_equal_bytes_whoever_else_holds_their_objects() -> None:
    """The rows-or-list choice follows from the pickled value only: an outside reference to
    the neighbour ring's list or to one of its entries (e.g. a garbage cycle not yet
    collected) does not change the bytes, and a restored robot snapshots to the same bytes.
    (The pickled layout: what a state outside the flat layout's shape, and every recording
    of formats 2 and 3, holds.)"""
    from bbzide.vm.neighbors import NeighborEntry

    robot = booted()
    ring = robot.vm.neighbors.ring
    if not ring.records:  # an XTREME ring may start empty: give it entries to flatten
        ring.records.extend(NeighborEntry(i, 10 + i, 20, 30) for i in range(3))
    before = robot.pickled_snapshot()
    assert b"_rebuild_rows" in before
    outside = [ring.records, ring.records[0], *robot.vm.vstig.entries]  # extra holders
    assert robot.pickled_snapshot() == before
    del outside
    other = booted()
    other.control_step()
    other.restore(before)
    assert other.pickled_snapshot() == before
    kept = list(other.vm.neighbors.ring.records)  # noqa: F841 - holds every entry once more
    assert other.pickled_snapshot() == before
    assert not any(has_dict(r) for r in records(other))


def test_rows_are_used_for_unshared_lists_whatever_order_the_sharing_comes_in() -> None:
    from bbzide.vm.neighbors import NeighborEntry

    entry = NeighborEntry(5, 6, 7, 8)
    held = RingBuffer([NeighborEntry(1, 2, 3, 4), entry], 2)
    for value in ((entry, held), (held, entry)):  # the item written before or after the rows
        data = snapshot_pickle.dumps(value)
        copy = pickle.loads(data)
        ring_copy, entry_copy = (copy[1], copy[0]) if value[0] is entry else copy
        assert ring_copy.records[1] is entry_copy
    two = [NeighborEntry(1, 2, 3, 4)]
    first, second = RingBuffer(two, 1), RingBuffer(two, 1)  # one list held by two records
    a, b = pickle.loads(snapshot_pickle.dumps((first, second)))
    assert a.records is b.records
    alone = RingBuffer([NeighborEntry(1, 2, 3, 4)], 1)
    holder = [alone.records]  # held outside the pickled value: rows all the same
    assert b"_rebuild_rows" in snapshot_pickle.dumps(alone)
    assert holder
