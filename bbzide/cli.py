"""The `bbzide` command: one entry point that hands each subcommand to the room that owns it.

    bbzide                      the IDE on the default world (same as `bbzide ide`)
    bbzide compile X.bzz ...    compiler room  (bbzide.compiler.commands)
    bbzide disasm X.bo|X.bbo    compiler room
    bbzide bo2bbo X.bo          compiler room
    bbzide run X.bzz|X.bbo --platform P ...   one robot on the VM model (bbzide.vm.commands)
    bbzide run X.bzz --world W --robots N ... a swarm in a world (bbzide.worlds.commands)
    bbzide ide [X.bzz] ...      the browser IDE (bbzide.ui.commands)
    bbzide replay X.rrd         the browser IDE in replay mode (bbzide.ui.commands)

Each room's `commands` module exposes `register(subparsers)`; rooms are imported lazily so that
`bbzide compile` never pays for importing viser. This file only routes and turns `UserError`
into a one-screen message with exit status 1: no traceback reaches a user.
"""

from __future__ import annotations

import argparse
import importlib
import sys
from collections.abc import Sequence

from bbzide.diagnostics import UserError

#: Rooms that contribute subcommands, lowest first (the order of the help text).
COMMAND_MODULES = (
    "bbzide.compiler.commands",
    "bbzide.vm.commands",
    "bbzide.worlds.commands",
    "bbzide.ui.commands",
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
    return parser


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


if __name__ == "__main__":
    sys.exit(main())
