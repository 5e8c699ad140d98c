"""Estimated step times of the Crazyflie examples beside the thesis' Table 4.3 (§4.5: min, mean
and max time step in ms on the Crazyflie, "without timing constraints": exploration 12 /
68.74 ± 9.66 / 110, VS 1 / 3.83 ± 1.08 / 13, neighbour queries 2 / 5.92 ± 0.56 / 9).

Runs each example in the Crazyflie lab with the drone count of its experiment and estimates
every robot-step's duration from the model's exact counts (bbzide.worlds.steptime) on the
Crazyflie cost model (scaled from the Kilobot's measured one: a factor 2 either way) and, for
comparison, the Kilobot's (measured). The paper's times include what the model does not see:
the host functions' own work (sensor reads, the commander), FreeRTOS scheduling and the
radio stack, which the paper names as the cause of its jitter.

    PYTHONPATH=. python experiments/crazyflie_steptime.py [steps, default 200]
"""

from __future__ import annotations

import statistics
import sys

from common import compile_example, run_script, table

from bbzide.vm.steptime import COST_MODELS
from bbzide.worlds.engine import Simulation
from bbzide.worlds.steptime import StepTimeMeter

#: (label, example, drones, constants, the paper's Table 4.3 column or "-")
EXPERIMENTS = (
    ("exploration", "examples/crazyflie/exploration.bzz", 2, {}, "12 / 68.74 ± 9.66 / 110"),
    ("VS (consensus)", "examples/crazyflie/consensus.bzz", 10, {}, "1 / 3.83 ± 1.08 / 13"),
    ("neighbour queries", "examples/crazyflie/packet_loss.bzz", 4, {},
     "2 / 5.92 ± 0.56 / 9"),
    ("bidding, 6 drones", "examples/crazyflie/bidding.bzz", 6, {"N": 6}, "-"),
)


def measure(example: str, drones: int, constants: dict[str, int], steps: int,
            seed: int = 0) -> StepTimeMeter:
    program = compile_example("crazyflie", example, constants)
    sim = Simulation("crazyflie", program, robots=drones, seed=seed, watch=(),
                     asynchronous=True)
    meter = StepTimeMeter(sim)
    meter.run(steps)
    if sim.failures:
        first = sim.failures[0]
        raise RuntimeError(f"{example}: robot {first.robot_id} failed: {first.failure}")
    return meter


def min_mean_max(times: list[float]) -> str:
    return (f"{min(times):.2f} / {statistics.fmean(times):.2f} ± "
            f"{statistics.pstdev(times):.2f} / {max(times):.2f}")


def main() -> None:
    steps = int(sys.argv[1]) if len(sys.argv) > 1 else 200
    crazyflie, kilobot = COST_MODELS["crazyflie"], COST_MODELS["kilobot"]
    rows = []
    for label, example, drones, constants, paper in EXPERIMENTS:
        meter = measure(example, drones, constants, steps)
        counts = meter.counts
        rows.append([label, drones,
                     f"{statistics.fmean(c.instructions for c in counts):.0f}",
                     min_mean_max(meter.milliseconds(crazyflie)),
                     min_mean_max(meter.milliseconds(kilobot)), paper])
    print(table(["script", "drones", "instructions / step (mean)",
                 "Crazyflie estimate, ms (min / mean ± sd / max)",
                 "Kilobot estimate, ms", "paper, Crazyflie ms (Table 4.3)"], rows))
    print(f"\nCrazyflie: {crazyflie.source} (x{crazyflie.uncertainty:g} either way); "
          f"Kilobot: {kilobot.source}")


if __name__ == "__main__":
    run_script(main)
