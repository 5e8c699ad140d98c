"""The worlds room's command line: `bbzide run X.bzz --world W ...` and `bbzide worlds`.

    bbzide run X.bzz|X.bbo --world kilobot|crazyflie|... [--robots N] [--steps S] [--seed K]
               [--comm-range M] [--loss P] [--set KEY=VALUE]... [--asynchronous] [-I DIR]...
               [--steptime]   (estimated step time per platform: bbzide.worlds.steptime)
    bbzide run S.toml [--steps S] [--seed K]    a scenario file (bbzide/worlds/scenario.py)
    bbzide worlds               list the worlds, their platform, host functions and example
    bbzide memory X.bzz [--platform P] [--world W] [--robots N] [--steps S]
                                the RAM the script needs on P (bbzide/worlds/memory.py)

`run` is shared with the VM room (single robot): `bbzide/cli.py` builds one parser from both
rooms' options, so `add_world_run_arguments` adds only the options the VM room has not added
already (`--steps`, `--seed`, the script argument). The script is compiled for the world's
platform (BittyBuzz base strings + the world's host names); the run prints one summary: speed,
radio traffic and every robot error with its source line. Every problem is a `UserError`.
A scenario file pins the world, its options, the robots and their scripts: with one, only
`--steps` and `--seed` may be given (they override the file's); options the file pins are
refused rather than silently ignored. Watched globals are printed after the summary.
"""

from __future__ import annotations

import argparse
import re
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from bbzide.compiler.call_sites import explain_failure, lint_globals, robot_phrase
from bbzide.diagnostics import UserError
from bbzide.worlds.radio import WorldConfigError
from bbzide.worlds.registry import DEFAULT_SEED, WORLDS, world_spec
from bbzide.worlds.scripts import load_script

#: Steps of a headless run when neither room's parser gives a default: 10 s of Kilobot time.
DEFAULT_STEPS = 100


def register(subparsers: argparse._SubParsersAction) -> None:
    worlds = subparsers.add_parser("worlds", help="list the simulated worlds")
    worlds.set_defaults(handler=run_list_worlds)
    from bbzide.worlds import sar_experiment

    sar_experiment.register(subparsers)      # `bbzide experiment sar` (thesis §5.4)
    register_memory(subparsers)              # `bbzide memory` (thesis Table 4.2)


def _has_option(parser: argparse.ArgumentParser, option: str) -> bool:
    return option in parser._option_string_actions


def add_world_run_arguments(parser: argparse.ArgumentParser) -> None:
    if not any(action.dest == "script" for action in parser._actions):
        parser.add_argument("script", help="the .bzz (or .bbo) file")
    group = parser.add_argument_group("swarm in a world (with --world)")
    group.add_argument("--world", help=f"run a swarm in a world: {', '.join(WORLDS)}")
    group.add_argument("--robots", type=int, default=None,
                       help="number of robots (default: the world's)")
    if not _has_option(parser, "--steps"):
        group.add_argument("--steps", type=int, default=DEFAULT_STEPS, help="control steps")
    if not _has_option(parser, "--seed"):
        group.add_argument("--seed", type=int, default=0, help="random seed")
    group.add_argument("--comm-range", type=float, default=None, help="radio range, metres")
    group.add_argument("--loss", type=float, default=None,
                       help="message loss probability (replaces the world's loss model)")
    group.add_argument("--asynchronous", action="store_true",
                       help="robots step at their own phase within the step (not in lockstep)")
    group.add_argument("--threads", type=int, default=None, metavar="N",
                       help="split each step of a large swarm over N threads (default 1; "
                            "the same run, sooner on a machine with cores to spare)")
    group.add_argument("--steptime", action="store_true",
                       help="estimate each control step's duration on the platforms with a "
                            "cost model (Kilobot measured, Crazyflie scaled): min/mean/max ms")
    group.add_argument("--set", dest="world_options", action="append", default=[],
                       metavar="KEY=VALUE", help="world option, e.g. width=2.0 (repeatable)")
    if not _has_option(parser, "-I"):
        group.add_argument("-I", dest="include", action="append", default=[],
                           help="include folder")


def parse_world_options(items: list[str]) -> dict[str, Any]:
    """`KEY=VALUE` strings -> options; numbers become int/float, the rest stay strings."""
    options: dict[str, Any] = {}
    for item in items:
        key, sep, value = item.partition("=")
        if not sep or not key:
            raise WorldConfigError(f"world option {item!r} must be KEY=VALUE")
        parsed: Any = value
        for convert in (int, float):
            try:
                parsed = convert(value)
                break
            except ValueError:
                continue
        options[key.replace("-", "_")] = parsed
    return options


#: `run` options a scenario file pins: (argparse dest, option, value when not given).
SCENARIO_PINNED = (("world", "--world", None), ("robots", "--robots", None),
                   ("comm_range", "--comm-range", None), ("loss", "--loss", None),
                   ("asynchronous", "--asynchronous", False), ("world_options", "--set", []))


def prepare_scenario(args: argparse.Namespace) -> tuple[Any, int, dict[str, Any],
                                                      dict[Path, Any]]:
    """The scenario file `args.script` for a run: (scenario with --seed applied, steps,
    --budget/--loop engine options, compiled programs). Options the file pins are refused."""
    from bbzide.worlds.scenario import load_scenario

    for dest, option, unset in SCENARIO_PINNED:
        if getattr(args, dest, unset) not in (unset, None):
            raise WorldConfigError(f"{option} cannot be combined with a scenario file (it pins "
                                   f"the world and the robots): edit {args.script}")
    scenario = load_scenario(Path(args.script))
    steps = scenario.steps if args.steps is None else int(args.steps)
    if steps < 0:
        raise WorldConfigError(f"--steps must be >= 0, got {steps}")
    if getattr(args, "seed", None) is not None:
        scenario = scenario.with_seed(seed_of(args))
    engine_options = vm_options_for_world(args)
    programs = scenario.programs(list(getattr(args, "include", []) or []))
    return scenario, steps, engine_options, programs


#: Runs a built swarm for a command instead of `Simulation.run`: (simulation, steps) -> the
#: control steps it ran (the debugger room's `--break` runs, bbzide/debugger/commands.py).
Driver = Callable[[Any, int], int]


def run_scenario(args: argparse.Namespace, drive: Driver | None = None) -> int:
    """`bbzide run S.toml`: the scenario's swarm, `--steps`/`--seed` overriding the file's."""
    scenario, steps, engine_options, programs = prepare_scenario(args)
    started = time.perf_counter()
    sim = scenario.simulation(programs, **engine_options)
    booted = time.perf_counter()
    if drive is not None:
        steps = drive(sim, steps)
    else:
        sim.run(steps)
    finished = time.perf_counter()
    print(summary(sim, steps, booted - started, finished - booted))
    for name in scenario.watch:
        print(watched_line(sim, name))
    return 0


def watched_line(sim: Any, name: str) -> str:
    """`gradient: 0 1 1 2 ...` (robot-id order; `-` where the global is nil)."""
    values = [state.global_value(name) for state in sim.robots]
    shown = " ".join("-" if value is None else str(value) for value in values)
    return f"watch {name}: {shown}"


def run_world(args: argparse.Namespace, drive: Driver | None = None) -> int:
    from bbzide.worlds.engine import Simulation

    spec = world_spec(args.world)
    steps = int(args.steps if args.steps is not None else DEFAULT_STEPS)
    if steps < 0:
        raise WorldConfigError(f"--steps must be >= 0, got {steps}")
    seed = seed_of(args)
    robots = args.robots if args.robots is not None else spec.default_robots
    engine_options = vm_options_for_world(args)
    program = load_script(Path(args.script), spec.host_names, list(getattr(args, "include", [])
                                                                    or []))
    for where, message in lint_globals(program, spec.host_names, robot_phrase(spec.name)):
        print(f"{where}: warning: {message}", file=sys.stderr)
    radio: dict[str, Any] = {}
    if args.comm_range is not None:
        radio["comm_range"] = args.comm_range
    if args.loss is not None:
        radio["loss_probability"] = args.loss
        radio["loss_by_rate"] = ()
    started = time.perf_counter()
    sim = Simulation(spec.name, program, robots=robots, seed=seed,
                     world_options=parse_world_options(args.world_options), radio=radio,
                     asynchronous=bool(args.asynchronous), **engine_options)
    booted = time.perf_counter()
    meter = None
    if drive is not None:
        steps = drive(sim, steps)
    elif getattr(args, "steptime", False):
        from bbzide.worlds.steptime import StepTimeMeter

        meter = StepTimeMeter(sim)
        meter.run(steps)
    else:
        sim.run(steps)
    finished = time.perf_counter()
    print(summary(sim, steps, booted - started, finished - booted))
    if meter is not None:
        from bbzide.worlds.steptime import report

        print(report(meter))
    return 0


#: The VM room's single-robot options that mean nothing in a world (its host functions, ids and
#: radio replace them): refused rather than silently ignored.
SINGLE_ROBOT_ONLY = (("dump", "--dump"), ("inject", "--inject"), ("reg", "--reg"),
                     ("robot", "--robot"))


def seed_of(args: argparse.Namespace) -> int:
    """The run's `--seed` (`DEFAULT_SEED` when not given), refused when negative."""
    given = getattr(args, "seed", None)
    seed = DEFAULT_SEED if given is None else int(given)
    if seed < 0:  # numpy's seed sequences take non-negative integers only
        raise WorldConfigError(f"--seed must be >= 0, got {seed}")
    return seed


def vm_options_for_world(args: argparse.Namespace) -> dict[str, Any]:
    """`--budget` and `--loop` for every robot of the world (and `--threads` for the swarm's
    steps, set here once for the run); single-robot options refused."""
    for dest, option in SINGLE_ROBOT_ONLY:
        if getattr(args, dest, None):
            raise WorldConfigError(f"{option} is for one robot (without --world)")
    threads = getattr(args, "threads", None)
    if threads is not None:
        if threads < 1:
            raise WorldConfigError(f"--threads must be >= 1, got {threads}")
        from bbzide.vm import swarm_batch  # the kernels load with the run, not the CLI

        swarm_batch.set_threads(threads)
    options: dict[str, Any] = {}
    budget = getattr(args, "budget", None)
    if budget is not None:
        if budget < 1:  # 0 (no limit) would let one looping robot stop the whole swarm
            raise WorldConfigError(f"--budget must be >= 1 in a world, got {budget}")
        options["instruction_budget"] = budget
    loop = getattr(args, "loop", None)
    if loop is not None:
        options["loop"] = loop
    return options


def summary(sim: Any, steps: int, boot_seconds: float, run_seconds: float) -> str:
    """The text `bbzide run --world` prints."""
    world = sim.world
    rate = steps / run_seconds if run_seconds > 0 else float("inf")
    totals = sim.totals
    lines = [
        f"world {world.name}: {sim.count} robots, {steps} steps of {world.step_seconds:g} s "
        f"({sim.time:g} s simulated), seed {sim.seed}",
        f"speed: {rate:.1f} steps/s ({run_seconds:.2f} s; boot {boot_seconds:.2f} s)",
        f"messages: {totals['sent']} sent, {totals['received']} received, "
        f"{totals['dropped']} dropped, {totals['bytes']} bytes",
    ]
    spent = sum(sim.timings.values())
    if spent > 0:
        shares = ", ".join(f"{name} {100 * t / spent:.0f} %" for name, t in sim.timings.items())
        lines.append(f"time: {shares}")
    lines.extend(heap_lines(sim))
    failures = sim.failures
    lines.append(f"errors: {len(failures)} robot(s)" if failures else "errors: none")
    # Robots that fail the same way (same error at the same place) are listed together, so
    # a script error in a 1,000-robot swarm prints one entry, not 1,000.
    groups: dict[tuple[str, str, str], list[Any]] = {}
    for state in failures:
        f = state.failure
        key = (str(getattr(f, "reason", f)), str(getattr(f, "location", "")),
               str(getattr(f, "message", "")))
        groups.setdefault(key, []).append(state)
    for states in groups.values():
        lines.append("  " + describe_failure(states[0], others=len(states) - 1,
                                             world=world.name))
    return "\n".join(lines)


#: Up to this many robots, each robot's peak is listed; a larger swarm gets the range.
LISTED_ROBOTS = 12


def heap_lines(sim: Any) -> list[str]:
    """Each robot's peak heap against its profile's heap (and the platform's RAM), with a
    warning naming the robots near the limit."""
    from bbzide.compiler.footprint import RAM_BYTES
    from bbzide.vm.profiles import HEAP_WARNING_SHARE

    peaks = [(s.robot_id, int(s.robot.vm.heap.peak_used), s.robot.profile)
             for s in sim.robots if s.robot is not None]
    if not peaks:
        return []
    profile = peaks[0][2]
    size = int(profile.heap_size)
    ram = RAM_BYTES.get(profile.name)
    of = f"of the {size} B heap ({profile.name} profile" + \
         (f", {ram} B of RAM)" if ram else ")")
    values = [peak for _, peak, _ in peaks]
    if len(peaks) <= LISTED_ROBOTS:
        each = ", ".join(f"robot {robot} {peak} B" for robot, peak, _ in peaks)
        lines = [f"heap peak: {each} {of}"]
    else:
        lines = [f"heap peak: {min(values)}-{max(values)} B over {len(values)} robots {of}"]
    near = [(robot, peak) for robot, peak, p in peaks if peak >= HEAP_WARNING_SHARE * p.heap_size]
    if near:
        names = ", ".join(str(robot) for robot, _ in near[:LISTED_ROBOTS])
        more = f" and {len(near) - LISTED_ROBOTS} more" if len(near) > LISTED_ROBOTS else ""
        top = max(peak for _, peak in near)
        lines.append(f"warning: robot(s) {names}{more} used up to {100 * top / size:.0f} % of "
                     f"the heap: a larger table or more messages may stop them with MEM")
    return lines


def describe_failure(state: Any, others: int = 0, world: str | None = None) -> str:
    """`robot 3 (step 12): MEM at gradient.bzz:14:2, pc 37: <message>` plus the source line
    (`robot 3 and 4 others ...` when `others` robots failed the same way). A TYPE error on a
    line that calls a host function of another world (nil in this one) gets a hint naming it."""
    failure = state.failure
    reason = getattr(failure, "reason", str(failure))
    location = getattr(failure, "location", None)
    pc = getattr(failure, "pc", None)
    message = getattr(failure, "message", "")
    explained = None
    if world is not None and pc is not None and state.robot is not None:
        spec = world_spec(world)
        explained = explain_failure(state.robot.program, reason, pc, spec.host_names,
                                    robot_phrase(spec.name))
    if explained is not None:
        location, message = explained
    who = f"robot {state.robot_id}" + (f" and {others} other(s)" if others else "")
    text = f"{who} (step {state.failure_step}): {reason}"
    if location is not None:
        text += f" at {location}"
    if pc is not None:
        text += f", pc {pc}"
    if message:
        text += f": {message}"
    program = state.robot.program if state.robot is not None else None
    line = program.source_line(location) if program is not None and location is not None \
        and hasattr(program, "source_line") else None
    if line is None:
        line = _source_line(location)
    if line is not None:
        text += f"\n      {line.strip()}"
        if reason == "TYPE" and world is not None:
            # without the call's own position, bzzparse's debug position points at the token
            # after the call (often the next line's `}`), so the call can be on the line before
            before = "" if explained else _source_line(location, offset=-1) or ""
            hints = _other_world_calls(before + "\n" + line, world)
            text += "".join(f"\n      hint: {hint}" for hint in hints)
    return text


def _other_world_calls(line: str, world: str) -> list[str]:
    """Calls on `line` of host functions that other worlds have and `world` has not."""
    own = set(world_spec(world).host_names)
    hints = []
    for name in dict.fromkeys(re.findall(r"([A-Za-z]\w*)\s*\(", line)):
        if name in own:
            continue
        others = [spec.name for spec in WORLDS.values() if name in spec.host_names]
        if others:
            hints.append(f"{name}() is a host function of the {', '.join(others)} "
                         f"world{'s' if len(others) > 1 else ''}, not of {world}")
    return hints


def _source_line(location: Any, offset: int = 0) -> str | None:
    try:  # the compiler reads bytes; a line with non-UTF-8 bytes is shown with U+FFFD
        text = Path(location.file).read_text(encoding="utf-8", errors="replace")
        lines = text.splitlines()
        number = location.line + offset
        return lines[number - 1] if 1 <= number <= len(lines) else None
    except (OSError, AttributeError, TypeError):
        return None


def run_list_worlds(args: argparse.Namespace) -> int:
    for spec in WORLDS.values():
        print(f"{spec.name:10} {spec.title}: profile {spec.profile}, "
              f"{spec.default_robots} robots by default, example {spec.example}")
        print(f"{'':10} host functions: {', '.join(spec.host_names)}")
    return 0


def register_memory(subparsers: argparse._SubParsersAction) -> None:
    """`bbzide memory SCRIPT --platform P ...` (bbzide/worlds/memory.py measures)."""
    from bbzide.vm.profiles import PROFILES
    from bbzide.worlds.memory import DEFAULT_STEPS as MEMORY_STEPS

    parser = subparsers.add_parser(
        "memory", help="how much RAM a script needs on a platform (peak heap, smallest heap "
                       "and stack)")
    parser.add_argument("script", help="the .bzz file")
    parser.add_argument("--platform", default="crazyflie", choices=sorted(PROFILES),
                        help="VM profile (default crazyflie)")
    parser.add_argument("--world", default=None,
                        help="world to run the swarm in (default: the platform's own)")
    parser.add_argument("--robots", type=int, default=None,
                        help="robots (default: the world's default)")
    parser.add_argument("--steps", type=int, default=MEMORY_STEPS,
                        help=f"control steps (default {MEMORY_STEPS})")
    parser.add_argument("--seed", type=int, default=0, help="random seed")
    parser.add_argument("--set", dest="world_options", action="append", default=[],
                        metavar="KEY=VALUE", help="world option (as for `bbzide run`)")
    parser.add_argument("-I", dest="include", action="append", default=[],
                        help="include folder")
    parser.set_defaults(handler=run_memory)


def run_memory(args: argparse.Namespace) -> int:
    from bbzide.worlds.memory import measure

    world = args.world
    if world is None:
        world = next((name for name, spec in WORLDS.items() if spec.profile == args.platform),
                     None)
        if world is None:
            raise UserError(f"no world runs the {args.platform} platform by default; give "
                            f"--world ({', '.join(WORLDS)})")
    if world not in WORLDS:
        raise UserError(f"unknown world {world!r}; choose from {', '.join(WORLDS)}")
    if args.steps < 1:
        raise UserError(f"--steps must be at least 1, got {args.steps}")
    if args.seed < 0:
        raise UserError(f"--seed must be >= 0, got {args.seed}")
    spec = WORLDS[world]
    robots = spec.default_robots if args.robots is None else args.robots
    if robots < 1:
        raise UserError(f"--robots must be at least 1, got {robots}")
    program = load_script(Path(args.script), spec.host_names, list(args.include or []))
    report = measure(Path(args.script), program, world, args.platform, robots, args.steps,
                     args.seed, parse_world_options(args.world_options))
    print(report.text())
    return 0
