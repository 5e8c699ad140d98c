"""Compile the VM's machine code once, at set-up, so the first swarm a user opens starts at once.

The fast VM mode runs its hot loops as numba kernels cached on disk (`cache=True`, in
bbzide/vm/compiled/__pycache__/kernels-DIGEST, one folder per version of the kernels' sources:
see fastgc._kernel_sources_digest). Without a cache, the first control step of the
first swarm compiles them all: about a minute on an idle 2-core machine (119 kernels, 65 s
measured) — long enough for a student running `make run` to think the IDE is broken. `make
setup` runs this once after installing: a few steps of each world's default example, which
reaches every kernel a world run uses; later runs load the cached code in about a second.
Without numba (an optional dependency) there is nothing to compile: it says so and stops.
"""

from __future__ import annotations

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


if __name__ == "__main__":
    main()
