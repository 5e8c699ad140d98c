"""Consensus time through the virtual stigmergy, 10 Crazyflies in a chain and in a circle
(thesis §4.6.2, Fig. 4.7: 20 tests alternating the two configurations, mean 56.8 ± 23.26 ms,
envelope 17-87 ms: consensus in one or two 50 ms control steps).

Runs examples/crazyflie/consensus.bzz with asynchronous drones (each its own phase within the
50 ms step, as real drones): drone 0 writes at step 5, every drone records the step at which it
first read the value; a drone's delay is (its step + its phase) - (5 + the writer's phase), and
a run's consensus time is the last drone's, in steps and in ms.

    PYTHONPATH=. python experiments/crazyflie_consensus.py [runs, default 20] [--jobs N]
        [--cluster ADDRESS]
"""

from __future__ import annotations

import math
import sys
from collections import Counter
from functools import partial

from common import compile_example, executor_from_argv, globals_of, mean_sd, run, table

from bbzide.worlds.executors import run_in_order

WRITE_STEP = 5
DRONES = 10


def consensus_time(formation: str, seed: int, program: object) -> float:
    """Steps (phases included) from the write to the last drone's first read; -1: never."""
    def everyone_agrees(sim: object) -> bool:
        return sim.step_count > WRITE_STEP and all(
            a is not None and a >= 0 for a in globals_of(sim, "agreed"))

    sim = run("crazyflie", program, DRONES, seed, WRITE_STEP + 40, {"formation": formation},
              until=everyone_agrees)
    agreed = globals_of(sim, "agreed")
    if any(a is None or a < 0 for a in agreed):
        return -1.0
    phases = sim.phases
    return max(a + phases[i] for i, a in enumerate(agreed)) - (WRITE_STEP + phases[0])


def _consensus_test(test: tuple[str, int], program: object) -> float:
    formation, seed = test
    return consensus_time(formation, seed=seed, program=program)


def main() -> None:
    executor, argv = executor_from_argv(sys.argv[1:])
    runs = int(argv[0]) if argv else 20
    program = compile_example("crazyflie", "examples/crazyflie/consensus.bzz")
    tests = [(("chain", "circle")[k % 2], k) for k in range(runs)]   # (formation, seed)
    with executor:
        delays = run_in_order(executor, partial(_consensus_test, program=program), tests,
                              [f"consensus-{formation}-seed{k}" for formation, k in tests])
    results: dict[str, list[float]] = {"chain": [], "circle": []}
    for (formation, _), delay in zip(tests, delays, strict=True):
        results[formation].append(delay)
    results["both"] = results["chain"] + results["circle"]
    step_ms = 50
    rows = []
    for formation, times in results.items():
        reached = [t for t in times if t >= 0]
        histogram = Counter(min(2, math.ceil(t)) for t in reached)
        rows.append([formation, len(times),
                     ", ".join(f"{k}: {histogram[k]}" for k in sorted(histogram)),
                     mean_sd([t * step_ms for t in reached]),
                     f"{min(reached) * step_ms:.0f}-{max(reached) * step_ms:.0f}",
                     len(times) - len(reached)])
    print(table(["configuration", "runs", "runs by control steps (1 = within one step)",
                 "mean ± sd (ms)", "range (ms)", "no consensus"], rows))
    print("\npaper (Fig. 4.7): 56.8 ± 23.26 ms, 17-87 ms, one or two control steps")


if __name__ == "__main__":
    main()
