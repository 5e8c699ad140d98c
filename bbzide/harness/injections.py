"""Parsing of the corpus harness's ``--inject`` files (conformance README, "Harness options used").

A line is ``STEP TYPE ARGS``; ``#`` starts a comment.  Types:

* ``bc RID TOPIC VTYPE VALUE [DIST AZ EL]`` - a broadcast from robot RID (with a position, the
  neighbor table is fed first, as the Kilobot receive handler does);
* ``vput|vquery RID KEY VTYPE VALUE LAMPORT`` - a virtual-stigmergy put or query;
* ``nb RID DIST AZ EL`` - only a neighbor entry, no message.

Quoted topics, keys and string values are names in the ``.bo`` string table; they are kept as
names here and resolved by the harness, which owns the string table.  This module only reads
text, so a malformed line becomes an ``InjectionError`` naming the file line, never a crash.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from bbzide.diagnostics import UserError

VALUE_TYPES = ("nil", "int", "float", "string")


class InjectionError(UserError):
    """A line of an ``--inject`` file that cannot be read."""


@dataclass(frozen=True)
class InjectedValue:
    """A Buzz value written in an injection line: VTYPE and its text (a name for strings)."""

    type_name: str
    text: str


@dataclass(frozen=True)
class Position:
    """Distance, azimuth, elevation as written (bbzfloat on PC, uint8 on Kilobot when applied)."""

    distance: float
    azimuth: float
    elevation: float


@dataclass(frozen=True)
class Injection:
    """One injection line: queued right before ``process_inmsgs`` of control step ``step``."""

    step: int
    kind: str  # "bc", "vput", "vquery", "nb"
    robot: int
    line: str  # the line as written (the PC harness echoes it in its ``inject`` line)
    topic: str | None = None  # bc topic or vstig key (a string-table name)
    value: InjectedValue | None = None
    lamport: int | None = None
    position: Position | None = None


def _unquote(token: str) -> str:
    return token[1:-1] if len(token) >= 2 and token[0] == token[-1] == '"' else token


def _number(token: str, what: str, lineno: int) -> float:
    try:
        return float(token)
    except ValueError:
        raise InjectionError(f"line {lineno}: {what} {token!r} is not a number") from None


def _integer(token: str, what: str, lineno: int) -> int:
    try:
        return int(token)
    except ValueError:
        raise InjectionError(f"line {lineno}: {what} {token!r} is not an integer") from None


def _value(tokens: list[str], lineno: int) -> InjectedValue:
    type_name = tokens[0]
    if type_name not in VALUE_TYPES:
        allowed = ", ".join(VALUE_TYPES)
        raise InjectionError(f"line {lineno}: value type {type_name!r} is not one of {allowed}")
    return InjectedValue(type_name, _unquote(tokens[1]))


def parse_injection_line(text: str, lineno: int = 1) -> Injection | None:
    """One line of an ``--inject`` file, or None for a blank or comment line."""
    body = text.split("#", 1)[0].strip()
    if not body:
        return None
    tokens = body.split()
    if len(tokens) < 3:
        raise InjectionError(f"line {lineno}: expected 'STEP TYPE ARGS', got {body!r}")
    step = _integer(tokens[0], "step", lineno)
    kind, args = tokens[1], tokens[2:]
    robot = _integer(args[0], "robot id", lineno)
    if kind == "nb":
        if len(args) != 4:
            raise InjectionError(f"line {lineno}: 'nb' takes RID DIST AZ EL")
        position = Position(*(_number(t, "position", lineno) for t in args[1:4]))
        return Injection(step, kind, robot, body, position=position)
    if kind == "bc":
        if len(args) not in (4, 7):
            raise InjectionError(
                f"line {lineno}: 'bc' takes RID TOPIC VTYPE VALUE [DIST AZ EL]")
        position = None
        if len(args) == 7:
            position = Position(*(_number(t, "position", lineno) for t in args[4:7]))
        return Injection(step, kind, robot, body, topic=_unquote(args[1]),
                         value=_value(args[2:4], lineno), position=position)
    if kind in ("vput", "vquery"):
        if len(args) != 5:
            raise InjectionError(f"line {lineno}: '{kind}' takes RID KEY VTYPE VALUE LAMPORT")
        lamport = _integer(args[4], "lamport", lineno)
        if not 0 <= lamport <= 255:  # the wire field is a u8
            raise InjectionError(f"line {lineno}: lamport {lamport} does not fit in a byte")
        return Injection(step, kind, robot, body, topic=_unquote(args[1]),
                         value=_value(args[2:4], lineno), lamport=lamport)
    raise InjectionError(f"line {lineno}: unknown injection type {kind!r} (bc, vput, vquery, nb)")


def parse_injection_file(path: Path) -> list[Injection]:
    """All injections of a file, in file order."""
    injections = []
    for lineno, text in enumerate(path.read_text().splitlines(), start=1):
        injection = parse_injection_line(text, lineno)
        if injection is not None:
            injections.append(injection)
    return injections
