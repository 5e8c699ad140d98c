"""What the debugger costs: control steps per second of the gradient example on 25 Kilobots.

Cases, each on a fresh swarm (seed 1) after a few warm-up steps:

* `engine`: `Simulation.step()` alone (the fast path; world_bench.py's kind of figure);
* `debugger, no breakpoint`: `SwarmDebugger.run` with nothing set (the fast step, plus a
  checkpoint every `CHECKPOINT_EVERY` steps and a look at the failures);
* `1 breakpoint, robot 0`: a breakpoint whose condition is never true on one robot — that robot
  runs instruction by instruction in the VM's reference mode with the tracer, the swarm takes
  its turns robot by robot, and every step is checkpointed;
* `1 breakpoint, any robot`: the same breakpoint for every robot (all 25 traced).

Each line prints steps per wall second and per CPU second of this process (what a busy shared
machine distorts least), the CPU time per step and the ratio to the engine's, and the load
average of the machine.

    PYTHONPATH=. python benchmarks/debugger_bench.py [seconds per case, default 5]
"""

from __future__ import annotations

import sys
import time
from collections.abc import Callable
from pathlib import Path

from bbzide.debugger import Breakpoint, SwarmDebugger
from bbzide.worlds.commands import load_script
from bbzide.worlds.engine import Simulation
from bbzide.worlds.registry import WORLDS

REPO = Path(__file__).resolve().parents[1]
SCRIPT = REPO / "examples/kilobot/gradient.bzz"
ROBOTS = 25
#: a 0.5 m table: 25 Kilobots in radio range of several others (messages every step)
OPTIONS = {"width": 0.5, "height": 0.5}
WARM_UP_STEPS = 3
#: line 20 of gradient.bzz (`gradient = heard + 1`, in `step`), with a condition that is
#: never true: the cost of watching without stopping
NEVER = Breakpoint(20, condition="gradient > 1000")


def swarm() -> Simulation:
    program = load_script(SCRIPT, WORLDS["kilobot"].host_names, [])
    return Simulation("kilobot", program, robots=ROBOTS, seed=1, world_options=OPTIONS,
                      watch=())


def timed(advance: Callable[[], object], seconds: float) -> tuple[int, float, float]:
    steps = 0
    t0, c0 = time.perf_counter(), time.process_time()
    while time.perf_counter() - t0 < seconds or steps < 2:
        advance()
        steps += 1
    return steps, time.perf_counter() - t0, time.process_time() - c0


def engine_case(seconds: float) -> tuple[int, float, float]:
    sim = swarm()
    sim.run(WARM_UP_STEPS)
    return timed(sim.step, seconds)


def debugger_case(breakpoints: list[Breakpoint], seconds: float) -> tuple[int, float, float]:
    debugger = SwarmDebugger(swarm())
    debugger.breakpoints = breakpoints
    debugger.run(WARM_UP_STEPS)

    def one_step() -> None:
        if debugger.run(1) is not None:
            raise SystemExit("a breakpoint stopped the benchmark: its condition must stay "
                             "false")

    return timed(one_step, seconds)


def main() -> None:
    seconds = float(sys.argv[1]) if len(sys.argv) > 1 else 5.0
    cases: list[tuple[str, Callable[[], tuple[int, float, float]]]] = [
        ("engine", lambda: engine_case(seconds)),
        ("debugger, no breakpoint", lambda: debugger_case([], seconds)),
        ("1 breakpoint, robot 0", lambda: debugger_case(
            [Breakpoint(NEVER.line, robot=0, condition=NEVER.condition)], seconds)),
        ("1 breakpoint, any robot", lambda: debugger_case([NEVER], seconds)),
    ]
    loadavg = Path("/proc/loadavg")
    load = loadavg.read_text().split()[0] if loadavg.exists() else "unknown"
    print(f"gradient x {ROBOTS} Kilobots; load average {load}")
    print(f"{'case':26} {'steps/s':>9} {'per CPU s':>10} {'CPU ms/step':>12} {'x engine':>9}")
    engine_cpu = None
    for label, run in cases:
        steps, wall, cpu = run()
        per_step = 1e3 * cpu / steps
        engine_cpu = engine_cpu or per_step
        print(f"{label:26} {steps / wall:9.2f} {steps / max(cpu, 1e-9):10.2f} "
              f"{per_step:12.2f} {per_step / engine_cpu:9.2f}")


if __name__ == "__main__":
    main()
