"""One control step of many robots' firmware loops at once: the swarm's side of the VM room.

Design: a world engine steps every robot each control step — each robot takes the messages
the radio delivered to it (`Robot.receive_all`), then runs its firmware loop once
(`Robot.control_step`: in-queue, ``step``, out-queue) — and collects what they sent. Done
robot by robot from Python, the calls around the VM cost more than the VM itself for a
1,000-Kilobot table (benchmarks/world_bench.py), so the engine hands the whole step over in
one call, `control_steps`, with the messages as columns instead of a tuple per message:

* `PackedMessages` — rows of (robot index, payload bytes, wire length), plus for deliveries
  the situated data of each row (distance, azimuth, elevation). The same type carries a
  step's deliveries (row = receiver, rows sorted by receiver, each receiver's rows in
  arrival order) and a step's outbox (row = sender, rows sorted by sender, each sender's
  rows in out-queue order; the type lives in `packed_messages`). A payload is at most
  `message_layout.PAYLOAD_SIZE` bytes as a VM reads
  it (a robot's receive reads no more); `lengths` keeps the wire length for the radio's byte
  counters.
* `control_steps(robots, deliveries, stepping)` — every robot with deliveries receives
  them, in receiver order, then every robot with `stepping[i]` runs one control step, in
  index order; returns the outbox and which robots failed during the call.

This file is the contract and the reference implementation (`control_steps_reference`):
plain calls of each robot's own methods, obviously right. `control_steps` takes the
compiled path (`swarm_batch_fast`) unless asked for the reference (`reference=True`, or
`REFERENCE = True` for every call, like clox's DEBUG_STRESS_GC); that path leaves every
robot in the same state and returns the same outbox (tested against this one:
tests/worlds/test_fast_swarm_equivalence.py). Receiving everything before stepping
anyone is equivalent to receiving and stepping robot by robot: a robot's receive touches
only its own VM, never a host function, so no robot's step can observe another's receive.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any, Protocol

import numpy as np

from bbzide.vm import kernels
from bbzide.vm.packed_messages import PackedMessages, StepResult
from bbzide.vm.robot import Robot


class SteppableRobot(Protocol):
    """What `control_steps` needs of a robot (`Robot`, or a wrapper such as a recorder's)."""

    failure: Any

    def receive_all(self, deliveries: Sequence[tuple[Any, bytes, float, float, float]]
                    ) -> None: ...

    def control_step(self) -> list[bytes]: ...


def control_steps(robots: Sequence[SteppableRobot | None], deliveries: PackedMessages,
                  stepping: np.ndarray, reference: bool | None = None) -> StepResult:
    """Deliver `deliveries`, then one control step of each robot i with `stepping[i]`.

    `robots[i]` may be None (a slot without a VM, e.g. a passive target); deliveries to it
    are ignored (the engine counts them). The compiled path (`swarm_batch_fast`) unless
    `reference` (default: the module's `REFERENCE`) or numba is missing.
    """
    if reference is None:
        reference = REFERENCE
    if not reference and kernels.COMPILED:
        return kernels.swarm_batch_fast.control_steps(robots, deliveries, stepping, Robot)
    return control_steps_reference(robots, deliveries, stepping)


def set_threads(count: int) -> None:
    """The threads the compiled path splits each later swarm step over (robots in
    contiguous index ranges, each range's kernel part on its own thread; the results do
    not depend on the count). Without numba there is one: the reference path is Python."""
    if count < 1:
        raise ValueError(f"a swarm step needs at least 1 thread, not {count}")
    if kernels.COMPILED:
        kernels.swarm_batch_fast.set_threads(count)


def control_steps_reference(robots: Sequence[SteppableRobot | None],
                            deliveries: PackedMessages, stepping: np.ndarray) -> StepResult:
    """`control_steps` by plain calls of each robot's own methods (see the module doc)."""
    count = len(robots)
    before = np.fromiter((r is not None and r.failure is not None for r in robots),
                         dtype=bool, count=count)
    bounds = deliveries.bounds(count).tolist()
    for index in np.flatnonzero(np.diff(bounds)).tolist():
        robot = robots[index]
        if robot is not None:
            robot.receive_all(deliveries.tuples_of(bounds[index], bounds[index + 1]))
    rows: list[tuple[int, int, bytes, float, float, float]] = []
    for index in np.flatnonzero(stepping).tolist():
        robot = robots[index]
        if robot is None:
            continue
        for payload in robot.control_step():
            rows.append((index, index, payload, 0.0, 0.0, 0.0))
    after = np.fromiter((r is not None and r.failure is not None for r in robots),
                        dtype=bool, count=count)
    return StepResult(PackedMessages.from_rows(rows), after & ~before)

#: True: `control_steps` always takes the reference path (tests, benchmarks compare the two)
REFERENCE = False
