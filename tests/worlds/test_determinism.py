"""Same seed, same run: two fresh runs of each world agree on everything a run decides
(`fingerprint.py`), and the engine (packed radio, `swarm_batch.control_steps`) decides
lockstep runs exactly as the robot-by-robot reference (`reference_engine.py`) does."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest

from bbzide.vm.messages import PAYLOAD_SIZE
from bbzide.worlds.commands import load_script
from bbzide.worlds.engine import Simulation
from bbzide.worlds.registry import WORLDS
from tests.worlds.doubles import FakeFailure, ScriptedRobot, factory
from tests.worlds.fingerprint import fingerprint
from tests.worlds.reference_engine import ReferenceSimulation

REPO = Path(__file__).resolve().parents[2]

#: (world, robots, script, world options, steps): the world_bench cases, shrunk to keep the
#: test quick, and another Kilobot example
CASES = {
    "kilobot gradient": ("kilobot", 30, "examples/kilobot/gradient.bzz", {}, 12),
    "kilobot firefly": ("kilobot", 20, "examples/kilobot/firefly.bzz", {}, 12),
    "crazyflie consensus": ("crazyflie", 6, "examples/crazyflie/consensus.bzz", {}, 12),
    "m300 flocking": ("m300", 8, None, {}, 12),
    "m300 sar": ("m300", 6, "examples/sar/sar.bzz", {"size": 20.0}, 55),
}


def build(case: str, kind: type[Simulation] = Simulation, seed: int = 1,
          **kwargs: Any) -> Simulation:
    world, robots, script, options, _ = CASES[case]
    spec = WORLDS[world]
    program = load_script(REPO / (script or spec.example), spec.host_names, [])
    return kind(world, program, robots=robots, seed=seed, world_options=options, watch=(),
                **kwargs)


@pytest.mark.parametrize("case", sorted(CASES))
def test_engine_equals_robot_by_robot_reference(case: str) -> None:
    steps = CASES[case][4]
    fast = build(case)
    assert fingerprint(fast, steps) == fingerprint(build(case, ReferenceSimulation), steps)
    assert fast.totals["received"] > 0           # messages flowed


def test_same_seed_same_run_other_seed_differs() -> None:
    steps = CASES["kilobot gradient"][4]
    first = fingerprint(build("kilobot gradient"), steps)
    assert first == fingerprint(build("kilobot gradient"), steps)
    assert first != fingerprint(build("kilobot gradient", seed=2), steps)


def test_asynchronous_runs_repeat() -> None:
    runs = [fingerprint(build("kilobot gradient", asynchronous=True), 8) for _ in range(2)]
    assert runs[0] == runs[1]


def restless(robot: ScriptedRobot, step: int) -> list[bytes]:
    """Bursts that overflow the Kilobot's send queue, `delay` naps, motion, and robot 3
    failing at its step 5: the engine's less travelled paths."""
    rid = robot.robot_id
    if rid == 3 and step == 5:
        robot.failure = FakeFailure("MEM", pc=7)
        return [b"lost"]
    if (rid + step) % 6 == 0:
        robot.call("delay", 250)
    robot.call("motion", (rid + step) % 4)
    return [bytes([rid, step % 256, k]) * (1 + k % 5) for k in range((rid * step) % 5)]


def test_scripted_swarm_equals_reference() -> None:
    def run(kind: type[Simulation]) -> tuple[str, list, list, int]:
        sim = kind("kilobot", program="p", robots=16, seed=4, robot_factory=factory(restless),
                   radio={"receive_cap_per_step": 3})
        # a robot reads at most PAYLOAD_SIZE bytes of a message: the packed radio carries
        # no more (the wire length still counts in the bytes)
        return (fingerprint(sim, 20), [[(m[:PAYLOAD_SIZE], *situated)
                                        for m, *situated in s.robot.inbox] for s in sim.robots],
                [(s.index, s.failure_step) for s in sim.failures], sim.totals["dropped"])

    fast, reference = run(Simulation), run(ReferenceSimulation)
    assert fast == reference
    # robot 3 fails at its own step 5, a sim step later than 5 (it napped in `delay`)
    assert sum(map(len, fast[1])) > 0 and fast[2] == [(3, 7)] and fast[3] > 0
