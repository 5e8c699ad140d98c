"""Memory per robot: bytes of Python and numba state per Kilobot robot at 1,000 robots.

How it is measured: the kernels are compiled (or loaded) and the script compiled first, so
that neither the code nor numba's caches count; then ``tracemalloc`` traces every allocation
made while the 1,000-robot Kilobot simulation of the gradient example is built and runs
``STEPS`` steps (Python objects and numpy/numba arrays: numpy reports its buffers to
tracemalloc). The figure is the traced memory still held after the steps, divided by the
robots: the VMs (heap bytes, stacks, queues, neighbour rings), the packed arrays the compiled
swarm step works on, the world's per-robot state, the radio. The firmware's heap (the
Kilobot's 1,088 bytes, BBZHEAP_SIZE) is printed beside it.

    PYTHONPATH=. python benchmarks/memory_bench.py [robots, default 1000]
"""

from __future__ import annotations

import gc
import sys
import tracemalloc
from pathlib import Path

from bbzide.vm.profiles import PROFILES
from bbzide.worlds.commands import load_script
from bbzide.worlds.engine import Simulation
from bbzide.worlds.registry import WORLDS

REPO = Path(__file__).resolve().parents[1]
#: steps run before measuring: the queues, rings and packed arrays reach their working size
STEPS = 5
#: the arena of world_bench's 1,000-robot case (the same density)
OPTIONS = {"width": 2.0, "height": 2.0}


def main() -> None:
    robots = int(sys.argv[1]) if len(sys.argv) > 1 else 1000
    program = load_script(REPO / "examples/kilobot/gradient.bzz", WORLDS["kilobot"].host_names,
                          [])
    Simulation("kilobot", program, robots=2, seed=1, world_options=OPTIONS, watch=()).run(2)
    gc.collect()
    tracemalloc.start()
    sim = Simulation("kilobot", program, robots=robots, seed=1, world_options=OPTIONS,
                     watch=())
    sim.run(STEPS)
    gc.collect()
    held, peak = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    heap = PROFILES["kilobot"].heap_size
    print(f"kilobot x {robots} gradient, after {STEPS} steps (tracemalloc, allocations made "
          "while the simulation was built and run):")
    print(f"  held per robot: {held / robots:10,.0f} bytes (peak {peak / robots:,.0f})")
    print(f"  the firmware's heap per robot:  {heap:,} bytes (BBZHEAP_SIZE)")
    del sim


if __name__ == "__main__":
    main()
