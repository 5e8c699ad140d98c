"""Readings and a latched doze (vm/host.py) on M300 drones: the same drones in both VM modes.

An M300's ``clock``, ``position``, ``flying``, ``arrived`` and ``camera`` are readings: the
compiled swarm step reads them before a drone's kernel part and the kernel pushes them in
place, and while Python finishes a handed-over step the kernels entered from Python push
them too, until the drone's first host call made in Python. ``doze`` is latched. Each
scenario runs the same field twice — drones in the reference mode (``stress_gc``: every
host function called in Python) and in the fast mode — and compares, after every step, each
drone's whole VM state and the world's state of every drone (position, goal, flight mode,
wake-up step).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from bbzide.vm.host import ReadingHostFunction
from bbzide.vm.robot import Robot
from bbzide.worlds.engine import Simulation
from tests.worlds.m300_modes import compile_script, field, run_both

READINGS = """
var v
var seen = 0
var log = 0
var arrivals = 0
var kept = {}
function init() {
  v = stigmergy.create(1)
  takeoff()
  neighbors.listen("p", function(vid, value, rid) {
    var p = position()                       # a reading inside a listener
    seen = seen + p.cell + clock() % 3
  })
}
function step() {
  var t = clock()
  var p = position()
  var c = camera()
  if (c != nil) { seen = seen + c.x % 5 }
  log = log + flying() + 2 * arrived() + p.x % 7 + p.z % 3
  neighbors.broadcast("p", t)
  if (id % 3 == 0 and t % 4 == 1) {
    v.put(id, t)                             # stigmergy: the next step is handed over
  }
  if (id % 4 == 1 and t > 3) {
    goto(p.x + 5, p.y)                       # a host call in Python: readings after it
    log = log + 4 * arrived() + flying()     # are the world's as it is now
    goto(p.x, p.y)
    arrivals = arrivals + arrived()
  }
  if (id == 2 and t > 6) {
    log = log + position(1).x                # an argument: Python's call
  }
  if (id == 5 and t > 8) {
    var i = 0
    while (i < 100) {                        # the heap runs out under a reading: MEM
      kept[i] = {.a = position(), .b = camera(), .c = clock()}
      i = i + 1
    }
  }
  if (id == 6) {
    doze(0.5)                                # not an int: the latched doze's Python path
  } else {
    doze(t % 3)
  }
}
"""


def _world_state(sim: Simulation) -> tuple:
    world = sim.world
    return (sim.positions.tobytes(), world.goals.tobytes(), world.mode.tobytes(),
            world.asleep_until.tobytes())


def test_readings_and_doze_identical(tmp_path: Path) -> None:
    """Readings in step and in a listener, after a stigmergy hand-over, after a Python
    goto in the same step, with an argument, without heap room; doze with an int and not."""
    reference, fast = run_both(compile_script(tmp_path, READINGS), 26, 9, _world_state)
    failures = {state.index: str(state.robot.failure) for state in fast.robots
                if state.robot.failure is not None}
    assert list(failures) == [5] and "MEM" in failures[5], failures
    assert fast.world.asleep_until.max() > fast.step_count - 3       # dozes were latched
    assert any(state.global_value("seen") > 40 for state in fast.robots)  # cameras saw
    assert any(state.global_value("log") > 0 for state in reference.robots)
    assert any(state.global_value("arrivals") > 0 for state in reference.robots)


def test_readings_run_in_place(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    """A step of readings, broadcasts and doze never calls a reading in Python in the fast
    mode (every call is the kernel's) and does in the reference mode."""
    calls = {"fast": 0, "reference": 0}
    mode = ["reference"]
    original = ReadingHostFunction.__call__

    def counted(self, call):  # noqa: ANN001, ANN202
        calls[mode[0]] += 1
        return original(self, call)

    monkeypatch.setattr(ReadingHostFunction, "__call__", counted)
    text = READINGS.split("  if (id % 3 == 0")[0] + "  doze(t % 2)\n}\n"
    program = compile_script(tmp_path, text)
    for stress, name in ((True, "reference"), (False, "fast")):
        mode[0] = name
        sim = field(program, 6, stress)
        sim.run(12)
        assert all(state.robot.failure is None for state in sim.robots)
    assert calls["reference"] > 6 * 12 and calls["fast"] == 0, calls


def test_readings_switched_off_with_latching_identical(tmp_path: Path) -> None:
    """`Robot.latch_host_calls = False` (a recorder logging every host call) sends the
    readings and doze to Python, with the same drones."""
    program = compile_script(tmp_path, READINGS)
    sims = [field(program, 6, False) for _ in range(2)]
    for state in sims[1].robots:
        state.robot.latch_host_calls = False
    for step in range(14):
        for sim in sims:
            sim.step()
        assert _world_state(sims[0]) == _world_state(sims[1]), step
        for a, b in zip(sims[0].robots, sims[1].robots, strict=True):
            assert Robot.comparable(a.robot.snapshot()) == Robot.comparable(b.robot.snapshot())
    assert np.any(sims[0].world.asleep_until > 0)


@pytest.mark.parametrize("size", [12.0, 40.0])
def test_missed_table_clamped_gives_every_flight_its_value(tmp_path: Path, size: float) -> None:
    """`missed(flown)` as a lookup (kernel: the argument clamped into the table) equals the
    world's computation for every int16 flight, negative ones and those past the table."""
    sim = Simulation("m300", compile_script(tmp_path, READINGS), robots=2, seed=4,
                     world_options={"size": size}, watch=())
    world = sim.world
    table = world.missed_values
    flights = np.arange(-32768, 32768)
    looked_up = table[np.clip(flights, 0, len(table) - 1)]
    step = 97  # every 97th flight, and the table's ends (the world's exp is per call)
    for flown in list(flights[::step]) + [len(table) - 2, len(table) - 1, len(table), 32767]:
        assert looked_up[flown + 32768] == world.miss_percent(int(flown)), flown
    assert 1 < len(table) < 32768 and table[-1] == 0
