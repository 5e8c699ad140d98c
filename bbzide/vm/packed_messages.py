"""A control step's messages as columns: the deliveries a world engine hands to a swarm and
the outbox it gets back (`swarm_batch.control_steps`, the radio, the input log).

Rows of (robot index, payload bytes, wire length), plus for deliveries the situated data of
each row (distance, azimuth, elevation). The same type carries a step's deliveries (row =
receiver, rows sorted by receiver, each receiver's rows in arrival order) and a step's
outbox (row = sender, rows sorted by sender, each sender's rows in out-queue order). A
payload is at most `message_layout.PAYLOAD_SIZE` bytes as a VM reads it (a robot's receive
reads no more); `lengths` keeps the wire length for the radio's byte counters.

Plain data over numpy, importing nothing of the model's routines: both the reference swarm
step and the compiled one (`compiled/swarm_batch_fast.py`) build these.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from bbzide.vm.message_layout import PAYLOAD_SIZE


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
