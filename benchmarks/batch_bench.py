"""Time `swarm_batch.control_steps` alone: gradient Kilobots, all-to-all-in-range deliveries.

The world benchmark (`world_bench.py`) measures a whole swarm step (sense, VM, radio,
physics); this one isolates the VM room's share — one `control_steps` call per control step
— for the reference implementation and the compiled path, so the two can be compared on the
same robots and deliveries. The robots come from a real Kilobot `Simulation` (its host
functions, its placement); the deliveries of a step are last step's outbox sent to every
robot within the Kilobot's 10 cm range (distance in mm, no loss, no bandwidth limit: more
messages than the world's radio delivers, so an upper bound of the VM's work).

    PYTHONPATH=. python benchmarks/batch_bench.py [seconds per case, default 3] [robots ...]
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np

from bbzide.vm import swarm_batch
from bbzide.vm.swarm_batch import PackedMessages, control_steps
from bbzide.worlds.commands import load_script
from bbzide.worlds.engine import Simulation
from bbzide.worlds.radio import pairs_within_range
from bbzide.worlds.registry import WORLDS

REPO = Path(__file__).resolve().parents[1]
#: the Kilobot's IR range in metres (kilobot.py), and the table side per robot count
RANGE = 0.1
SIDES = {100: 1.0, 1000: 2.0}


def deliveries_of(outbox: PackedMessages, senders: np.ndarray, receivers: np.ndarray,
                  distances: np.ndarray) -> PackedMessages:
    """Every outbox row to every receiver in range of its sender, rows sorted by receiver."""
    if len(outbox) == 0 or len(senders) == 0:
        return PackedMessages.empty()
    first = np.searchsorted(outbox.robots, senders, side="left")
    last = np.searchsorted(outbox.robots, senders, side="right")
    counts = last - first
    link = np.repeat(np.arange(len(senders)), counts)
    row = np.repeat(first - (np.cumsum(counts) - counts), counts) + np.arange(int(counts.sum()))
    order = np.argsort(receivers[link], kind="stable")
    link, row = link[order], row[order]
    zeros = np.zeros(len(row))
    return PackedMessages(receivers[link], outbox.payloads[row], outbox.lengths[row],
                          senders[link], distances[link] * 1000.0, zeros, zeros)


def bench(count: int, seconds: float, reference: bool) -> tuple[float, float, int]:
    spec = WORLDS["kilobot"]
    program = load_script(REPO / "examples/kilobot/gradient.bzz", spec.host_names, [])
    side = SIDES.get(count, 2.0)
    sim = Simulation("kilobot", program, robots=count, seed=1,
                     world_options={"width": side, "height": side}, watch=())
    robots = [s.robot for s in sim.robots]
    links = pairs_within_range(sim.positions, RANGE)
    stepping = np.ones(count, dtype=bool)
    swarm_batch.REFERENCE = reference
    outbox = PackedMessages.empty()
    delivered = 0
    try:
        for _ in range(3):  # warm-up (and the compiled path's first-use packing)
            outbox = control_steps(robots, deliveries_of(outbox, links.senders,
                                                         links.receivers, links.distances),
                                   stepping).outbox
        steps = 0
        spent = 0.0
        started = time.perf_counter()
        while time.perf_counter() - started < seconds or steps < 2:
            deliveries = deliveries_of(outbox, links.senders, links.receivers, links.distances)
            delivered += len(deliveries)
            t0 = time.process_time()
            outbox = control_steps(robots, deliveries, stepping).outbox
            spent += time.process_time() - t0
            steps += 1
    finally:
        swarm_batch.REFERENCE = False
    return steps / spent, spent / steps / count * 1e6, delivered // max(steps, 1)


def main() -> None:
    seconds = float(sys.argv[1]) if len(sys.argv) > 1 else 3.0
    counts = [int(a) for a in sys.argv[2:]] or [100, 1000]
    print(f"{'case':24} {'steps/cpu s':>12} {'us/robot-step':>14} {'msgs/step':>10}")
    for count in counts:
        for reference in (True, False):
            rate, per_robot, messages = bench(count, seconds, reference)
            label = f"kilobot x {count} {'reference' if reference else 'compiled'}"
            print(f"{label:24} {rate:12.1f} {per_robot:14.1f} {messages:10d}")


if __name__ == "__main__":
    main()
