"""The command-line options of the corpus harnesses (``bbzharness-pc`` and ``bbzavr.py``).

Both accept ``--robot --steps --seed --loop robot|pop --reg NAME=KIND --inject FILE``
(conformance README, "Harness options used").  This module turns them into data; the harness
that runs them registers the host closures in the order given.  ``tbl.field=KIND`` entries that
follow each other form one global table ``tbl``.
"""

from __future__ import annotations

import argparse
import shlex
from dataclasses import dataclass
from pathlib import Path

from bbzide.diagnostics import UserError

#: ``trace`` and ``abs`` are ours (not the reference harness's): a firmware function shown as
#: ``name(args)``, and the absolute value of an int (the Kilobot firmware's ``abs``).
SIMPLE_KINDS = ("print", "log", "ret0", "retnil", "rand", "min", "trace", "abs")


class HarnessOptionError(UserError):
    """A harness option that cannot be understood."""


@dataclass(frozen=True)
class HostKind:
    """What a registered host closure does: ``name`` of the kind and its parameter
    (N of ``ret0/N``, V of ``reti:V``), or None."""

    name: str
    parameter: int | None = None


@dataclass(frozen=True)
class Registration:
    """One global (``table`` None) or one table of consecutive ``tbl.field`` closures."""

    name: str
    kind: HostKind | None  # None for a table
    fields: tuple[tuple[str, HostKind], ...] = ()


def parse_kind(text: str) -> HostKind:
    if text in SIMPLE_KINDS:
        return HostKind(text)
    try:
        if text.startswith("ret0/"):
            return HostKind("ret0", int(text[5:]))
        if text.startswith("reti:"):
            return HostKind("reti", int(text[5:]))
    except ValueError:
        pass
    raise HarnessOptionError(f"unknown --reg kind {text!r} (print, log, ret0, ret0/N, retnil, "
                             "rand, min, trace, abs, reti:V)")


def group_registrations(options: list[str]) -> list[Registration]:
    """``--reg`` values in order, consecutive ``tbl.field`` entries grouped into one table."""
    registrations: list[Registration] = []
    for option in options:
        name, sep, kind_text = option.partition("=")
        if not sep or not name:
            raise HarnessOptionError(f"--reg expects NAME=KIND, got {option!r}")
        kind = parse_kind(kind_text)
        table, dot, field = name.partition(".")
        if not dot:
            registrations.append(Registration(name, kind))
            continue
        if not table or not field:
            raise HarnessOptionError(f"--reg name {name!r} must be NAME or TABLE.FIELD")
        last = registrations[-1] if registrations else None
        if last is not None and last.kind is None and last.name == table:
            registrations[-1] = Registration(table, None, last.fields + ((field, kind),))
        else:
            registrations.append(Registration(table, None, ((field, kind),)))
    return registrations


@dataclass(frozen=True)
class HarnessOptions:
    bytecode: Path
    robot: int
    steps: int
    seed: int
    loop: str
    registrations: list[Registration]
    inject: Path | None


def harness_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="bbzharness", exit_on_error=False, add_help=False)
    parser.add_argument("bytecode", type=Path)
    parser.add_argument("--robot", type=int, default=0)
    parser.add_argument("--steps", type=int, default=0)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--loop", choices=("pop", "robot"), default="pop")
    parser.add_argument("--reg", action="append", default=[])
    parser.add_argument("--inject", type=Path)
    return parser


def parse_harness_arguments(argv: list[str], base: Path = Path()) -> HarnessOptions:
    """Options of one harness invocation; relative paths are taken from ``base``."""
    try:
        namespace, rest = harness_parser().parse_known_args(argv)
    except (argparse.ArgumentError, SystemExit) as error:
        raise HarnessOptionError(f"bad harness arguments {argv!r}: {error}") from None
    if rest:
        raise HarnessOptionError(f"unexpected harness arguments {rest!r}")
    return HarnessOptions(
        bytecode=base / namespace.bytecode, robot=namespace.robot, steps=namespace.steps,
        seed=namespace.seed, loop=namespace.loop,
        registrations=group_registrations(namespace.reg),
        inject=base / namespace.inject if namespace.inject else None,
    )


def split_command_line(line: str) -> list[str]:
    """A ``.cmd`` line split as a shell would (the corpus lines use no shell features)."""
    return shlex.split(line)
