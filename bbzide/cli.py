"""The `bbzide` command: one entry point that hands each subcommand to the room that owns it.

    bbzide                      the IDE on the default world (same as `bbzide ide`)
    bbzide compile X.bzz ...    compiler room  (bbzide.compiler.commands)
    bbzide disasm X.bo|X.bbo    compiler room
    bbzide bo2bbo X.bo          compiler room
    bbzide run X.bzz|X.bbo --platform P ...   one robot on the VM model (bbzide.harness.commands)
    bbzide run X.bzz --world W --robots N ... a swarm in a world (bbzide.worlds.commands)
    bbzide run S.toml [--steps S] [--seed K]  a scenario file's swarm (bbzide.worlds.commands)
    bbzide run ... --break F:LINE[:COND] [--stop]  breakpoint hits (bbzide.debugger.commands)
    bbzide ide [X.bzz] ...      the browser IDE (bbzide.ui.commands)
    bbzide replay X.rrd         the browser IDE in replay mode (bbzide.ui.commands)
    bbzide lesson [N] [--check [FILE] | --reset]  the teaching track (bbzide.ui.lesson_commands)

Each room's `commands` module exposes `register(subparsers)`; rooms are imported lazily so that
`bbzide compile` never pays for importing viser. `run` is shared by two rooms, so it is defined
here: `bbzide.harness.commands.add_run_arguments(parser)` adds the single-robot options (the corpus
harness's: --platform, --robot, --reg, --inject, --loop, --seed, --dump, ...) and
`bbzide.worlds.commands.add_world_run_arguments(parser)` the swarm options (--world, --robots, ...);
with `--world` or a scenario file (`.toml`) the worlds room runs it (`run_world(args)`,
`run_scenario(args)`), otherwise the VM room
(`run_single_robot(args)`); with `--record` (options from
`bbzide.recording.commands.add_record_arguments`) the recording room runs it
(`run_recorded(args)`, above the worlds, which never import it); with `--break`/`--stop`
(`bbzide.debugger.commands.add_break_arguments`) the debugger room drives the world run
(`run_with_breakpoints(args)`). This file only routes and
turns `UserError` into a one-screen message with exit status 1: no traceback reaches a user.
Any other exception is a bug of ours: the user sees one line naming it and the file where its
traceback was saved (exit status 70, `EX_SOFTWARE` of sysexits.h); `BBZIDE_TRACEBACK=1` lets it
propagate for whoever debugs bbzide. A `.bo` given to `run` (the reference VM's bytecode, which
the BittyBuzz model does not run) is named as such with the `bo2bbo` command that converts it.
"""

from __future__ import annotations

import argparse
import importlib
import os
import sys
import tempfile
import traceback
from collections.abc import Sequence
from pathlib import Path

from bbzide.diagnostics import UserError

#: Exit status of a bug (an exception that is not a UserError): EX_SOFTWARE of sysexits.h.
EXIT_BUG = 70

#: Rooms that contribute subcommands, lowest first (the order of the help text).
COMMAND_MODULES = (
    "bbzide.compiler.commands",
    "bbzide.harness.commands",
    "bbzide.worlds.commands",
    "bbzide.ui.commands",
    "bbzide.ui.lesson_commands",
)


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="bbzide",
        description="Buzz swarm IDE and simulator on a byte-faithful BittyBuzz VM model.",
    )
    subparsers = parser.add_subparsers(dest="command", metavar="COMMAND")
    for module_name in COMMAND_MODULES:
        try:
            module = importlib.import_module(module_name)
        except ModuleNotFoundError as missing:
            if missing.name != module_name:
                raise
            continue
        module.register(subparsers)
    _register_run(subparsers)
    return parser


def _optional_module(name: str):  # noqa: ANN202 - a module or None
    try:
        return importlib.import_module(name)
    except ModuleNotFoundError as missing:
        if missing.name != name:
            raise
        return None


def _register_run(subparsers: argparse._SubParsersAction) -> None:
    vm_commands = _optional_module("bbzide.harness.commands")
    world_commands = _optional_module("bbzide.worlds.commands")
    if vm_commands is None and world_commands is None:
        return
    run = subparsers.add_parser(
        "run",
        help="run a Buzz script: one robot on the VM model, or a swarm in a world (--world)",
    )
    if vm_commands is not None:
        vm_commands.add_run_arguments(run)
    if world_commands is not None:
        world_commands.add_world_run_arguments(run)
    record_commands = _optional_module("bbzide.recording.commands")
    if record_commands is not None:
        record_commands.add_record_arguments(run)
    debugger_commands = _optional_module("bbzide.debugger.commands")
    if debugger_commands is not None:
        debugger_commands.add_break_arguments(run)

    def dispatch(args: argparse.Namespace) -> int:
        script = Path(str(getattr(args, "script", "")))
        if script.suffix == ".bo":
            raise UserError(f"{script} is bytecode for the reference Buzz VM; the BittyBuzz model "
                            f"runs a .bbo: bbzide bo2bbo {script}, then run "
                            f"{script.with_suffix('.bbo')} (or run the .bzz)")
        if script.suffix == ".toml" and world_commands is None:
            raise UserError("scenario files need the worlds, not in this build")
        if getattr(args, "breaks", None) or getattr(args, "stop", False):
            if debugger_commands is None:
                raise UserError("--break needs the debugger, not in this build")
            return int(debugger_commands.run_with_breakpoints(args) or 0)
        if getattr(args, "record", None):
            if record_commands is None:
                raise UserError("recording is not available in this build")
            return int(record_commands.run_recorded(args) or 0)
        if script.suffix == ".toml":
            return int(world_commands.run_scenario(args) or 0)
        if getattr(args, "world", None):
            if world_commands is None:
                raise UserError("worlds are not available in this build")
            return int(world_commands.run_world(args) or 0)
        if vm_commands is None:
            raise UserError("give --world: single-robot runs are not available in this build")
        return int(vm_commands.run_single_robot(args) or 0)

    # --seed not given: None (a scenario's own seed stands; both rooms read None as 0)
    run.set_defaults(handler=dispatch, seed=None)


def main(argv: Sequence[str] | None = None) -> int:
    arguments = list(sys.argv[1:] if argv is None else argv)
    parser = build_parser()
    if not arguments:
        arguments = ["ide"]
    args = parser.parse_args(arguments)
    handler = getattr(args, "handler", None)
    if handler is None:
        parser.print_help()
        return 2
    try:
        return int(handler(args) or 0)
    except UserError as error:
        print(error.render(), file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        return 130
    except BrokenPipeError:
        return 0
    except Exception as bug:
        if os.environ.get("BBZIDE_TRACEBACK"):
            raise
        print(_report_bug(bug), file=sys.stderr)
        return EXIT_BUG


def _report_bug(bug: Exception) -> str:
    """One line for the user; the traceback goes to a file they can attach to a bug report."""
    what = f"{type(bug).__name__}: {bug}"
    try:
        with tempfile.NamedTemporaryFile("w", prefix="bbzide-bug-", suffix=".txt",
                                         delete=False, encoding="utf-8") as saved:
            saved.write(f"bbzide {' '.join(sys.argv[1:])}\n\n")
            saved.write("".join(traceback.format_exception(bug)))
        where = f"; traceback saved in {saved.name}"
    except OSError:
        where = ""
    return f"error: internal error (a bug in bbzide): {what}{where}"


if __name__ == "__main__":
    sys.exit(main())
