"""A fingerprint of a swarm run: one sha256 of everything the run decided.

Design: a speed change in the engine, the radio or a world must not change what a run does,
so a run is hashed whole — the traffic counters and links of every step, then every robot's
VM state (`Robot.comparable(snapshot())`: decoded states, not snapshot bytes), failures,
positions, headings, LED colours and the totals. `test_determinism.py` compares fingerprints
of two runs; `benchmarks/world_fingerprint.py` prints one per `world_bench` case so a change
can be checked on the full-size swarms.
"""

from __future__ import annotations

import hashlib

import numpy as np

from bbzide.vm.robot import Robot
from bbzide.worlds.engine import Simulation


def fingerprint(sim: Simulation, steps: int) -> str:
    """Run `steps` steps of `sim` and hash everything the run decided (see the module doc)."""
    digest = hashlib.sha256()
    for _ in range(steps):
        stats = sim.step()
        for column in (stats.sent, stats.received, stats.dropped, stats.bytes_sent,
                       stats.bytes_received):
            digest.update(np.ascontiguousarray(column, dtype=np.int64).tobytes())
        digest.update(repr(sorted(sim.links)).encode())
    for state in sim.robots:
        robot = state.robot
        if robot is not None and hasattr(robot, "snapshot"):
            digest.update(Robot.comparable(robot.snapshot()))
        failure = state.failure
        digest.update(repr((state.failure_step, getattr(failure, "reason", None),
                            getattr(failure, "pc", None))).encode())
    for array in (sim.positions, sim.headings, sim.leds):
        digest.update(np.ascontiguousarray(array, dtype=np.float64).tobytes())
    digest.update(repr(sorted(sim.totals.items())).encode())
    return digest.hexdigest()
