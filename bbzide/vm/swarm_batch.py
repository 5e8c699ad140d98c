"""One control step of many robots' firmware loops at once: the swarm's side of the VM room.

Design: a world engine steps every robot each control step — each robot takes the messages
the radio delivered to it (`Robot.receive_all`), then runs its firmware loop once
(`Robot.control_step`: in-queue, ``step``, out-queue) — and collects what they sent. Done
robot by robot from Python, the calls around the VM cost more than the VM itself for a
1,000-Kilobot table (issue #4), so the engine hands the whole step over in one call,
`control_steps`, with the messages as columns instead of a tuple per message:

* `PackedMessages` — rows of (robot index, payload bytes, wire length), plus for deliveries
  the situated data of each row (distance, azimuth, elevation). The same type carries a
  step's deliveries (row = receiver, rows sorted by receiver, each receiver's rows in
  arrival order) and a step's outbox (row = sender, rows sorted by sender, each sender's
  rows in out-queue order). A payload is at most `messages.PAYLOAD_SIZE` bytes as a VM reads
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
from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np

from bbzide.vm.messages import PAYLOAD_SIZE


class SteppableRobot(Protocol):
    """What `control_steps` needs of a robot (`Robot`, or a wrapper such as a recorder's)."""

    failure: Any

    def receive_all(self, deliveries: Sequence[tuple[Any, bytes, float, float, float]]
                    ) -> None: ...

    def control_step(self) -> list[bytes]: ...


@dataclass(frozen=True, slots=True)
class PackedMessages:
    """Messages of one control step as columns, one row per message (see the module doc)."""

    robots: np.ndarray      # int64[n]: receiver (deliveries) or sender (outbox) index, sorted
    payloads: np.ndarray    # uint8[n, PAYLOAD_SIZE]: the first PAYLOAD_SIZE bytes, zero-padded
    lengths: np.ndarray     # int64[n]: wire length in bytes (may exceed PAYLOAD_SIZE)
    senders: np.ndarray     # int64[n]: sender index of a delivery (= robots in an outbox)
    distances: np.ndarray   # float64[n]: situated data of a delivery (zeros in an outbox)
    azimuths: np.ndarray    # float64[n]
    elevations: np.ndarray  # float64[n]

    def __len__(self) -> int:
        return len(self.robots)

    @classmethod
    def empty(cls) -> PackedMessages:
        ints, floats = np.empty(0, dtype=np.int64), np.empty(0, dtype=np.float64)
        return cls(ints, np.empty((0, PAYLOAD_SIZE), dtype=np.uint8), ints, ints,
                   floats, floats, floats)

    @classmethod
    def from_rows(cls, rows: Sequence[tuple[int, int, bytes, float, float, float]]
                  ) -> PackedMessages:
        """From (robot, sender, payload, distance, azimuth, elevation) rows, already sorted
        by robot (the slow, readable way; tests and adapters use it)."""
        n = len(rows)
        if n == 0:
            return cls.empty()
        payloads = np.zeros((n, PAYLOAD_SIZE), dtype=np.uint8)
        for k, (_, _, payload, _, _, _) in enumerate(rows):
            head = bytes(payload[:PAYLOAD_SIZE])
            payloads[k, :len(head)] = np.frombuffer(head, dtype=np.uint8)
        robots = np.array([r[0] for r in rows], dtype=np.int64)
        if np.any(np.diff(robots) < 0):
            raise ValueError("PackedMessages rows must be sorted by robot index")
        return cls(robots, payloads, np.array([len(r[2]) for r in rows], dtype=np.int64),
                   np.array([r[1] for r in rows], dtype=np.int64),
                   np.array([r[3] for r in rows], dtype=np.float64),
                   np.array([r[4] for r in rows], dtype=np.float64),
                   np.array([r[5] for r in rows], dtype=np.float64))

    def payload(self, row: int) -> bytes:
        """Row `row`'s payload as a VM reads it (at most PAYLOAD_SIZE bytes)."""
        return self.payloads[row, :min(int(self.lengths[row]), PAYLOAD_SIZE)].tobytes()

    def bounds(self, count: int) -> np.ndarray:
        """int64[count + 1]: robot i's rows are ``bounds[i]:bounds[i + 1]``."""
        return np.searchsorted(self.robots, np.arange(count + 1, dtype=np.int64))

    def tuples_of(self, start: int, stop: int) -> list[tuple[int, bytes, float, float, float]]:
        """Rows start:stop as the (sender, payload, distance, azimuth, elevation) tuples of
        `Robot.receive_all`."""
        return [(int(self.senders[k]), self.payload(k), float(self.distances[k]),
                 float(self.azimuths[k]), float(self.elevations[k]))
                for k in range(start, stop)]


@dataclass(frozen=True, slots=True)
class StepResult:
    """What `control_steps` returns: the step's outbox and who failed during it."""

    outbox: PackedMessages
    failed: np.ndarray  # bool[count]: failure was set during this call


def control_steps(robots: Sequence[SteppableRobot | None], deliveries: PackedMessages,
                  stepping: np.ndarray, reference: bool | None = None) -> StepResult:
    """Deliver `deliveries`, then one control step of each robot i with `stepping[i]`.

    `robots[i]` may be None (a slot without a VM, e.g. a passive target); deliveries to it
    are ignored (the engine counts them). The compiled path (`swarm_batch_fast`) unless
    `reference` (default: the module's `REFERENCE`) or numba is missing.
    """
    if reference is None:
        reference = REFERENCE
    if not reference and _fast_available():
        from bbzide.vm.compiled import swarm_batch_fast

        return swarm_batch_fast.control_steps(robots, deliveries, stepping)
    return control_steps_reference(robots, deliveries, stepping)


def _fast_available() -> bool:
    from bbzide.vm.compiled import fastbatch

    return fastbatch.COMPILED


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
