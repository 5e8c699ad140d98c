"""Packet loss of neighbour broadcasts at 2, 10 and 20 Hz on the Crazyflie (thesis §4.6.1,
Fig. 4.5: 20 tests of 200 broadcasts each; mean loss 0 % at 2 Hz, 1.55 ± 0.97 % at 10 Hz,
1.9 ± 1.2 % at 20 Hz, every test between 0 and 4.5 %).

Runs examples/crazyflie/packet_loss.bzz with PERIOD = 10, 2, 1 (50 ms steps) on DRONES drones
until each has sent 200 broadcasts; a test's loss is 1 - heard / (broadcasts the others sent),
summed over the drones. The model's loss curve is the paper's own measurement, so this checks
that the engine's rate estimate, loss draws and the VM's receive path give it back.

    PYTHONPATH=. python experiments/crazyflie_packet_loss.py [tests, default 20] [drones, 4]
        [--jobs N] [--cluster ADDRESS]
"""

from __future__ import annotations

import sys
from functools import partial

from common import compile_example, executor_from_argv, globals_of, mean_sd, run, run_script, table

from bbzide.worlds.executors import run_in_order

DRONES = 4
BROADCASTS = 200
PAPER = {2: "0", 10: "1.55 ± 0.97", 20: "1.9 ± 1.2"}


def loss_percent(period: int, seed: int, program: object, drones: int) -> float:
    steps = BROADCASTS * period + 1   # +1: the last broadcasts arrive one step later
    # Lockstep: the loss model does not depend on the phases, and lockstep is faster.
    sim = run("crazyflie", program, drones, seed, steps, asynchronous=False)
    sent = globals_of(sim, "sent")
    heard = globals_of(sim, "heard")
    expected = sum(sum(sent) - s for s in sent)
    return 100.0 * (1 - sum(heard) / expected)


def _loss_test(seed: int, period: int, program: object, drones: int) -> float:
    return loss_percent(period, seed, program, drones)


def main() -> None:
    executor, argv = executor_from_argv(sys.argv[1:])
    tests = int(argv[0]) if argv else 20
    drones = int(argv[1]) if len(argv) > 1 else DRONES
    seeds = list(range(tests))
    rows = []
    with executor:
        for hz, period in ((2, 10), (10, 2), (20, 1)):
            program = compile_example("crazyflie", "examples/crazyflie/packet_loss.bzz",
                                      {"PERIOD": period, "COUNT": BROADCASTS})
            losses = run_in_order(
                executor, partial(_loss_test, period=period, program=program, drones=drones),
                seeds, [f"loss-{hz}hz-{drones}drones-seed{s}" for s in seeds],
                what=f"{hz} Hz")
            rows.append([f"{hz} Hz ({period * 50} ms)", f"{tests} x {drones} drones",
                         mean_sd(losses), f"{min(losses):.1f}-{max(losses):.1f}", PAPER[hz]])
    print(table(["broadcast rate", "tests", "loss (%)", "range (%)", "paper (%)"], rows))


if __name__ == "__main__":
    run_script(main)
