"""Small Kilobot swarms for the debugger tests: a script written to a temporary file (the
debugger maps lines through the script's text), compiled for the Kilobot table, 5 robots
close enough to hear each other from the second step on."""

from __future__ import annotations

from pathlib import Path

from bbzide.worlds.engine import Simulation
from bbzide.worlds.registry import WORLDS
from bbzide.worlds.scripts import load_script

#: A script whose line numbers the tests name (line 1 is `var total = 0`): a function call,
#: a listener, a `neighbors.foreach` closure and host calls.
STEPPING_SCRIPT = """\
var total = 0
var seen = 0
function add(x) {
  var doubled = x * 2
  return doubled + 1
}
function init() {
  neighbors.listen("v", function(vid, value, rid) {
    seen = seen + value
  })
}
function step() {
  total = add(id)
  neighbors.foreach(function(rid, data) {
    total = total + 1
  })
  neighbors.broadcast("v", id)
  led(total % 7)
}
"""

#: Robot 2 fails with a TYPE error on line 8 in its third control step (step 2).
ERROR_SCRIPT = """\
var count = 0
var broken = nil
function init() {
}
function step() {
  count = count + 1
  if (id == 2 and count == 3) {
    count = broken(count)
  }
}
"""

#: robots on a 0.2 m table: every Kilobot is within radio range of every other
ROBOTS = 5
TABLE = {"width": 0.2, "height": 0.2}


def swarm(tmp_path: Path, script: str, robots: int = ROBOTS, seed: int = 1,
          asynchronous: bool = False, name: str = "swarm.bzz") -> Simulation:
    path = tmp_path / name
    path.write_text(script)
    program = load_script(path, WORLDS["kilobot"].host_names, [])
    return Simulation("kilobot", program, robots=robots, seed=seed, world_options=TABLE,
                      watch=(), asynchronous=asynchronous)
