"""Numbers one slot alone holds (``fastgc.OWNED``) in a swarm step: the same drones in both
VM modes.

A collection says which numbers it meets once, as a leaf of a table it walks from the
permanent roots: a global's, a table's or a frame's local. Overwriting or removing that
slot then frees the number without a collection (``gstore``, ``tput``, ``lremove``), and
any other reference to it — a push, a walk's argument, a frame's local, a stigmergy entry —
takes the mark back. The script below makes each of them happen next to the others: a
listener that overwrites its neighbours' entries (as the flocking example does), a table
walk over them whose elements store into globals, locals that outlive a call only in a
global, and stigmergy puts and gets of stored and local numbers (the compiled ``v.put``
and ``v.get`` collect in the middle of their call, with the call's arguments in its frame).
Each run is compared after every step with the reference mode.
"""

from __future__ import annotations

from pathlib import Path

from bbzide.worlds.engine import Simulation
from tests.worlds.m300_modes import compile_script, run_both

OWNED_NUMBERS = """
var heard = {}
var when = {}
var sum = 0
var last = 0
var v = nil
var calls = 0
var walked = 0
function init() {
  takeoff()
  v = stigmergy.create(1)
  neighbors.listen("n", function(topic, value, rid) {
    heard[rid] = (value / 8) * 3           # the old entry is this slot's alone: freed
    calls = calls + 1
    when[rid] = last                       # a number many entries share: not freed
    if (value % 4 == 0) { heard[rid] = heard[rid] + 1 }
  })
}
function add(rid, x) {
  var d = x * 2                            # a local: freed when the function ends
  walked = walked + 1
  if (d % 3 == 0) {
    var e = d + rid
    sum = sum + e % 7                      # a global's number read, then replaced
    last = e                               # e outlives the call in a global
  }
  sum = sum + d % 5
}
function step() {
  var t = clock()
  last = t
  foreach(heard, add)                      # the entries as a walk's arguments
  var mine = t * 3 + id
  v.put(id % 3, mine)                      # a local's number into the stigmergy
  v.put(3, sum % 50)                       # a global's number too
  var got = v.get((t + id) % 4)
  if (got != nil) { sum = sum + got % 11 }
  heard[100 + id] = mine                   # a local's number into a table
  if (t % 3 == 0) { heard[100 + id] = nil }
  neighbors.broadcast("n", t + id * 5)
  if (id % 2 == 0) { return sum }          # a step ending on a global's number
}
"""


def _world_state(sim: Simulation) -> tuple:
    return sim.positions.tobytes(), sim.leds.tobytes()


def test_owned_numbers_identical(tmp_path: Path) -> None:
    _reference, fast = run_both(compile_script(tmp_path, OWNED_NUMBERS), 16, 5, _world_state)
    assert all(state.robot.failure is None for state in fast.robots)
    for state in fast.robots:  # each drone heard the others, walked their entries, added
        assert state.global_value("calls") > 20, state.index
        assert state.global_value("walked") > 20, state.index
        assert state.global_value("sum") > 20, state.index
