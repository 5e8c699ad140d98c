"""A fingerprint of whole swarm runs: one sha256 per `world_bench` case after a few steps.

Design: a speed change in the engine, the radio or a world must not change what a run does.
This script runs each `world_bench.CASES` entry on its threads (and the 100 Kilobots
asynchronous) with a fixed seed for a fixed number of steps and prints
`tests/worlds/fingerprint.py`'s hash of everything the run decided, one line per case, to
compare runs before and after a change on the full-size swarms; a case on 2 threads prints
its 1-thread hash (`tests/worlds/test_determinism.py` does it on small ones).

    PYTHONPATH=. python benchmarks/world_fingerprint.py [steps, default 20]
"""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Any

from bbzide.vm import swarm_batch
from bbzide.worlds.commands import load_script
from bbzide.worlds.engine import Simulation
from bbzide.worlds.registry import WORLDS

REPO = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(REPO), str(REPO / "benchmarks")]

from world_bench import CASES  # noqa: E402 - benchmarks/ is not a package

from tests.worlds.fingerprint import fingerprint  # noqa: E402 - needs the repo on the path


def build(world: str, robots: int, script: str | None, options: dict[str, Any],
          seed: int = 1, **kwargs: Any) -> Simulation:
    """A case's simulation as `world_bench` builds it."""
    spec = WORLDS[world]
    program = load_script(REPO / (script or spec.example), spec.host_names, [])
    return Simulation(world, program, robots=robots, seed=seed, world_options=options,
                      watch=(), **kwargs)


def main() -> None:
    steps = int(sys.argv[1]) if len(sys.argv) > 1 else 20
    for world, robots, script, options, _, threads in CASES:
        label = f"{world} x {robots} {Path(script or WORLDS[world].example).stem}" + \
            ("" if threads == 1 else f", {threads} thr")  # the same hash as on 1 thread
        swarm_batch.set_threads(threads)
        print(f"{label:31} {fingerprint(build(world, robots, script, options), steps)}")
    swarm_batch.set_threads(1)
    # robots that move (the gradient stands still): the physics' fingerprint
    for robots, options in ((100, {}), (1000, {"width": 2.0, "height": 2.0})):
        sim = build("kilobot", robots, "examples/kilobot/aggregation.bzz", options)
        print(f"{f'kilobot x {robots} aggregation':31} {fingerprint(sim, steps)}")
    label = "kilobot x 100 asynchronous"
    sim = build("kilobot", 100, "examples/kilobot/gradient.bzz", {}, asynchronous=True)
    print(f"{label:31} {fingerprint(sim, steps)}")


if __name__ == "__main__":
    main()
