"""Fig. 4.9 of the thesis (§4.7.2): the trajectories of two Crazyflies exploring the lab by
random walk with obstacle avoidance, drawn from a simulated run.

Runs examples/crazyflie/exploration.bzz on 2 drones in the default lab (6 x 6 m, two 0.4 m
pillars) for STEPS control steps (50 ms each), records every drone's position after each step
and draws the top view: the room's walls, the obstacles, each drone's path from its start
(circle) to its end (cross). Same seed, same picture.

    PYTHONPATH=. python experiments/crazyflie_exploration_plot.py [out.png] [steps] [seed]
    PYTHONPATH=. python experiments/crazyflie_exploration_plot.py --scenario S.toml [out.png]

With a scenario file (docs/scenarios.md) of the crazyflie world, the plot draws that run
instead: its room and obstacles, drones, positions, script, seed and `steps` (e.g.
examples/crazyflie/exploration.toml, or a set-up saved from the IDE).
"""

from __future__ import annotations

import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")   # files only: no display on a server
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from common import compile_example, run_script  # noqa: E402

from bbzide.diagnostics import UserError  # noqa: E402
from bbzide.worlds.engine import Simulation  # noqa: E402
from bbzide.worlds.scenario import load_scenario  # noqa: E402

#: 1200 steps of 50 ms: one minute of flight, about as long as a Crazyflie 2.1 battery allows
#: with a multi-ranger and a flow deck on board (~5-7 min) split over several runs.
DEFAULT_STEPS = 1200
DRONES = 2


def trajectories(steps: int, seed: int) -> tuple[np.ndarray, Simulation]:
    """Positions (steps + 1, drones, 3) of a run, the start included."""
    program = compile_example("crazyflie", "examples/crazyflie/exploration.bzz")
    sim = Simulation("crazyflie", program, robots=DRONES, seed=seed, watch=(),
                     asynchronous=True)
    return fly(sim, steps), sim


def scenario_trajectories(scenario_path: Path) -> tuple[np.ndarray, Simulation, str]:
    """Positions of the run a crazyflie scenario file pins (its `steps`), and its title."""
    scenario = load_scenario(scenario_path)
    if scenario.world != "crazyflie":
        raise UserError(f"{scenario_path}: the exploration plot draws a crazyflie room, not "
                        f"the {scenario.world} world")
    sim = scenario.simulation()
    return fly(sim, scenario.steps), sim, scenario.title


def fly(sim: Simulation, steps: int) -> np.ndarray:
    """Step `sim` `steps` times: positions (steps + 1, drones, 3), the start included."""
    path = [sim.positions.copy()]
    for _ in range(steps):
        sim.step()
        path.append(sim.positions.copy())
    if sim.failures:
        first = sim.failures[0]
        raise RuntimeError(f"robot {first.robot_id} failed: {first.failure}")
    return np.array(path)


def plot(path: np.ndarray, sim: Simulation, out: str,
         title: str = "Random-walk exploration") -> None:
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
    ax.set_title(f"{title}, {path.shape[1]} Crazyflies, {seconds:.0f} s (o start, x end)")
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.set_aspect("equal")
    ax.set_xlim(x0 - 0.2, x1 + 0.2)
    ax.set_ylim(y0 - 0.2, y1 + 0.2)
    ax.legend(loc="lower left")
    fig.tight_layout()
    fig.savefig(out, dpi=120)
    plt.close(fig)


def main(argv: list[str]) -> int:
    if argv[:1] == ["--scenario"]:
        if len(argv) < 2:
            print("--scenario needs a scenario file (S.toml)", file=sys.stderr)
            return 2
        out = argv[2] if len(argv) > 2 else "exploration_trajectories.png"
        try:
            path, sim, title = scenario_trajectories(Path(argv[1]))
        except UserError as error:
            print(error.render(), file=sys.stderr)
            return 1
        plot(path, sim, out, title or "Random-walk exploration")
    else:
        out = argv[0] if argv else "exploration_trajectories.png"
        steps = int(argv[1]) if len(argv) > 1 else DEFAULT_STEPS
        seed = int(argv[2]) if len(argv) > 2 else 0
        path, sim = trajectories(steps, seed)
        plot(path, sim, out)
    bumps = sim.world.bumps.tolist()
    print(f"{out}: {path.shape[1]} drones, {path.shape[0] - 1} steps; bumps per drone {bumps}")
    return 0


if __name__ == "__main__":
    run_script(lambda: sys.exit(main(sys.argv[1:])))
