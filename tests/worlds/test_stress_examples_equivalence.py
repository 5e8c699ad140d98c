"""The examples that normally run only in the fast mode, run in the reference mode too.

Design: the fast mode (compiled kernels behind `bbzide/vm/kernels.py`) must leave every robot
exactly as the reference mode (``stress_gc=True``: the model's own Python, a collection
before every instruction, plain-Python table reads and first-fit scans) does. The corpus
and `test_fast_swarm_equivalence.py` check that on small scripts; here the shipped examples
that exercise the rest — the search-and-rescue mission, flocking, bidding, exploration,
packet loss, the asynchronous engine, the Kilobot's `delay` and the M300's `doze` — run the
same swarm twice, once per mode, and after every step every observable byte is compared:
the traffic counters and links, positions, headings, LED colours, failures; every robot's
whole state (`Robot.comparable(snapshot())`: heap bytes, stack, registers, queues,
neighbours, stigmergy) every `SNAPSHOT_EVERY` steps and at the end.

A few robots and a few hundred steps per example: the reference mode collects before every
instruction in Python, so it is two orders of magnitude slower than the fast one.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest

from bbzide.vm.robot import Robot
from bbzide.worlds.commands import load_script
from bbzide.worlds.engine import Simulation
from bbzide.worlds.registry import WORLDS

REPO = Path(__file__).resolve().parents[2]

#: each case runs the reference mode for hundreds of steps: a parallel run starts them first
pytestmark = pytest.mark.slow

#: whole robot states are compared this often (every step would double the run's time)
SNAPSHOT_EVERY = 25

#: a Kilobot that naps in `delay` (a different length per robot and step), gossips a
#: counter and shows it on its LED: naps shift which robots step when
KILOBOT_DELAY = """
var heard = 0
var t = 0
function init() {
  neighbors.listen("c", function(vid, value, rid) { heard = heard + value % 3 })
}
function step() {
  t = t + 1
  neighbors.broadcast("c", t + id)
  led(heard % 8)
  if (t % 5 == id % 5) { delay(100 * (id % 4 + 1)) }
  if (t % 7 == 0) { set_motor(100 * (t % 3), 80) }
}
"""

#: an M300 that takes off, flies to goals and dozes between them, sharing its position
M300_DOZE = """
var t = 0
var near = 0
function init() {
  takeoff()
  neighbors.listen("p", function(vid, value, rid) { near = near + 1 })
}
function step() {
  t = t + 1
  neighbors.broadcast("p", t)
  if (t % 9 == 1) {
    random_goal()
    doze(t % 4 + 1)
  }
}
"""


def _program(world: str, script: str | None, text: str | None, tmp_path: Path) -> Any:
    if text is not None:
        path = tmp_path / f"{world}.bzz"
        path.write_text(text)
    else:
        path = REPO / (script or WORLDS[world].example)
    return load_script(path, WORLDS[world].host_names, [])


def _factory(stress: bool) -> Any:
    def build(program: Any, profile: Any, robot_id: int, host_functions: Any) -> Robot:
        return Robot(program, profile, robot_id, host_functions=host_functions,
                     stress_gc=stress)

    return build


def _step_observation(sim: Simulation) -> list[bytes]:
    """What a step decided, as bytes: counters, links, motion, LEDs, failures."""
    stats = sim.stats
    seen = [np.ascontiguousarray(column, dtype=np.int64).tobytes()
            for column in (stats.sent, stats.received, stats.dropped, stats.bytes_sent,
                           stats.bytes_received)]
    seen.append(repr(sorted(sim.links)).encode())
    seen += [np.ascontiguousarray(array, dtype=np.float64).tobytes()
             for array in (sim.positions, sim.headings, sim.leds)]
    seen.append(repr([(s.failure_step, str(s.failure)) for s in sim.robots]).encode())
    return seen


def _states(sim: Simulation) -> list[bytes]:
    return [Robot.comparable(s.robot.snapshot()) for s in sim.robots]


CASES = [
    # (name, world, robots, script, inline text, world options, steps, asynchronous)
    ("sar", "m300", 3, "examples/sar/sar.bzz", None, {"size": 20.0}, 200, False),
    ("flocking", "m300", 3, "examples/m300/flocking.bzz", None, {}, 200, False),
    ("bidding", "crazyflie", 3, "examples/crazyflie/bidding.bzz", None, {}, 200, False),
    ("exploration", "crazyflie", 3, "examples/crazyflie/exploration.bzz", None, {}, 200,
     False),
    ("packet_loss", "crazyflie", 4, "examples/crazyflie/packet_loss.bzz", None, {}, 300,
     False),
    ("asynchronous", "kilobot", 5, "examples/kilobot/gradient.bzz", None,
     {"width": 0.3, "height": 0.3}, 200, True),
    ("kilobot_delay", "kilobot", 6, None, KILOBOT_DELAY, {"width": 0.3, "height": 0.3}, 300,
     False),
    ("m300_doze", "m300", 4, None, M300_DOZE, {"size": 20.0}, 300, False),
]


@pytest.mark.parametrize(("name", "world", "robots", "script", "text", "options", "steps",
                          "asynchronous"), CASES, ids=[case[0] for case in CASES])
def test_example_identical_in_both_modes(tmp_path: Path, name: str, world: str, robots: int,
                                         script: str | None, text: str | None,
                                         options: dict, steps: int,
                                         asynchronous: bool) -> None:
    program = _program(world, script, text, tmp_path)
    reference, fast = (Simulation(world, program, robots=robots, seed=7, world_options=options,
                                  robot_factory=_factory(stress), asynchronous=asynchronous,
                                  watch=())
                       for stress in (True, False))
    assert all(s.robot.vm.stress_gc for s in reference.robots)
    assert not any(s.robot.vm.stress_gc for s in fast.robots)
    start = reference.positions.copy()
    for step in range(steps):
        reference.step()
        fast.step()
        assert _step_observation(reference) == _step_observation(fast), (name, step)
        if step % SNAPSHOT_EVERY == 0 or step == steps - 1:
            assert _states(reference) == _states(fast), (name, step)
    # the run did something worth comparing: robots moved or messages went round (the
    # exploration example never broadcasts), Buzz code ran, no robot failed
    moved = not np.array_equal(start, reference.positions)
    assert moved or reference.totals["received"] > 0, name
    assert all(s.robot.vm.instructions_executed > 1000 for s in reference.robots), name
    assert all(s.failure is None for s in reference.robots), name
