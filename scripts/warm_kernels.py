"""Compile the VM's machine code once, at set-up, so the first swarm a user opens starts at once.

The fast VM mode runs its hot loops as numba kernels cached on disk (`cache=True`, in
bbzide/vm/compiled/__pycache__/kernels-DIGEST, one folder per version of the kernels' sources:
see fastgc._kernel_sources_digest). Without a cache, the first control step of the
first swarm compiles them all: over a minute on an idle 2-core machine (125 machine codes, 77 s
measured) — long enough for a student running `make run` to think the IDE is broken. `make
setup` runs this once after installing: a few steps of each world's default example, of a
Kilobot script walking its neighbours (`neighbors.foreach`/`filter`/`reduce`, which the examples
do not use) and of a recorded run rebuilt as a replay rebuilds it (robots fed their recorded
messages from Python): together they reach every kernel the worlds, the IDE and the replay use,
so neither a user nor the test suite (whose parallel processes would each compile what is
missing, the same code at the same time) compiles one later. Later runs load the cached code in
about a second.
Without numba (an optional dependency) there is nothing to compile: it says so and stops.
Then it removes the caches of earlier kernel sources (a folder of 15-20 MB for each version a
pull or an edit brought), which nothing reads again.
"""

from __future__ import annotations

import shutil
import tempfile
import time
from pathlib import Path

from bbzide.vm import kernels
from bbzide.worlds.commands import load_script
from bbzide.worlds.engine import Simulation
from bbzide.worlds.registry import WORLDS

REPO = Path(__file__).resolve().parents[1]
#: Steps per world: the first step boots every robot and runs init, the next ones the
#: in-queue with received messages; three reach every kernel the examples use.
STEPS = 3
ROBOTS = 4


def main() -> None:
    if not kernels.COMPILED:
        print("numba is not installed: the VM's kernels run as plain Python (slower); "
              "nothing to compile", flush=True)
        return
    started = time.perf_counter()
    print("compiling the VM's machine code once (numba cache; a minute or more the first time)...",
          flush=True)
    for name, spec in WORLDS.items():
        run_briefly(name, REPO / spec.example)
    with tempfile.TemporaryDirectory() as folder:
        walk_neighbours(Path(folder))
        record_and_rebuild(Path(folder))
    print(f"done in {time.perf_counter() - started:.1f} s", flush=True)
    from numba import config

    removed = remove_stale_caches(Path(config.CACHE_DIR))
    if removed:
        print(f"removed {len(removed)} cache folder(s) of earlier kernel sources", flush=True)


#: A Kilobot walking its neighbours: the walks' kernels (fasthost.xtreme_walk, and
#: fasthost.add_functions for the table `filter` returns).
WALKING_SCRIPT = """
var near = 0
function init() { neighbors.listen("k", function(vid, value, rid) { near = value }) }
function step() {
  neighbors.broadcast("k", id)
  neighbors.foreach(function(rid, data) { near = near + data.distance })
  var close = neighbors.filter(function(rid, data) { return data.distance < 100 })
  near = close.reduce(function(rid, data, total) { return total + 1 }, 0)
}
"""


def run_briefly(world: str, script: Path) -> None:
    """`STEPS` steps of `ROBOTS` robots running `script` in `world`; a robot that failed (a
    kernel numba did not compile fails its robot) stops the set-up with its reason."""
    program = load_script(script, WORLDS[world].host_names, [])
    simulation = Simulation(world, program, robots=ROBOTS, seed=1, watch=())
    simulation.run(STEPS)
    if simulation.failures:
        state = simulation.failures[0]
        first_line = state.failure.message.splitlines()[0]
        raise SystemExit(f"warm-up: robot {state.robot_id} of {script.name} failed: "
                         f"{state.failure.reason}: {first_line[:300]}")


def walk_neighbours(folder: Path) -> None:
    script = folder / "walks.bzz"
    script.write_text(WALKING_SCRIPT)
    run_briefly("kilobot", script)


def record_and_rebuild(folder: Path) -> None:
    """Record a few steps of the Kilobot example, then rebuild a robot from the recording:
    the rebuild feeds it its recorded messages from Python (fastreceive.receive_all)."""
    from bbzide.recording.reader import read_recording
    from bbzide.recording.rebuild import RobotRebuilder
    from bbzide.recording.recorder import MissionRecorder, Recordable

    spec = WORLDS["kilobot"]
    program = load_script(REPO / spec.example, spec.host_names, [])
    recordable = Recordable()
    sim = Simulation("kilobot", program, robots=ROBOTS, seed=1, watch=(),
                     robot_factory=recordable.factory)
    path = folder / "warm.rrd"
    with MissionRecorder(path, sim, recordable) as recorder:
        for _ in range(STEPS):
            sim.step()
            recorder.record_step()
    RobotRebuilder(read_recording(path)).robot_at(0, STEPS)


def remove_stale_caches(current: Path) -> list[Path]:
    """Delete the `kernels-DIGEST` folders beside `current` (this version's cache) and return
    them: each holds the machine code of sources that no longer exist."""
    stale = [folder for folder in current.parent.glob("kernels-*")
             if folder.is_dir() and folder.resolve() != current.resolve()]
    for folder in stale:
        shutil.rmtree(folder, ignore_errors=True)
    return stale


if __name__ == "__main__":
    main()
