"""`bbzide run … --break FILE:LINE[:CONDITION] [--stop]`: breakpoints in a headless swarm run.

Design: the worlds room builds and summarises the run as always (`run_world`, `run_scenario`);
this module hands it a driver that runs the swarm through a `SwarmDebugger` instead of
`Simulation.run`, printing one block per breakpoint hit (robot, control step, file:line, the
function and its locals) — text a test or a grader can read. `--stop` ends the run at the
first hit (exit status 0, and the output says so). Robot errors are left to the run's summary
(the debugger does not pause on them here). A spec that cannot stop anything (no such line, a
line without code, a condition that does not compile) is a one-line `UserError` before the
run starts.
"""

from __future__ import annotations

import argparse
import re
from typing import Any

from bbzide.debugger.swarm_debugger import Breakpoint, DebuggerError, Stop, SwarmDebugger

#: FILE:LINE or FILE:LINE:CONDITION (the condition is the rest, colons included)
_SPEC = re.compile(r"^(?P<path>[^:]+):(?P<line>-?\d+)(?::(?P<condition>.*))?$")


def add_break_arguments(parser: argparse.ArgumentParser) -> None:
    group = parser.add_argument_group("breakpoints (with --world or a scenario file)")
    group.add_argument("--break", dest="breaks", action="append", default=[],
                       metavar="FILE:LINE[:CONDITION]",
                       help="print the robot, step and locals each time a robot reaches "
                            "LINE of FILE (and CONDITION, a Buzz expression, is true); "
                            "repeatable")
    group.add_argument("--stop", action="store_true",
                       help="with --break: end the run at the first hit")


def parse_break(spec: str) -> Breakpoint:
    """`FILE:LINE[:CONDITION]` as a Breakpoint (a one-line `DebuggerError` if malformed)."""
    match = _SPEC.match(spec.strip())
    if match is None:
        raise DebuggerError(f"--break {spec!r}: expected FILE:LINE or FILE:LINE:CONDITION")
    condition = match.group("condition")
    if condition is not None and not condition.strip():
        raise DebuggerError(f"--break {spec!r}: empty condition after the line number")
    return Breakpoint(int(match.group("line")), path=match.group("path"),
                      condition=condition.strip() if condition is not None else None)


def check_break_arguments(args: argparse.Namespace) -> list[Breakpoint]:
    """The run's breakpoints; `--stop` without `--break`, or `--break` where it cannot
    apply, refused."""
    breaks = list(getattr(args, "breaks", None) or [])
    if getattr(args, "stop", False) and not breaks:
        raise DebuggerError("--stop ends the run at the first --break hit: give --break "
                            "FILE:LINE")
    if breaks and getattr(args, "record", None):
        raise DebuggerError("--break cannot be combined with --record")
    return [parse_break(spec) for spec in breaks]


def run_with_breakpoints(args: argparse.Namespace) -> int:
    """`bbzide run` with `--break`: a world or scenario run driven by the debugger."""
    from bbzide.worlds import commands as world_commands

    breakpoints = check_break_arguments(args)
    stop_first = bool(getattr(args, "stop", False))

    def drive(sim: Any, steps: int) -> int:
        return drive_with_breakpoints(sim, steps, breakpoints, stop_first)

    if str(args.script).endswith(".toml"):
        return world_commands.run_scenario(args, drive)
    if not getattr(args, "world", None):
        raise DebuggerError("--break needs a swarm: give --world W or a scenario file")
    return world_commands.run_world(args, drive)


def drive_with_breakpoints(sim: Any, steps: int, breakpoints: list[Breakpoint],
                           stop_first: bool) -> int:
    """Run `steps` control steps of `sim`, printing each hit; the steps begun (a run
    stopped by `--stop` counts the step it stopped in)."""
    debugger = SwarmDebugger(sim)
    debugger.pause_on_error = False
    debugger.breakpoints = breakpoints
    first = sim.step_count
    end = first + steps
    hits = 0
    while sim.step_count < end:
        stop = debugger.run(end - sim.step_count)
        if stop is None:
            break
        hits += 1
        print(hit_block(stop, hits))
        if stop_first:
            print(f"stopped at the first hit (--stop): robot {stop.robot}, control step "
                  f"{stop.step}")
            return stop.step - first + 1
    if hits == 0:
        print("no breakpoint was hit")
    return sim.step_count - first


def hit_block(stop: Stop, number: int) -> str:
    """One hit as the command prints it: a header line, then the frame's locals."""
    frame = stop.frames[0] if stop.frames else None
    where = f" in {frame.function}" if frame is not None else ""
    condition = stop.breakpoint.condition if stop.breakpoint is not None else None
    because = f" ({condition})" if condition else ""
    lines = [f"hit {number}: robot {stop.robot}, control step {stop.step}, line {stop.line}"
             f"{where}{because}"]
    if stop.error:
        lines.append(f"  {stop.error}")
    local_values = frame.locals if frame is not None else {}
    if local_values:
        lines.extend(f"  {name} = {text}" for name, text in local_values.items())
    else:
        lines.append("  (no locals)")
    return "\n".join(lines)
