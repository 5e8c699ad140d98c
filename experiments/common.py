"""Shared helpers of the experiment scripts: compile an example (with constants replaced),
run it in a world, read script globals, run the runs on an executor, and print a Markdown table.

The experiments reproduce the Crazyflie experiments of the BittyBuzz thesis (ch. 4, §4.6-4.7)
in the simulator; each script prints its table next to the paper's figures (README.md). Their
runs go through the same executors as `bbzide experiment sar` (`--jobs N`, `--cluster
ADDRESS`; bbzide/worlds/executors.py); this module and the script travel to Dask workers by
value, since only the package is installed there.
"""

from __future__ import annotations

import argparse
import re
import statistics
import sys
import tempfile
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

from bbzide.diagnostics import UserError
from bbzide.worlds.commands import load_script
from bbzide.worlds.engine import Simulation
from bbzide.worlds.executors import Executor, add_executor_arguments, open_executor
from bbzide.worlds.registry import WORLDS

REPO = Path(__file__).resolve().parents[1]


def compile_example(world: str, example: str, constants: dict[str, int] | None = None) -> Any:
    """The example compiled for `world`, with `var NAME = value` lines replaced."""
    text = (REPO / example).read_text(encoding="utf-8")
    for name, value in (constants or {}).items():
        text, count = re.subn(rf"^var {name} = .*$", f"var {name} = {value}", text,
                              flags=re.MULTILINE)
        if count != 1:
            raise ValueError(f"{example} has no line 'var {name} = ...'")
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / Path(example).name
        path.write_text(text, encoding="utf-8")
        return load_script(path, WORLDS[world].host_names, [str((REPO / example).parent)])


def run(world: str, program: Any, robots: int, seed: int, steps: int,
        options: dict[str, Any] | None = None, until: Any = None,
        asynchronous: bool = True) -> Simulation:
    """Run `steps` control steps (or stop early when `until(sim)` is true).

    Robots are asynchronous by default (each its own phase within the 50 ms step), as the
    paper's drones were: event times are then `step + phase` steps.
    """
    sim = Simulation(world, program, robots=robots, seed=seed, world_options=options or {},
                     watch=(), asynchronous=asynchronous)
    for _ in range(steps):
        sim.step()
        if until is not None and until(sim):
            break
    failures = sim.failures
    if failures:
        first = failures[0]
        raise RuntimeError(f"robot {first.robot_id} failed: {first.failure}")
    return sim


def globals_of(sim: Simulation, name: str) -> list[Any]:
    return [state.global_value(name) for state in sim.robots]


def mean_sd(values: Sequence[float]) -> str:
    if not values:
        return "-"
    if len(values) == 1:
        return f"{values[0]:.1f}"
    return f"{statistics.mean(values):.1f} ± {statistics.stdev(values):.1f}"


def table(header: Sequence[str], rows: Sequence[Sequence[Any]]) -> str:
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    lines += ["| " + " | ".join(str(c) for c in row) + " |" for row in rows]
    return "\n".join(lines)


def executor_from_argv(argv: list[str]) -> tuple[Executor, list[str]]:
    """`--jobs N` / `--cluster ADDRESS` taken out of `argv` (default: 1 job, in this process),
    and the script's own arguments left."""
    parser = argparse.ArgumentParser(add_help=False)
    add_executor_arguments(parser, default_jobs=1)
    options, rest = parser.parse_known_args(argv)
    # The script itself (`__main__`) is shipped by value anyway; this module is not.
    return open_executor(options.jobs, options.cluster,
                         local_modules=[sys.modules[__name__]]), rest


def run_script(main: Callable[[], None]) -> None:
    """A script's `main()` as `bbzide` runs its commands: a `UserError` (a bad argument, an
    unreachable Dask scheduler, a cluster lost mid-run) is one line on stderr and exit
    status 1, never a traceback."""
    try:
        main()
    except UserError as error:
        print(error.render(), file=sys.stderr)
        sys.exit(1)
    except KeyboardInterrupt:
        sys.exit(130)
