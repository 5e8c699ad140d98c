"""`swarm_batch.control_steps` (one control step of many robots) against the robots' own
`receive`/`control_step` called one by one — the contract a compiled path must also keep."""

from __future__ import annotations

import numpy as np
import pytest

from bbzide.compiler import bittybuzz_string_table, compile_source
from bbzide.vm.profiles import CRAZYFLIE, KILOBOT
from bbzide.vm.robot import Robot
from bbzide.vm.swarm_batch import PackedMessages, control_steps

SCRIPT = """
heard = 0
function init() {
  neighbors.listen("h", function(topic, value, rid) { heard = heard + value })
  v = stigmergy.create(1)
}
function step() {
  neighbors.broadcast("h", id + heard % 5)
  if (id % 3 == 0) { v.put(id, heard) }
  if (heard > 20 and id == 2) { x = nil + 1 }
}
"""


def swarm(profile, count: int) -> list[Robot]:  # noqa: ANN001
    table = bittybuzz_string_table([])
    program = compile_source(SCRIPT, "batch.bzz", string_table=table).to_bbo()
    robots = [Robot(program, profile, i) for i in range(count)]
    for robot in robots:
        robot.boot()
    return robots


def all_to_all(sent: list[list[bytes]], count: int) -> list[tuple]:
    """Rows (receiver, sender, payload, distance, azimuth, elevation) sorted by receiver."""
    return [(r, s, payload, 0.05 + 0.01 * s, 0.3 * (r - s), 0.0)
            for r in range(count) for s in range(count) if s != r for payload in sent[s]]


@pytest.mark.parametrize("profile", [KILOBOT, CRAZYFLIE], ids=["kilobot", "crazyflie"])
def test_control_steps_equals_robot_by_robot(profile) -> None:  # noqa: ANN001
    count = 5
    batch, single = swarm(profile, count), swarm(profile, count)
    sent: list[list[bytes]] = [[] for _ in range(count)]
    failed_seen = np.zeros(count, dtype=bool)
    for step in range(12):
        rows = all_to_all(sent, count)
        stepping = np.array([(i + step) % 4 != 0 for i in range(count)])
        result = control_steps(batch, PackedMessages.from_rows(rows), stepping)
        for receiver in range(count):
            mine = [(s, p, d, a, e) for r, s, p, d, a, e in rows if r == receiver]
            single[receiver].receive_all(mine)
        expected: list[list[bytes]] = [[] for _ in range(count)]
        for i in range(count):
            if stepping[i]:
                expected[i] = single[i].control_step()
        got: list[list[bytes]] = [[] for _ in range(count)]
        for k in range(len(result.outbox)):
            got[int(result.outbox.robots[k])].append(result.outbox.payload(k))
        assert got == expected
        for a, b in zip(batch, single, strict=True):
            assert Robot.comparable(a.snapshot()) == Robot.comparable(b.snapshot())
            assert (a.failure is None) == (b.failure is None)
        now_failed = np.array([r.failure is not None for r in batch])
        assert (result.failed == (now_failed & ~failed_seen)).all()
        failed_seen = now_failed
        sent = got
    # robots fail on the way (a full stigmergy on the Kilobot, the TYPE error of robot 2),
    # others run to the end: both kinds are compared above
    assert failed_seen.any() and not failed_seen.all()


def test_packed_messages_rows_must_be_sorted() -> None:
    with pytest.raises(ValueError, match="sorted"):
        PackedMessages.from_rows([(1, 0, b"x", 0, 0, 0), (0, 1, b"y", 0, 0, 0)])


def test_payload_keeps_wire_length_but_reads_at_most_nine_bytes() -> None:
    packed = PackedMessages.from_rows([(0, 3, bytes(range(12)), 1.0, 2.0, 3.0)])
    assert packed.lengths.tolist() == [12]
    assert packed.payload(0) == bytes(range(9))
    assert packed.tuples_of(0, 1) == [(3, bytes(range(9)), 1.0, 2.0, 3.0)]
    assert packed.bounds(3).tolist() == [0, 1, 1, 1]
