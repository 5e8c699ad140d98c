"""Auction duration of the distributed bidding with 3, 4 and 6 Crazyflies (thesis §4.7.1,
Fig. 4.8: 88.00 ± 29.25 ms, 99.05 ± 35.30 ms, 137.10 ± 21.70 ms; 20 runs each, 50 ms steps).

Runs examples/crazyflie/bidding.bzz with N set to the swarm size and asynchronous drones (each
its own phase within the 50 ms step): drone 0 posts the task at step 5; a run's duration is from
the post (step 5 + drone 0's phase) to the moment the last drone knew the winner (its `done`
step + its phase).
The run also checks that every drone names the same winner.

    PYTHONPATH=. python experiments/crazyflie_bidding.py [runs, default 20] [loss] [--jobs N]
        [--cluster ADDRESS]

With a loss probability, every message is lost with it (instead of the paper's loss-by-rate
curve, measured with one broadcast per drone per step): the auction's traffic — a bid from
every drone at every step, stigmergy queries until the task is known — loads the channel
more than that measurement did; the README compares the durations this gives with the paper's.
"""

from __future__ import annotations

import sys
from functools import partial

from common import compile_example, executor_from_argv, globals_of, mean_sd, run_script, table

from bbzide.worlds.engine import Simulation
from bbzide.worlds.executors import run_in_order

POST_STEP = 5
PAPER_MS = {3: "88.00 ± 29.25", 4: "99.05 ± 35.30", 6: "137.10 ± 21.70"}


def auction_time(drones: int, seed: int, program: object,
                 loss: float | None = None) -> tuple[float, bool]:
    radio = {} if loss is None else {"loss_probability": loss, "loss_by_rate": ()}
    sim = Simulation("crazyflie", program, robots=drones, seed=seed, watch=(),
                     asynchronous=True, radio=radio)
    for _ in range(POST_STEP + 60):
        sim.step()
        if all(d is not None and d >= 0 for d in globals_of(sim, "done")):
            break
    if sim.failures:
        first = sim.failures[0]
        raise RuntimeError(f"robot {first.robot_id} failed: {first.failure}")
    done = globals_of(sim, "done")
    winners = set(globals_of(sim, "winner"))
    if any(d is None or d < 0 for d in done):
        return -1.0, False
    phases = sim.phases
    finish = max(d + phases[i] for i, d in enumerate(done))
    return finish - (POST_STEP + phases[0]), len(winners) == 1


def main() -> None:
    executor, argv = executor_from_argv(sys.argv[1:])
    runs = int(argv[0]) if argv else 20
    loss = float(argv[1]) if len(argv) > 1 else None
    seeds = list(range(runs))
    rows = []
    with executor:
        for drones in (3, 4, 6):
            program = compile_example("crazyflie", "examples/crazyflie/bidding.bzz",
                                      {"N": drones})
            results = run_in_order(
                executor, partial(auction_time, drones, program=program, loss=loss), seeds,
                [f"bidding-{drones}drones-seed{s}" for s in seeds], what=f"{drones} drones")
            times = [t * 50 for t, _ in results if t >= 0]
            agree = sum(1 for _, same in results if same)
            rows.append([drones, runs, mean_sd(times),
                         f"{min(times):.0f}-{max(times):.0f}" if times else "-",
                         f"{agree}/{runs}", PAPER_MS[drones]])
    print(table(["drones", "runs", "auction duration (ms)", "range (ms)",
                 "same winner everywhere", "paper (ms)"], rows))


if __name__ == "__main__":
    run_script(main)
