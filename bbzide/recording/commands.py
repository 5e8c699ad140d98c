"""`bbzide run X.bzz --world W --record mission.rrd [--force] [--keyframe-every K]`, and
`bbzide run S.toml --record mission.rrd` (a scenario file's swarm, bbzide/worlds/scenario.py).

The recording room sits above the worlds room, so the worlds' `run` command knows nothing of
recording: `bbzide/cli.py` adds these options to the shared `run` parser and, when `--record`
is given, hands the run here. We build the same swarm `bbzide.worlds.commands.run_world` would
(same script loading, seed check, world options, radio overrides, `--budget`/`--loop`,
`--asynchronous`, reusing its helpers) but through a `Recordable` robot factory, record every
step, and print the worlds' summary plus the recording's figures (file size, share of the run
time spent recording).
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path
from typing import Any

from bbzide.recording.recorder import KEYFRAME_EVERY, RecordingError, check_output_path


def add_record_arguments(parser: argparse.ArgumentParser) -> None:
    group = parser.add_argument_group("recording (with --world)")
    group.add_argument("--record", type=Path, metavar="FILE.rrd",
                       help="write the run to a Rerun recording (replay: bbzide replay FILE.rrd)")
    group.add_argument("--force", action="store_true", help="overwrite an existing recording")
    group.add_argument("--keyframe-every", type=int, default=KEYFRAME_EVERY, metavar="K",
                       help=f"VM keyframe interval in steps (default {KEYFRAME_EVERY})")


def run_recorded(args: argparse.Namespace) -> int:
    from bbzide.recording.recorder import Recordable
    from bbzide.worlds import commands as world_commands
    from bbzide.worlds.engine import Simulation
    from bbzide.worlds.radio import WorldConfigError
    from bbzide.worlds.registry import world_spec

    if Path(args.script).suffix == ".toml":
        return _run_recorded_scenario(args)
    if not getattr(args, "world", None):
        raise RecordingError("--record needs --world: recordings are of swarms in a world")
    path = check_output_path(Path(args.record), bool(args.force))
    spec = world_spec(args.world)
    steps = int(args.steps if args.steps is not None else world_commands.DEFAULT_STEPS)
    if steps < 0:
        raise WorldConfigError(f"--steps must be >= 0, got {steps}")
    seed = world_commands.seed_of(args)
    vm_options = world_commands.vm_options_for_world(args)  # --budget, --loop; refuses --dump...
    robots = args.robots if args.robots is not None else spec.default_robots
    script = Path(args.script)
    program = world_commands.load_script(script, spec.host_names,
                                         list(getattr(args, "include", []) or []))
    radio: dict[str, Any] = {}
    if args.comm_range is not None:
        radio["comm_range"] = args.comm_range
    if args.loss is not None:
        radio["loss_probability"] = args.loss
        radio["loss_by_rate"] = ()
    source = script.read_text(encoding="utf-8", errors="replace") if script.suffix == ".bzz" \
        else None
    started = time.perf_counter()
    # The factory builds the robots, so it (not the engine) takes --budget and --loop; the
    # recorder writes them into the recording's metadata for the replay's rebuilt robots.
    recordable = Recordable(loop=vm_options.get("loop", "pop"),
                            instruction_budget=vm_options.get("instruction_budget"))
    sim = Simulation(spec.name, program, robots=robots, seed=seed,
                     world_options=world_commands.parse_world_options(args.world_options),
                     radio=radio, robot_factory=recordable.factory,
                     asynchronous=bool(getattr(args, "asynchronous", False)))
    return _record_run(args, path, sim, recordable, steps, lambda _program: source,
                       booted_in=time.perf_counter() - started)


def _run_recorded_scenario(args: argparse.Namespace) -> int:
    """`bbzide run S.toml --record FILE.rrd`: the scenario's swarm, recorded (each robot's
    source is its group's script)."""
    from bbzide.recording.recorder import Recordable
    from bbzide.worlds import commands as world_commands

    scenario, steps, vm_options, programs = world_commands.prepare_scenario(args)
    path = check_output_path(Path(args.record), bool(args.force))
    sources = {id(program): script.read_text(encoding="utf-8", errors="replace")
               for script, program in programs.items() if script.suffix == ".bzz"}
    started = time.perf_counter()
    recordable = Recordable(loop=vm_options.get("loop", "pop"),
                            instruction_budget=vm_options.get("instruction_budget"))
    sim = scenario.simulation(programs, robot_factory=recordable.factory)
    return _record_run(args, path, sim, recordable, steps,
                       lambda program: sources.get(id(program)),
                       booted_in=time.perf_counter() - started)


def _record_run(args: argparse.Namespace, path: Path, sim: Any, recordable: Any, steps: int,
                source_of: Any, booted_in: float) -> int:
    """Run `steps` steps of the booted `sim`, recording each into `path`; print the worlds'
    summary and the recording's figures."""
    from bbzide.recording.recorder import MissionRecorder
    from bbzide.worlds import commands as world_commands

    booted = time.perf_counter()
    recorder = MissionRecorder(path, sim, recordable, force=bool(args.force),
                               keyframe_every=int(args.keyframe_every), source_of=source_of)
    try:
        for _ in range(steps):
            sim.step()
            recorder.record_step()
    finally:
        recorder.close()
    run_seconds = time.perf_counter() - booted
    print(world_commands.summary(sim, steps, booted_in, run_seconds))
    share = 100 * recorder.seconds_spent / run_seconds if run_seconds > 0 else 0.0
    print(f"recording: {path} ({path.stat().st_size / 1e6:.2f} MB, steps "
          f"{recorder.start_step}..{sim.step_count}; recording took {share:.1f} % of the run)")
    return 0
