"""The engine's lockstep step written the slow, readable way: a test oracle.

Design: `ReferenceSimulation` is a `Simulation` whose `step` is the per-robot loop the engine
had before it handed the VM phase to `swarm_batch.control_steps` — each robot's
deliveries as tuples, `receive_all` (or `receive` one by one), `world.is_asleep` and
`control_step` robot by robot, counters added robot by robot — over the tuple radio of
`reference_radio.py`. `test_determinism.py` requires the real engine to decide every run the
same way.
"""

from __future__ import annotations

import time

import numpy as np

from bbzide.worlds.engine import Simulation, StepStats
from bbzide.worlds.radio import TrafficCounters
from tests.worlds.reference_radio import ReferenceRadio


class ReferenceSimulation(Simulation):
    """A lockstep `Simulation` stepped robot by robot (see the module doc)."""

    def _reset_world(self) -> None:
        super()._reset_world()
        self.radio = ReferenceRadio(self.world.radio, self.count, self.world.step_seconds,
                                    self.rng["loss"], self.rng["noise"])

    def step(self) -> StepStats:
        assert not self.asynchronous, "the reference is the lockstep engine"
        step = self.step_count
        counters = TrafficCounters.zeros(self.count)
        self.world.sense(self)
        robots = self.robots
        for receiver, deliveries in enumerate(self.radio.due(step)):
            if not deliveries:
                continue
            state = robots[receiver]
            if not state.alive:
                counters.dropped[receiver] += len(deliveries)
                continue
            robot = state.robot
            receive_all = getattr(robot, "receive_all", None)
            if receive_all is not None:
                receive_all(deliveries)
            else:
                for _, message, distance, azimuth, elevation in deliveries:
                    robot.receive(message, distance, azimuth, elevation)
            counters.received[receiver] += len(deliveries)
            counters.bytes_received[receiver] += sum(len(d[1]) for d in deliveries)
        for state in robots:
            if not state.alive or self.world.is_asleep(state.index, step):
                continue
            outgoing = state.robot.control_step()
            if state.robot.failure is not None:
                self._check_failure(state)
                continue
            if outgoing:
                self.radio.enqueue(state.index, outgoing, counters)
        listening = np.fromiter((s.alive for s in robots), dtype=bool, count=self.count)
        self._set_links(self.radio.transmit(step, self.positions, self.headings, listening,
                                            counters))
        started = time.perf_counter()
        self.world.advance(self, self.world.step_seconds)
        self.timings["physics"] += time.perf_counter() - started
        return self._finish_step(step, counters)
