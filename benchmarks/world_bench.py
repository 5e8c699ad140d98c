"""Control steps per second of whole swarms, and where the time goes (VM, radio, physics).

Cases: the Kilobot table with 100 and 1,000 robots running the gradient example,
the Crazyflie lab with 10 drones running the consensus example, and the M300 field with 25
drones running the flocking example and the search-and-rescue mission (examples/sar/sar.bzz, a
30 m arena: the thesis §5.4 sweep's middle size; its figure sets the sweep's wall time, see
README "Search and rescue"). Each case boots the swarm,
runs a few warm-up steps, then times `seconds` of steps and prints steps/s next to the goal
(issue 20's: 100 Kilobots >= 400 steps/s, 1,000 >= 40, M300 x 25 flocking >= 300, search and
rescue >= 500; the Kilobot cases once more on 2 threads, `--threads 2`, as a machine with a
core to spare runs them), the steps per CPU second of this process and the CPU seconds beside the
wall seconds (a shared machine's load inflates the wall figure; the load average is printed
before each case), and the share of step time spent in the engine's
phases (`Simulation.timings`: sense, vm = `swarm_batch.control_steps` (receive and control
step of every robot), radio (deliveries due, counters, queues, transmission), physics), and
the microseconds per robot-step of the VM phase and of the rest (the engine's own share).

    PYTHONPATH=. python benchmarks/world_bench.py [seconds per case, default 5] [world]
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

from bbzide.vm import swarm_batch
from bbzide.worlds.commands import load_script
from bbzide.worlds.engine import Simulation
from bbzide.worlds.registry import WORLDS

REPO = Path(__file__).resolve().parents[1]

#: (world, robots, script, world options, goal in steps/s or None, threads: `--threads`)
CASES = [
    ("kilobot", 100, "examples/kilobot/gradient.bzz", {"width": 1.0, "height": 1.0}, 400.0, 1),
    ("kilobot", 100, "examples/kilobot/gradient.bzz", {"width": 1.0, "height": 1.0}, 400.0, 2),
    ("kilobot", 1000, "examples/kilobot/gradient.bzz", {"width": 2.0, "height": 2.0}, 40.0, 1),
    ("kilobot", 1000, "examples/kilobot/gradient.bzz", {"width": 2.0, "height": 2.0}, 40.0, 2),
    ("crazyflie", 10, "examples/crazyflie/consensus.bzz", {}, None, 1),
    ("m300", 25, None, {}, 300.0, 1),
    ("m300", 25, "examples/sar/sar.bzz", {"size": 30.0}, 500.0, 1),
]
WARM_UP_STEPS = 3


def bench(world: str, robots: int, script: str | None, options: dict, seconds: float,
          threads: int = 1) -> dict:
    swarm_batch.set_threads(threads)
    spec = WORLDS[world]
    path = REPO / (script or spec.example)
    program = load_script(path, spec.host_names, [])
    started = time.perf_counter()
    sim = Simulation(world, program, robots=robots, seed=1, world_options=options, watch=())
    boot = time.perf_counter() - started
    sim.run(WARM_UP_STEPS)
    for key in sim.timings:
        sim.timings[key] = 0.0
    steps = 0
    t0 = time.perf_counter()
    c0 = time.process_time()
    while time.perf_counter() - t0 < seconds or steps < 2:
        sim.step()
        steps += 1
    elapsed = time.perf_counter() - t0
    cpu = time.process_time() - c0
    spent = sum(sim.timings.values()) or 1.0
    robot_steps = steps * robots
    return {
        "vm_us": 1e6 * sim.timings["vm"] / robot_steps,
        "engine_us": 1e6 * (spent - sim.timings["vm"]) / robot_steps,
        "steps_per_s": steps / elapsed, "steps_per_cpu_s": steps / max(cpu, 1e-9),
        "steps": steps, "boot_s": boot, "wall_s": elapsed, "cpu_s": cpu,
        "shares": {k: v / spent for k, v in sim.timings.items()},
        "failures": len(sim.failures),
        "messages_per_step": sim.totals["sent"] / max(sim.step_count, 1),
    }


def main() -> None:
    seconds = float(sys.argv[1]) if len(sys.argv) > 1 else 5.0
    only = sys.argv[2] if len(sys.argv) > 2 else None      # e.g. `m300`: one world's cases
    print(f"{'case':31} {'steps/s':>9} {'goal':>6} {'vm':>5} {'radio':>6} {'physics':>8} "
          f"{'sense':>6} {'msg/step':>9} {'boot s':>7} errors")
    # vm / engine us: microseconds per robot-step in the VM phase (`control_steps`) and in
    # everything else (sense, radio, physics), from `Simulation.timings`
    # steps/s is wall clock (what the goals mean); the last column, steps per CPU second of
    # this process, is what a busy shared machine distorts least
    for world, robots, script, options, goal, threads in CASES:
        example = script or (WORLDS[world].example if world in WORLDS else "")
        label = f"{world} x {robots} {Path(example).stem}" + \
            ("" if threads == 1 else f", {threads} thr")
        if only is not None and world != only:
            continue
        if world not in WORLDS:
            print(f"{label:31} (world not registered in this build)")
            continue
        load = Path("/proc/loadavg").read_text().split()[0] \
            if Path("/proc/loadavg").exists() else "?"
        r = bench(world, robots, script, options, seconds, threads)
        s = r["shares"]
        verdict = "" if goal is None else f"{goal:6.0f}"
        ratio = "" if goal is None else f"  ({r['steps_per_s'] / goal:.2f} x goal)"
        print(f"{label:31} {r['steps_per_s']:9.2f} {verdict:>6} {100 * s['vm']:4.0f}% "
              f"{100 * s['radio']:5.0f}% {100 * s['physics']:7.0f}% {100 * s['sense']:5.0f}% "
              f"{r['messages_per_step']:9.1f} {r['boot_s']:7.2f} {r['failures']}{ratio}"
              f"  [{r['steps_per_cpu_s']:.2f} per CPU s ({r['steps']} steps: "
              f"{r['cpu_s']:.2f} CPU s, {r['wall_s']:.2f} wall s, load {load}); "
              f"us per robot-step: vm {r['vm_us']:.1f}, engine {r['engine_us']:.1f}]")


if __name__ == "__main__":
    main()
