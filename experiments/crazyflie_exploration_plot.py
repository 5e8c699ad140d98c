"""Fig. 4.9 of the thesis (§4.7.2): the trajectories of two Crazyflies exploring the lab by
random walk with obstacle avoidance, drawn from a simulated run.

Runs examples/crazyflie/exploration.bzz on 2 drones in the default lab (6 x 6 m, two 0.4 m
pillars) for STEPS control steps (50 ms each), records every drone's position after each step
and draws the top view: the room's walls, the obstacles, each drone's path from its start
(circle) to its end (cross). Same seed, same picture.

    PYTHONPATH=. python experiments/crazyflie_exploration_plot.py [out.png] [steps] [seed]
"""

from __future__ import annotations

import sys

import matplotlib

matplotlib.use("Agg")   # files only: no display on a server
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from common import compile_example, run_script  # noqa: E402

from bbzide.worlds.engine import Simulation  # noqa: E402

#: 1200 steps of 50 ms: one minute of flight, about as long as a Crazyflie 2.1 battery allows
#: with a multi-ranger and a flow deck on board (~5-7 min) split over several runs.
DEFAULT_STEPS = 1200
DRONES = 2


def trajectories(steps: int, seed: int) -> tuple[np.ndarray, Simulation]:
    """Positions (steps + 1, drones, 3) of a run, the start included."""
    program = compile_example("crazyflie", "examples/crazyflie/exploration.bzz")
    sim = Simulation("crazyflie", program, robots=DRONES, seed=seed, watch=(),
                     asynchronous=True)
    path = [sim.positions.copy()]
    for _ in range(steps):
        sim.step()
        path.append(sim.positions.copy())
    if sim.failures:
        first = sim.failures[0]
        raise RuntimeError(f"robot {first.robot_id} failed: {first.failure}")
    return np.array(path), sim


def plot(path: np.ndarray, sim: Simulation, out: str) -> None:
    world = sim.world
    x0, y0, x1, y1 = world.bounds
    fig, ax = plt.subplots(figsize=(6, 6))
    ax.add_patch(plt.Rectangle((x0, y0), x1 - x0, y1 - y0, fill=False, lw=2, color="black"))
    for bx0, by0, bx1, by1 in world.obstacles:
        ax.add_patch(plt.Rectangle((bx0, by0), bx1 - bx0, by1 - by0, color="0.5"))
    for drone in range(path.shape[1]):
        xy = path[:, drone, :2]
        line, = ax.plot(xy[:, 0], xy[:, 1], lw=1.2, label=f"drone {drone}")
        ax.plot(*xy[0], "o", color=line.get_color(), ms=8)
        ax.plot(*xy[-1], "x", color=line.get_color(), ms=9, mew=2)
    seconds = (path.shape[0] - 1) * world.step_seconds
    ax.set_title(f"Random-walk exploration, {path.shape[1]} Crazyflies, {seconds:.0f} s "
                 "(o start, x end)")
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.set_aspect("equal")
    ax.set_xlim(x0 - 0.2, x1 + 0.2)
    ax.set_ylim(y0 - 0.2, y1 + 0.2)
    ax.legend(loc="lower left")
    fig.tight_layout()
    fig.savefig(out, dpi=120)
    plt.close(fig)


def main() -> None:
    out = sys.argv[1] if len(sys.argv) > 1 else "exploration_trajectories.png"
    steps = int(sys.argv[2]) if len(sys.argv) > 2 else DEFAULT_STEPS
    seed = int(sys.argv[3]) if len(sys.argv) > 3 else 0
    path, sim = trajectories(steps, seed)
    plot(path, sim, out)
    bumps = sim.world.bumps.tolist()
    print(f"{out}: {path.shape[1]} drones, {steps} steps; bumps per drone {bumps}")


if __name__ == "__main__":
    run_script(main)
