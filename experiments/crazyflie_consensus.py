"""Consensus time through the virtual stigmergy, 10 Crazyflies in a chain and in a circle
(thesis §4.6.2, Fig. 4.7: 20 tests alternating the two configurations, mean 56.8 ± 23.26 ms,
envelope 17-87 ms: consensus in one or two 50 ms control steps).

Runs examples/crazyflie/consensus.bzz: drone 0 writes at step 5, every drone records the step
at which it first read the value; a run's consensus time is the last drone's.

    PYTHONPATH=. python experiments/crazyflie_consensus.py [runs, default 20]
"""

from __future__ import annotations

import sys
from collections import Counter

from common import compile_example, globals_of, mean_sd, run, table

WRITE_STEP = 5
DRONES = 10


def consensus_steps(formation: str, seed: int, program: object) -> int:
    def everyone_agrees(sim: object) -> bool:
        return sim.step_count > WRITE_STEP and all(
            a is not None and a >= 0 for a in globals_of(sim, "agreed"))

    sim = run("crazyflie", program, DRONES, seed, WRITE_STEP + 40, {"formation": formation},
              until=everyone_agrees)
    agreed = globals_of(sim, "agreed")
    if any(a is None or a < 0 for a in agreed):
        return -1
    return max(agreed) - WRITE_STEP


def main() -> None:
    runs = int(sys.argv[1]) if len(sys.argv) > 1 else 20
    program = compile_example("crazyflie", "examples/crazyflie/consensus.bzz")
    results: dict[str, list[int]] = {"chain": [], "circle": []}
    for k in range(runs):
        formation = ("chain", "circle")[k % 2]
        results[formation].append(consensus_steps(formation, seed=k, program=program))
    step_ms = 50
    rows = []
    for formation, steps in results.items():
        histogram = Counter(steps)
        rows.append([formation, len(steps),
                     ", ".join(f"{s} step(s): {histogram[s]}" for s in sorted(histogram)),
                     mean_sd([s * step_ms for s in steps if s >= 0]),
                     f"{min(steps) * step_ms}-{max(steps) * step_ms}"])
    every = results["chain"] + results["circle"]
    rows.append(["both", len(every), ", ".join(
        f"{s} step(s): {Counter(every)[s]}" for s in sorted(Counter(every))),
        mean_sd([s * step_ms for s in every if s >= 0]),
        f"{min(every) * step_ms}-{max(every) * step_ms}"])
    print(table(["configuration", "runs", "consensus time (control steps)", "mean ± sd (ms)",
                 "range (ms)"], rows))
    print("\npaper (Fig. 4.7): 56.8 ± 23.26 ms, 17-87 ms, one or two control steps")


if __name__ == "__main__":
    main()
