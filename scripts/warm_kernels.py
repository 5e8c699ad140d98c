"""Compile the VM's machine code once, at set-up, so the first swarm a user opens starts at once.

The fast VM mode runs its hot loops as numba kernels cached on disk (`cache=True`, in
bbzide/vm/compiled/__pycache__/kernels-DIGEST, one folder per version of the kernels' sources:
see fastgc._kernel_sources_digest). Without a cache, the first control step of the
first swarm compiles them all: about a minute on an idle 2-core machine (119 kernels, 65 s
measured) — long enough for a student running `make run` to think the IDE is broken. `make
setup` runs this once after installing: a few steps of each world's default example, which
reaches every kernel a world run uses; later runs load the cached code in about a second.
Without numba (an optional dependency) there is nothing to compile: it says so and stops.
Then it removes the caches of earlier kernel sources (a folder of 15-20 MB for each version a
pull or an edit brought), which nothing reads again.
"""

from __future__ import annotations

import shutil
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
    print("compiling the VM's machine code once (numba cache; about a minute the first time)...",
          flush=True)
    for name, spec in WORLDS.items():
        program = load_script(REPO / spec.example, spec.host_names, [])
        Simulation(name, program, robots=ROBOTS, seed=1, watch=()).run(STEPS)
    print(f"done in {time.perf_counter() - started:.1f} s", flush=True)
    from numba import config

    removed = remove_stale_caches(Path(config.CACHE_DIR))
    if removed:
        print(f"removed {len(removed)} cache folder(s) of earlier kernel sources", flush=True)


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
