"""The table library's ``foreach`` walked inside the compiled swarm step
(``fasthost.run_walking``): the same drones in both VM modes.

A control step's ``foreach(t, f)`` runs in the swarm step's machine code. A walk that meets
something the kernels leave to Python — a host function only Python computes, a walk inside
the walk, a stigmergy, an error — puts back everything it wrote (heap, stack, out-queue,
latches, the random goals it took) and hands the whole call to Python. Each script below
runs in both modes, compared after every step, and the test counts the drones whose step
Python finished: none where the kernel covers the walk, some where it hands the walk over
after elements that already broadcast, latched a call, took goals and stored numbers.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from bbzide.vm.robot import Robot
from bbzide.worlds.engine import Simulation
from tests.worlds.m300_modes import compile_script, run_both

#: the walk: a listener fills `heard` (robot id -> position code); each element's call
#: stores numbers in globals, computes a distance in place, takes a random goal drawn ahead,
#: broadcasts and latches a goto; STOP is the element's last statement, run on the third
#: element of a step
WALK = """
var heard = {}
var t = 0
var walked = 0
var near = 0
var gx = 0
var v = nil
var inner = {}
function init() {
  takeoff()
  v = stigmergy.create(1)
  inner[1] = 5
  neighbors.listen("p", function(topic, code, rid) { heard[rid] = code })
}
function visit(rid, code) {
  var d = distance(id * 10, 0, code, 0)
  walked = walked + 1
  if (d < 40) { near = near + 1 }
  gx = gx + (code - d) % 7 + random_goal().x % 5
  neighbors.broadcast("w", walked)
  goto(gx % 50, d % 50)
  if (walked % 5 == 3) {
    STOP
  }
}
function step() {
  t = clock()
  neighbors.broadcast("p", id * 10 + t % 10)
  foreach(heard, visit)
  doze(1)
}
"""

#: what the third element of a step does, and whether the kernel can do it
STOPS = {
    "covered": ("near = near + 1", False),
    "a host function only Python computes": ("near = near + rand() % 3", True),
    "a walk inside the walk": ("foreach(inner, function(k, x) { near = near + x })", True),
    "a stigmergy put": ("v.put(1, walked)", True),
}


def _world_state(sim: Simulation) -> tuple:
    return sim.positions.tobytes(), sim.leds.tobytes()


def _count_python_finishes(monkeypatch: pytest.MonkeyPatch) -> list[int]:
    """Counts the calls of `Robot.finish_compiled_step` (a step the swarm step handed to
    Python), in a one-element list."""
    finished = [0]
    finish = Robot.finish_compiled_step

    def counted(self: Robot, *args: object) -> object:
        finished[0] += 1
        return finish(self, *args)

    monkeypatch.setattr(Robot, "finish_compiled_step", counted)
    return finished


@pytest.mark.parametrize("stop", sorted(STOPS))
def test_a_walk_is_identical_in_both_modes(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                           stop: str) -> None:
    statement, handed_over = STOPS[stop]
    finished = _count_python_finishes(monkeypatch)
    program = compile_script(tmp_path, WALK.replace("STOP", statement))
    _reference, fast = run_both(program, 12, 4, _world_state)
    for state in fast.robots:
        assert state.robot.failure is None, state.index
        assert state.global_value("walked") >= 10, state.index  # the neighbours, each step
    if handed_over:
        assert finished[0] > 0
    else:
        assert finished[0] == 0


def test_an_error_inside_a_walk_fails_the_drone_as_the_reference_does(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    finished = _count_python_finishes(monkeypatch)
    program = compile_script(tmp_path, WALK.replace("STOP", "if (t > 6) { missing(1) }"))
    reference, fast = run_both(program, 12, 4, _world_state)
    assert finished[0] > 0
    for a, b in zip(reference.robots, fast.robots, strict=True):
        assert b.robot.failure is not None, b.index
        assert str(a.robot.failure) == str(b.robot.failure)
