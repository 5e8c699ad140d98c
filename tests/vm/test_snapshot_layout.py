"""The flat snapshot layout (`snapshot_layout`): what `Robot.snapshot()` writes for a VM of the
usual shape. It must restore exactly, give equal bytes for equal states whichever form (packed
arrays or Python records) holds the queues and the ring, read old pickled snapshots, fall back
to the pickled layout for any other shape, and refuse damaged bytes without running anything."""

from __future__ import annotations

import pickle

import numpy as np
import pytest

from bbzide.compiler import bittybuzz_string_table, compile_source
from bbzide.vm import snapshot_layout
from bbzide.vm.profiles import CRAZYFLIE, KILOBOT, M300
from bbzide.vm.robot import Robot
from bbzide.vm.snapshot_layout import SnapshotError
from bbzide.vm.swarm_batch import PackedMessages, control_steps

SCRIPT = """
heard = 0
steps = 0
function init() {
  neighbors.listen("h", function(topic, value, rid) { heard = heard + value })
  v = stigmergy.create(1)
}
function step() {
  steps = steps + 1
  neighbors.broadcast("h", id + heard % 5)
  if (id % 3 == 0) { v.put(id, heard) }
  if (steps > 6 and id == 2) { x = 1 / 0 }
}
"""


def swarm(profile, count: int) -> list[Robot]:  # noqa: ANN001
    program = compile_source(SCRIPT, "layout.bzz",
                             string_table=bittybuzz_string_table([])).to_bbo()
    robots = [Robot(program, profile, i) for i in range(count)]
    for robot in robots:
        robot.boot()
    return robots


def run(robots: list[Robot], steps: int) -> None:
    """`steps` swarm steps, every robot hearing every other (the compiled step for a
    Kilobot: its queues and ring end up held by the packed arrays)."""
    count = len(robots)
    sent: list[list[bytes]] = [[] for _ in range(count)]
    for _ in range(steps):
        rows = [(r, s, payload, 0.05 + 0.01 * s, 0.3 * (r - s), 0.0)
                for r in range(count) for s in range(count) if s != r for payload in sent[s]]
        result = control_steps(robots, PackedMessages.from_rows(rows), np.ones(count, bool))
        sent = [[] for _ in range(count)]
        for k in range(len(result.outbox)):
            sent[int(result.outbox.robots[k])].append(result.outbox.payload(k))


@pytest.mark.parametrize("profile", [KILOBOT, CRAZYFLIE, M300], ids=lambda p: p.name)
def test_flat_snapshots_restore_exactly_and_match_the_pickled_layout(profile) -> None:  # noqa: ANN001
    robots = swarm(profile, 5)
    run(robots, 12)
    assert robots[2].failure is not None  # a failed robot's failure is part of its state
    fresh = swarm(profile, 1)[0]
    for robot in robots:
        flat = robot.snapshot()
        assert flat.startswith(snapshot_layout.ROBOT_MAGIC)
        # the same state in both layouts decodes to the same records
        assert Robot.comparable(flat) == Robot.comparable(robot.pickled_snapshot())
        fresh.restore(flat)
        assert fresh.snapshot() == flat
        assert fresh.failure == robot.failure
    assert robots[3].vm.vstig.entries  # the stigmergy entries were written and read back


def test_packed_and_python_forms_of_one_state_give_the_same_bytes() -> None:
    robots = swarm(KILOBOT, 5)
    run(robots, 8)
    # the compiled step holds the arrays of the robots that made no Python host call (put)
    # and did not fail
    live = [robot.vm._packed_live for robot in robots]
    assert live == [robot.robot_id % 3 != 0 and robot.failure is None for robot in robots]
    assert any(live)
    packed = [robot.snapshot() for robot in robots]
    assert [robot.vm._packed_live for robot in robots] == live  # a snapshot does not unpack
    for robot in robots:
        robot.vm.queues  # noqa: B018 - a Python access: the records hold the truth again
        assert not robot.vm._packed_live
    assert [robot.snapshot() for robot in robots] == packed
    run(robots, 3)  # and the robots go on exactly after being snapshotted while packed
    other = swarm(KILOBOT, 5)
    for robot, snapshot in zip(other, packed, strict=True):
        robot.restore(snapshot)
    run(other, 3)
    assert [r.snapshot() for r in other] == [r.snapshot() for r in robots]


def test_packed_queues_without_a_packed_ring_give_the_same_bytes() -> None:
    """A non-XTREME VM (Crazyflie) whose queues the arrays hold: its ring stays Python's."""
    robots = swarm(CRAZYFLIE, 3)
    run(robots, 4)
    for robot in robots:
        vm = robot.vm
        python_form = robot.snapshot()
        vm.packed()  # the arrays hold the truth now
        assert vm._packed_live and not vm._packed.xtreme  # type: ignore[union-attr]
        assert robot.snapshot() == python_form
        vm._packed.inq[3] ^= 0xFF  # type: ignore[union-attr] - and the arrays are what is read
        assert robot.snapshot() != python_form


def test_old_pickled_snapshots_still_restore() -> None:
    """Recordings of formats 2 and 3 hold pickled snapshots: they restore to the same state."""
    robots = swarm(KILOBOT, 4)
    run(robots, 6)
    fresh = swarm(KILOBOT, 1)[0]
    for robot in robots:
        old = robot.pickled_snapshot()
        assert old.startswith(b"\x80")
        fresh.restore(old)
        assert fresh.snapshot() == robot.snapshot()


@pytest.mark.parametrize("unsettled, truncated", [(True, False), (False, True), (True, True)])
def test_the_heap_flags_restore_in_both_layouts(unsettled: bool, truncated: bool) -> None:
    """`Heap.unsettled` and `Heap.truncated` (which collections the fast mode may skip) come
    back with the state; two states that differ only in them compare equal."""
    robots = swarm(KILOBOT, 2)
    run(robots, 4)
    robot = robots[0]
    plain = Robot.comparable(robot.snapshot())
    robot.vm.heap.unsettled, robot.vm.heap.truncated = unsettled, truncated
    for snapshot in (robot.snapshot(), robot.pickled_snapshot()):
        fresh = swarm(KILOBOT, 1)[0]
        fresh.restore(snapshot)
        assert (fresh.vm.heap.unsettled, fresh.vm.heap.truncated) == (unsettled, truncated)
        assert Robot.comparable(snapshot) == plain


def test_a_flat_snapshot_without_heap_flags_restores_with_none_set() -> None:
    """A flat VM snapshot written before the header held the flags (magic BZV 1, one field
    fewer): every recording made then."""
    robots = swarm(KILOBOT, 2)
    run(robots, 4)
    robot = robots[0]
    robot.vm.heap.truncated = True
    vm_at = snapshot_layout._ROBOT_HEAD.size
    flat = robot.snapshot()
    flags_at = vm_at + len(snapshot_layout.VM_MAGIC) + 8 * snapshot_layout.VM_FIELDS.index(
        "heap_flags")
    vm_bytes = (snapshot_layout.VM_MAGIC_WITHOUT_FLAGS + flat[vm_at + 4:flags_at]
                + flat[flags_at + 8:])
    _magic, steps, booted, failed, _length = snapshot_layout._ROBOT_HEAD.unpack_from(flat)
    old = snapshot_layout._ROBOT_HEAD.pack(snapshot_layout.ROBOT_MAGIC, steps, booted, failed,
                                           len(vm_bytes)) + vm_bytes
    fresh = swarm(KILOBOT, 1)[0]
    fresh.restore(old)
    assert not fresh.vm.heap.truncated and not fresh.vm.heap.unsettled
    assert Robot.comparable(old) == Robot.comparable(flat)
    for value in (4, -1, 2 ** 40):  # bits that mean nothing
        crafted = flat[:flags_at] + value.to_bytes(8, "little", signed=True) + \
            flat[flags_at + 8:]
        with pytest.raises(SnapshotError, match="heap flags"):
            fresh.restore(crafted)


def test_a_pickled_heap_of_another_shape_is_refused() -> None:
    """A pickled keyframe is untrusted: a heap tuple of another length, or flags that are not
    bools, is a `SnapshotError` and leaves the VM as it was."""
    robot = swarm(KILOBOT, 1)[0]
    before = robot.snapshot()
    state = robot.vm.decode_snapshot(robot.vm.pickled_snapshot())
    heap = state[0]
    for crafted in (heap[:2], heap[:6], (*heap[:5], 1, 0), (*heap, False)):
        with pytest.raises(SnapshotError):
            robot.vm.restore_state((crafted, *state[1:]))
    assert robot.snapshot() == before


def test_a_state_of_another_shape_is_pickled_and_restores() -> None:
    robot = swarm(KILOBOT, 1)[0]
    robot.control_step()  # robot 0 puts into its stigmergy
    robot.vm.vstig.entries[0].value = 2.5  # type: ignore[assignment] - not an int
    snapshot = robot.snapshot()
    assert snapshot.startswith(b"\x80")
    other = swarm(KILOBOT, 1)[0]
    other.restore(snapshot)
    assert other.vm.vstig.entries[0].value == 2.5
    robot = swarm(KILOBOT, 1)[0]
    robot.vm.swarm.extra = 1  # type: ignore[attr-defined] - an attribute beyond the fields
    assert robot.snapshot().startswith(b"\x80")
    robot = swarm(KILOBOT, 1)[0]
    robot.vm.neighbors.ring.records[3].mark = True  # a bool: would come back as an int
    assert robot.snapshot().startswith(b"\x80")
    robot = swarm(KILOBOT, 1)[0]
    entries = robot.vm.neighbors.ring.records
    del entries[1].mark  # one field fewer here, one attribute more there: the counts add up
    entries[2].extra = 0  # type: ignore[attr-defined]
    snapshot = robot.snapshot()
    assert snapshot.startswith(b"\x80")
    other = swarm(KILOBOT, 1)[0]
    other.restore(snapshot)
    assert other.vm.neighbors.ring.records[2].extra == 0  # type: ignore[attr-defined]


def test_damaged_or_crafted_flat_snapshots_are_refused() -> None:
    robots = swarm(KILOBOT, 3)
    run(robots, 5)
    flat = robots[0].snapshot()
    fresh = swarm(KILOBOT, 1)[0]
    # cut anywhere after the magic: never a partial restore that passes
    for cut in range(len(snapshot_layout.ROBOT_MAGIC), len(flat), 7):
        with pytest.raises(SnapshotError):
            Robot.decode_snapshot(flat[:cut])
    with pytest.raises(SnapshotError):
        Robot.decode_snapshot(flat + b"\x00")
    vm_at = snapshot_layout._ROBOT_HEAD.size
    fields = snapshot_layout.VM_FIELDS
    for field, value in (("inbox_records", 10**12), ("heap_bytes", -1), ("state", 99),
                         ("obj_size", 40), ("error_events", -1)):
        at = vm_at + len(snapshot_layout.VM_MAGIC) + 8 * fields.index(field)
        crafted = flat[:at] + value.to_bytes(8, "little", signed=True) + flat[at + 8:]
        with pytest.raises(SnapshotError):
            fresh.restore(crafted)
    # a pickle where the flat robot snapshot holds its VM's is refused, not unpickled
    inner = robots[0].vm.pickled_snapshot()
    head = snapshot_layout._ROBOT_HEAD.pack(snapshot_layout.ROBOT_MAGIC, 1, 1, 0, len(inner))
    with pytest.raises(SnapshotError):
        fresh.restore(head + inner)
    # a heap of another profile's size is not taken over, and the robot is left as it was
    other = swarm(CRAZYFLIE, 1)[0]
    before = fresh.snapshot()
    with pytest.raises(SnapshotError):
        fresh.restore(other.snapshot())
    assert fresh.snapshot() == before


def test_the_comparable_form_ignores_the_layout_but_not_the_state() -> None:
    a, b = swarm(KILOBOT, 2)
    assert Robot.comparable(a.snapshot()) == Robot.comparable(a.pickled_snapshot())
    assert Robot.comparable(a.snapshot()) != Robot.comparable(b.snapshot())
    assert pickle.loads(Robot.comparable(a.snapshot()))[2] == a.steps_done
