"""An M300's latched stores (goto, set_role, know_target) and drawn random goals (vm/host.py):
the same drones in both VM modes.

``goto`` is latched (``arrived()``, which reads its goal, goes to Python after it in a
step, also when the step went on in Python in between), ``set_role`` and ``know_target``
are latched once a step (a second call goes to Python; an out-of-range role is Python's
TYPE error), and ``random_goal`` is drawn: the compiled swarm step writes its next results
before a drone's kernel part and moves the drone's random stream on by the ones the kernel
took. A step ends on an int the kernel computes (``distance``, ``prior``, ``clock``), whose
host frame it drops without a collection. The script below calls each of them zero to many
times a step, mixes ``rand()`` (the same stream) in, and calls them from a listener too.
Each run is compared after every step with the reference mode (``stress_gc``: every host
function called in Python): each drone's VM state, and the world's state of every drone —
position, goal, flight mode, role, role changes counted, targets learnt, and its random
stream.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from bbzide.vm.host import DrawnHostFunction, LatchedHostFunction
from bbzide.worlds.engine import Simulation
from tests.worlds.m300_modes import compile_script, field, run_both

STORES_AND_DRAWS = """
var seen = 0
var goals = 0
function init() {
  takeoff()
  neighbors.listen("g", function(vid, value, rid) {
    var g = random_goal()                    # drawn inside a listener
    goals = goals + g.cell % 5
    if (value % 5 == 0) { set_role(value % 8) }
  })
}
function step() {
  var t = clock()
  var draws = (t + id) % 11                  # 0 to 10 a step: past the rows drawn ahead
  var i = 0
  while (i < draws) {
    var g = random_goal()
    goals = goals + g.x % 7 + g.y % 3 + g.cell % 11
    if (i == 3 and id % 2 == 0) { goals = goals + rand() % 4 }   # the same stream
    i = i + 1
  }
  if (t % 3 == 0) { goto(t % 12 * 10, id * 10) }
  if (t % 4 == 1) {
    goto(t % 7 * 10, 50)
    seen = seen + arrived()                  # reads the goal goto just stored
    goto(60, 60.5)                           # not an int: Python's goto
  }
  if (t % 4 == 2) {
    var here = position()
    if (t % 8 == 2) { goto(here.x, here.y) } else { goto(here.x + 40, here.y) }   # latched,
    var m = {}
    m.f = function(v) { return v }           # then an instruction Python runs (a method
    seen = seen + 3 * arrived()              # bound), then the goal read after it
  }
  set_role((t + id) % 8)
  if (id % 3 == 0) { set_role((t + 1) % 8) } # a second role change this step
  if (id == 4 and t == 9) { set_role(8) }    # no such role: TYPE
  know_target(t % 5 * 10, id * 10)
  if (id % 2 == 1) { know_target(t % 3 * 10 + 25, id * 10) }
  seen = seen + arrived() + flying()
  neighbors.broadcast("g", t + id)
  # a step ending on an int a kernel computes: no collection between it and the step's end
  if (id % 3 == 0) { return distance(t % 9, id, 3, 4) }
  if (id % 3 == 1) { return prior(t % 4) }
  return clock()
}
"""


def _world_state(sim: Simulation) -> tuple:
    world = sim.world
    return (sim.positions.tobytes(), world.goals.tobytes(), world.mode.tobytes(),
            list(world.roles), world.role_codes.tobytes(), world.rendezvous_returns.tobytes(),
            world.root_elections.tobytes(), world.auctions.tobytes(),
            repr(world.known_targets), sim.leds.tobytes(),
            [rng.bit_generator.state for rng in sim.robot_rngs])


def test_stores_and_draws_identical(tmp_path: Path) -> None:
    reference, fast = run_both(compile_script(tmp_path, STORES_AND_DRAWS), 24, 8,
                               _world_state)
    failures = {state.index: str(state.robot.failure) for state in fast.robots
                if state.robot.failure is not None}
    assert list(failures) == [4] and "TYPE" in failures[4], failures
    world = fast.world
    assert sum(len(known) for known in world.known_targets) > 8
    assert len(set(world.roles)) > 3
    assert any(state.global_value("goals") > 100 for state in fast.robots)


def test_stores_and_draws_run_in_place(monkeypatch: pytest.MonkeyPatch,
                                       tmp_path: Path) -> None:
    """With at most the rows drawn ahead a step, one role change and one target learnt, and
    no reading of the goal after goto, no call of these reaches Python in the fast mode."""
    calls = {"fast": 0, "reference": 0}
    mode = ["reference"]

    def counting(cls: type) -> None:
        original = cls.__call__

        def counted(self, call):  # noqa: ANN001, ANN202
            calls[mode[0]] += 1
            return original(self, call)

        monkeypatch.setattr(cls, "__call__", counted)

    counting(DrawnHostFunction)
    counting(LatchedHostFunction)
    text = """
function init() { takeoff() }
function step() {
  var t = clock()
  var i = 0
  while (i < (t + id) % 9) {                 # 0 to 8 draws: the rows drawn ahead
    var g = random_goal()
    i = i + 1
  }
  if (t % 3 == 0) { goto(t % 12 * 10, id * 10) }
  set_role(t % 8)
  know_target(t % 5 * 10, id * 10)
  doze(t % 2)
}
"""
    program = compile_script(tmp_path, text)
    states = []
    for stress, name in ((True, "reference"), (False, "fast")):
        mode[0] = name
        sim = field(program, 6, stress)
        sim.run(14)
        assert all(state.robot.failure is None for state in sim.robots)
        states.append(_world_state(sim))
    assert states[0] == states[1]
    assert calls["reference"] > 6 * 14 and calls["fast"] == 0, calls
