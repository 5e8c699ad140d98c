"""Scenario files: one `*.toml` that pins everything a swarm run needs besides the scripts' text.

Design: a scenario is data (`Scenario`, frozen), read with the standard `tomllib`, checked
against the schema below, and turned into a `Simulation` by `Scenario.simulation()`. Nothing
else in a run is left to defaults that could change under a class: `bbzide run S.toml`,
`bbzide ide S.toml`, a lesson and a test build the same swarm from the same file. Writing goes
through `scenario_text` (our own small TOML writer: the standard library reads TOML but does
not write it, and the schema needs only tables, arrays, strings and numbers), so
save -> load gives back an equal `Scenario`.

Schema, version 1 (docs/scenarios.md shows it with an example):

    version = 1                  required; the schema version this reader knows
    world = "kilobot"            required; a world of `bbzide worlds`
    title = "..."                optional text
    seed = 0                     optional, >= 0 (default 0)
    steps = 100                  optional, >= 0: control steps of `bbzide run` (default 100)
    asynchronous = false         optional: robots step at their own phase within a step
    watch = ["gradient"]         optional: script globals shown as labels and printed by run

    [world_options]              optional: the world's options (`bbzide run --set KEY=VALUE`)
    [radio]                      optional: comm_range (m), loss (probability per message)

    [[robots]]                   one or more robot groups, in robot-id order
    count = 12                   required, >= 1
    script = "gradient.bzz"      path relative to the scenario file; absent: passive bodies
    positions = [[x, y], ...]    optional, metres ([x, y, z] also); one per robot; all groups
                                 or none (the engine places all robots, or takes them all)
    headings = [0.0, ...]        optional, radians; needs positions
    labels = { role = "seed" }   optional labels shown by the IDE

A schema error names the file, the line and the key (`gradient.toml:9: robots[0].count: ...`).
`tomllib` reports its own syntax errors with a line and column but keeps no line for a key, so
`KeyLines` finds each key's line by scanning the text (headers, `key =` lines, multi-line arrays
skipped by bracket depth): an inline table's inner keys get their parent key's line.
"""

from __future__ import annotations

import math
import numbers
import os
import re
import tomllib
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

from bbzide.diagnostics import UserError
from bbzide.worlds.radio import WorldConfigError
from bbzide.worlds.registry import WORLDS, world_spec

#: The schema version this module reads and writes.
SCHEMA_VERSION = 1
#: Control steps of a run when the scenario does not say: the worlds room's headless default.
DEFAULT_STEPS = 100

TOP_KEYS = ("version", "world", "title", "seed", "steps", "asynchronous", "watch",
            "world_options", "radio", "robots")
GROUP_KEYS = ("count", "script", "positions", "headings", "labels")
RADIO_KEYS = ("comm_range", "loss")
#: Buzz identifiers: a letter, then letters, digits and `_` (a watch names a script global).
IDENTIFIER = re.compile(r"[A-Za-z][A-Za-z0-9_]*\Z")

KeyPath = tuple[str | int, ...]


class ScenarioError(UserError):
    """A scenario file that cannot be read or does not follow the schema."""


@dataclass(frozen=True)
class RobotGroupSpec:
    """One `[[robots]]` entry: `count` robots running `script` (None: passive bodies)."""

    count: int
    script: Path | None = None
    positions: tuple[tuple[float, ...], ...] | None = None
    headings: tuple[float, ...] | None = None
    labels: Mapping[str, Any] = field(default_factory=dict)


@dataclass(frozen=True)
class Scenario:
    """A whole run's set-up (see the module doc for the schema)."""

    world: str
    groups: tuple[RobotGroupSpec, ...]
    seed: int = 0
    steps: int = DEFAULT_STEPS
    asynchronous: bool = False
    watch: tuple[str, ...] = ()
    world_options: Mapping[str, Any] = field(default_factory=dict)
    radio: Mapping[str, float] = field(default_factory=dict)
    title: str = ""
    #: The file it was read from (None: built in memory); not part of the set-up.
    source: Path | None = field(default=None, compare=False)

    @property
    def robots(self) -> int:
        return sum(group.count for group in self.groups)

    def scripts(self) -> list[Path]:
        """The distinct scripts, in group order."""
        return list(dict.fromkeys(g.script for g in self.groups if g.script is not None))

    def with_seed(self, seed: int) -> Scenario:
        return replace(self, seed=seed)

    def with_script(self, script: Path) -> Scenario:
        """Every group that runs a script runs `script` instead (a lesson's work copy, the
        file the IDE edits); passive bodies stay passive."""
        path = Path(script).resolve()
        return replace(self, groups=tuple(g if g.script is None else replace(g, script=path)
                                          for g in self.groups))

    def radio_overrides(self) -> dict[str, Any]:
        """The `radio` table as `Simulation(radio=...)` overrides."""
        overrides: dict[str, Any] = {}
        if "comm_range" in self.radio:
            overrides["comm_range"] = float(self.radio["comm_range"])
        if "loss" in self.radio:
            overrides["loss_probability"] = float(self.radio["loss"])
            overrides["loss_by_rate"] = ()   # one loss figure replaces a rate-dependent model
        return overrides

    def programs(self, include: Sequence[str] = ()) -> dict[Path, Any]:
        """Each script compiled for the world (a `BittyBuzzProgram` per path)."""
        from bbzide.worlds.scripts import load_script

        host_names = world_spec(self.world).host_names
        return {path: load_script(path, host_names, list(include)) for path in self.scripts()}

    def simulation(self, programs: Mapping[Path, Any] | None = None, **engine_options: Any
                   ) -> Any:
        """The `Simulation` this scenario describes. `programs` (path -> program) replaces
        compiled scripts (the IDE passes the one being edited); `engine_options` go to the
        engine (robot_factory, instruction_budget, loop)."""
        import numpy as np

        from bbzide.worlds.engine import RobotGroup, Simulation

        compiled = dict(programs or {})
        missing = [p for p in self.scripts() if p not in compiled]
        if missing:
            compiled.update(replace(self, groups=tuple(
                g for g in self.groups if g.script in missing)).programs())
        groups = [RobotGroup(count=g.count, program=None if g.script is None
                             else compiled[g.script], labels=dict(g.labels))
                  for g in self.groups]
        positions = headings = None
        if self.groups[0].positions is not None:
            positions = np.array([_xyz(p) for g in self.groups for p in g.positions or ()],
                                 dtype=np.float64)
            if all(g.headings is not None for g in self.groups):
                headings = np.array([h for g in self.groups for h in g.headings or ()],
                                    dtype=np.float64)
        options: dict[str, Any] = {"watch": self.watch} if self.watch else {}
        return Simulation(self.world, groups=groups, seed=self.seed,
                          positions=positions, headings=headings,
                          world_options=dict(self.world_options), radio=self.radio_overrides(),
                          asynchronous=self.asynchronous, **options, **engine_options)


def _xyz(point: Sequence[float]) -> tuple[float, float, float]:
    return (float(point[0]), float(point[1]), float(point[2]) if len(point) > 2 else 0.0)


# ---- reading ---------------------------------------------------------------------------------
class KeyLines:
    """Line numbers of the keys of a TOML text, found by scanning it (tomllib keeps none).

    Paths are tuples: ("seed",), ("world_options", "spacing"), ("robots", 1, "count"); an
    array of tables counts its entries. A key not found (an inline table's inner key) falls back
    to the longest known prefix of its path, then to line 1.
    """

    _HEADER = re.compile(r"\s*(\[\[?)\s*([^\]]+?)\s*\]\]?\s*(#.*)?$")
    _PART = r"(?:[A-Za-z0-9_-]+|\"[^\"]*\"|'[^']*')"
    _KEY = re.compile(rf"\s*({_PART}(?:\s*\.\s*{_PART})*)\s*=")

    def __init__(self, text: str) -> None:
        self.lines: dict[KeyPath, int] = {}
        counts: dict[KeyPath, int] = {}
        table: KeyPath = ()
        depth = 0            # open brackets/braces of a multi-line value
        in_string = False    # inside a multi-line """ string
        for number, line in enumerate(text.splitlines(), start=1):
            if in_string or depth > 0:
                depth, in_string = _scan_value(line, depth, in_string)
                continue
            header = self._HEADER.match(line)
            if header and not self._KEY.match(line):
                name = tuple(_unquote(part) for part in header.group(2).split("."))
                if header.group(1) == "[[":
                    index = counts.get(name, 0)
                    counts[name] = index + 1
                    table = (*name, index)
                    self.lines.setdefault(name, number)
                else:
                    table = name
                self.lines[table] = number
                continue
            key = self._KEY.match(line)
            if key:
                path = (*table, *(_unquote(p) for p in key.group(1).split(".")))
                self.lines[path] = number
                depth, in_string = _scan_value(line[key.end():], 0, False)

    def line_of(self, path: KeyPath) -> int:
        for end in range(len(path), 0, -1):
            if path[:end] in self.lines:
                return self.lines[path[:end]]
        return 1


def _unquote(part: str) -> str:
    part = part.strip()
    return part[1:-1] if len(part) >= 2 and part[0] == part[-1] and part[0] in "\"'" else part


def _scan_value(text: str, depth: int, in_string: bool) -> tuple[int, bool]:
    """Bracket depth and multi-line-string state after `text` (strings and comments skipped)."""
    i = 0
    while i < len(text):
        if in_string:
            end = text.find('"""', i)
            if end < 0:
                return depth, True
            in_string, i = False, end + 3
            continue
        char = text[i]
        if text.startswith('"""', i):
            in_string, i = True, i + 3
            continue
        if char in "\"'":
            end = text.find(char, i + 1)
            while end > 0 and char == '"' and text[end - 1] == "\\":
                end = text.find(char, end + 1)
            i = len(text) if end < 0 else end + 1
            continue
        if char == "#":
            break
        if char in "[{":
            depth += 1
        elif char in "]}":
            depth -= 1
        i += 1
    return max(depth, 0), in_string


def describe_path(path: KeyPath) -> str:
    """("robots", 1, "count") -> "robots[1].count"."""
    text = ""
    for part in path:
        text += f"[{part}]" if isinstance(part, int) else (f".{part}" if text else part)
    return text


class _Checker:
    """Reads one parsed scenario, raising `ScenarioError` at the first schema error."""

    def __init__(self, path: Path, text: str) -> None:
        self.path = path
        self.lines = KeyLines(text)

    def fail(self, key: KeyPath, message: str) -> ScenarioError:
        where = f"{self.path}:{self.lines.line_of(key)}"
        return ScenarioError(f"{where}: {describe_path(key)}: {message}" if key
                             else f"{where}: {message}")

    def unknown_keys(self, table: Mapping[str, Any], allowed: Sequence[str],
                     prefix: KeyPath) -> None:
        for key in table:
            if key not in allowed:
                raise self.fail((*prefix, key), f"unknown key; the keys here are "
                                                f"{', '.join(allowed)}")

    def integer(self, value: Any, key: KeyPath, minimum: int = 0) -> int:
        if isinstance(value, bool) or not isinstance(value, int):
            raise self.fail(key, f"a whole number is needed, got {value!r}")
        if value < minimum:
            raise self.fail(key, f"must be >= {minimum}, got {value}")
        return value

    def number(self, value: Any, key: KeyPath) -> float:
        if isinstance(value, bool) or not isinstance(value, numbers.Real) \
                or not math.isfinite(value):
            raise self.fail(key, f"a finite number is needed, got {value!r}")
        return float(value)

    def table(self, value: Any, key: KeyPath) -> dict[str, Any]:
        if not isinstance(value, dict):
            raise self.fail(key, f"a table is needed, got {value!r}")
        return value

    def read(self, data: dict[str, Any]) -> Scenario:
        self.unknown_keys(data, TOP_KEYS, ())
        if "version" not in data:
            raise self.fail((), f"missing key 'version' (this bbzide reads version = "
                                f"{SCHEMA_VERSION})")
        version = data["version"]
        if version != SCHEMA_VERSION or isinstance(version, bool):
            raise self.fail(("version",), f"this bbzide reads scenario version "
                                          f"{SCHEMA_VERSION}, not {version!r}")
        world = data.get("world")
        if world is None:
            raise self.fail((), f"missing key 'world' (one of {', '.join(WORLDS)})")
        if world not in WORLDS:
            raise self.fail(("world",), f"unknown world {world!r}; the worlds are "
                                        f"{', '.join(WORLDS)}")
        title = data.get("title", "")
        if not isinstance(title, str):
            raise self.fail(("title",), "a string is needed")
        seed = self.integer(data.get("seed", 0), ("seed",))
        steps = self.integer(data.get("steps", DEFAULT_STEPS), ("steps",))
        asynchronous = data.get("asynchronous", False)
        if not isinstance(asynchronous, bool):
            raise self.fail(("asynchronous",), "true or false is needed")
        watch = data.get("watch", [])
        if not isinstance(watch, list):
            raise self.fail(("watch",), "a list of script global names is needed")
        for name in watch:
            if not isinstance(name, str) or not IDENTIFIER.match(name):
                raise self.fail(("watch",), f"{name!r} is not a Buzz global name")
        options = self.world_options(world, self.table(data.get("world_options", {}),
                                                       ("world_options",)))
        radio = self.radio(self.table(data.get("radio", {}), ("radio",)))
        if "robots" not in data:
            raise self.fail((), "missing [[robots]]: at least one robot group is needed")
        entries = data["robots"]
        if not isinstance(entries, list) or not entries:
            raise self.fail(("robots",), "an array of [[robots]] tables is needed")
        groups = tuple(self.group(entry, ("robots", i)) for i, entry in enumerate(entries))
        self.placement(world, options, groups)
        return Scenario(world=world, groups=groups, seed=seed, steps=steps,
                        asynchronous=asynchronous, watch=tuple(watch), world_options=options,
                        radio=radio, title=title, source=self.path)

    def world_options(self, world: str, options: dict[str, Any]) -> dict[str, Any]:
        spec = world_spec(world)
        for key, value in options.items():   # one at a time, so the error names its key
            try:
                spec.create(**{key: value})
            except WorldConfigError as error:
                raise self.fail(("world_options", key), str(error)) from None
        try:
            spec.create(**options)
        except WorldConfigError as error:
            raise self.fail(("world_options",), str(error)) from None
        return dict(options)

    def radio(self, radio: dict[str, Any]) -> dict[str, float]:
        self.unknown_keys(radio, RADIO_KEYS, ("radio",))
        checked = {key: self.number(value, ("radio", key)) for key, value in radio.items()}
        if checked.get("comm_range", 1.0) <= 0:
            raise self.fail(("radio", "comm_range"), "must be > 0 metres")
        if not 0.0 <= checked.get("loss", 0.0) <= 1.0:
            raise self.fail(("radio", "loss"), "a probability 0..1 is needed")
        return checked

    def group(self, entry: Any, key: KeyPath) -> RobotGroupSpec:
        entry = self.table(entry, key)
        self.unknown_keys(entry, GROUP_KEYS, key)
        if "count" not in entry:
            raise self.fail(key, "missing key 'count'")
        count = self.integer(entry["count"], (*key, "count"), minimum=1)
        script = None
        if "script" in entry:
            name = entry["script"]
            if not isinstance(name, str) or not name:
                raise self.fail((*key, "script"), "a path (string) is needed")
            script = Path(os.path.normpath(self.path.parent / name))
            if script.suffix not in (".bzz", ".bbo"):
                raise self.fail((*key, "script"), f"{name} is not a Buzz script (.bzz or .bbo)")
            if not script.is_file():
                raise self.fail((*key, "script"), f"no such script: {script}")
        positions = None
        if "positions" in entry:
            rows = entry["positions"]
            where = (*key, "positions")
            if not isinstance(rows, list) or len(rows) != count:
                raise self.fail(where, f"{count} [x, y] pairs are needed (one per robot)")
            points = []
            for row in rows:
                if not isinstance(row, list) or len(row) not in (2, 3):
                    raise self.fail(where, f"[x, y] or [x, y, z] in metres is needed, "
                                           f"got {row!r}")
                points.append(tuple(self.number(v, where) for v in row))
            positions = tuple(points)
        headings = None
        if "headings" in entry:
            where = (*key, "headings")
            if positions is None:
                raise self.fail(where, "headings need positions")
            rows = entry["headings"]
            if not isinstance(rows, list) or len(rows) != count:
                raise self.fail(where, f"{count} angles in radians are needed (one per robot)")
            headings = tuple(self.number(v, where) for v in rows)
        labels = self.table(entry.get("labels", {}), (*key, "labels"))
        for name, value in labels.items():
            if isinstance(value, dict | list):
                raise self.fail((*key, "labels", name), "a string or a number is needed")
        return RobotGroupSpec(count=count, script=script, positions=positions,
                              headings=headings, labels=dict(labels))

    def placement(self, world: str, options: dict[str, Any],
                  groups: tuple[RobotGroupSpec, ...]) -> None:
        pinned = [g.positions is not None for g in groups]
        if any(pinned) and not all(pinned):
            index = pinned.index(not pinned[0])
            raise self.fail(("robots", index), "positions are given for some groups and not "
                                               "others: give them for every group or none")
        built = world_spec(world).create(**options)
        total = sum(g.count for g in groups)
        fit = built.max_robots()
        if total > fit:
            raise self.fail(("robots",), f"{total} robots do not fit in this {world} world "
                                         f"(at most {fit})")
        x0, y0, x1, y1 = built.bounds
        for i, group in enumerate(groups):
            for x, y, *_ in group.positions or ():
                if not (x0 <= x <= x1 and y0 <= y <= y1):
                    raise self.fail(("robots", i, "positions"),
                                    f"({x:g}, {y:g}) is outside the world "
                                    f"({x0:g}..{x1:g} x {y0:g}..{y1:g} m)")


def parse_scenario(text: str, path: Path) -> Scenario:
    """A `Scenario` from TOML text; `path` names it in errors and anchors relative scripts."""
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as error:
        message = str(error)
        found = re.search(r"\(at line (\d+), column (\d+)\)", message)
        if found:
            message = message[:found.start()].strip()
            raise ScenarioError(f"{path}:{found.group(1)}:{found.group(2)}: TOML syntax "
                                f"error: {message}") from None
        raise ScenarioError(f"{path}: TOML syntax error: {message}") from None
    return _Checker(path, text).read(data)


def load_scenario(path: Path | str) -> Scenario:
    """Read and check a scenario file (`ScenarioError` with file:line and key otherwise)."""
    path = Path(path)
    if path.is_dir():
        raise ScenarioError(f"{path} is a folder, not a scenario file")
    try:
        data = path.read_bytes()
    except FileNotFoundError:
        raise ScenarioError(f"no such scenario: {path}") from None
    except OSError as error:
        raise ScenarioError(f"cannot read {path}: {error.strerror or error}") from None
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as error:
        line = data[:error.start].count(b"\n") + 1
        raise ScenarioError(f"{path}:{line}: not UTF-8 text (TOML files are UTF-8)") from None
    return parse_scenario(text, path.resolve())


def is_scenario(path: Path | str) -> bool:
    return Path(path).suffix == ".toml"


# ---- writing ---------------------------------------------------------------------------------
def _value(value: Any) -> str:
    """One TOML value: the types a scenario holds (bool, int, float, str, list, table)."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, numbers.Integral):
        return str(int(value))
    if isinstance(value, numbers.Real):
        number = float(value)
        if not math.isfinite(number):
            raise ScenarioError(f"cannot save the non-finite number {number}")
        text = repr(number)   # the shortest text that reads back as the same float
        return text if any(c in text for c in ".en") else text + ".0"
    if isinstance(value, str):
        escaped = value.replace("\\", "\\\\").replace('"', '\\"').replace("\n", "\\n")
        return f'"{escaped}"'
    if isinstance(value, Mapping):
        return "{ " + ", ".join(f"{_key(k)} = {_value(v)}" for k, v in value.items()) + " }"
    if isinstance(value, Sequence):
        return "[" + ", ".join(_value(v) for v in value) + "]"
    raise ScenarioError(f"cannot save {value!r} in a scenario")


def _key(key: str) -> str:
    return key if re.fullmatch(r"[A-Za-z0-9_-]+", key) else _value(key)


def _relative(script: Path, folder: Path) -> str:
    try:
        return Path(os.path.relpath(script, folder)).as_posix()
    except ValueError:   # another drive (Windows): keep the absolute path
        return script.as_posix()


def scenario_text(scenario: Scenario, folder: Path) -> str:
    """The TOML text of `scenario`, scripts written relative to `folder` (where it is saved)."""
    lines = [f"# bbzide scenario (schema version {SCHEMA_VERSION}; see docs/scenarios.md)",
             f"version = {SCHEMA_VERSION}"]
    if scenario.title:
        lines.append(f"title = {_value(scenario.title)}")
    lines += [f"world = {_value(scenario.world)}", f"seed = {scenario.seed}",
              f"steps = {scenario.steps}"]
    if scenario.asynchronous:
        lines.append("asynchronous = true")
    if scenario.watch:
        lines.append(f"watch = {_value(list(scenario.watch))}")
    if scenario.world_options:
        lines += ["", "[world_options]"]
        lines += [f"{_key(k)} = {_value(v)}" for k, v in scenario.world_options.items()]
    if scenario.radio:
        lines += ["", "[radio]"]
        lines += [f"{_key(k)} = {_value(v)}" for k, v in scenario.radio.items()]
    for group in scenario.groups:
        lines += ["", "[[robots]]", f"count = {group.count}"]
        if group.script is not None:
            lines.append(f"script = {_value(_relative(group.script, folder))}")
        if group.labels:
            lines.append(f"labels = {_value(dict(group.labels))}")
        if group.positions is not None:
            lines.append("positions = [")
            lines += [f"  {_value(list(p))}," for p in group.positions]
            lines.append("]")
        if group.headings is not None:
            lines.append(f"headings = {_value(list(group.headings))}")
    return "\n".join(lines) + "\n"


def save_scenario(scenario: Scenario, path: Path | str) -> Path:
    """Write `scenario` to `path` (scripts relative to its folder); the written file is read
    back and checked before this returns, so a saved scenario always loads."""
    path = Path(path)
    if not is_scenario(path):
        raise ScenarioError(f"{path}: a scenario file ends in .toml")
    text = scenario_text(scenario, path.resolve().parent)
    parse_scenario(text, path.resolve())   # never leave a file that does not load
    try:
        path.write_text(text, encoding="utf-8")
    except OSError as error:
        raise ScenarioError(f"cannot write {path}: {error.strerror or error}") from None
    return path


def pin_positions(scenario: Scenario, sim: Any) -> Scenario:
    """`scenario` with every robot's position and heading taken from `sim` now (the IDE's
    "save the current setup" keeps where the robots stand)."""
    groups = []
    start = 0
    for group in scenario.groups:
        rows = sim.positions[start:start + group.count]
        turns = sim.headings[start:start + group.count]
        groups.append(replace(group, positions=tuple(tuple(float(v) for v in row)
                                                      for row in rows),
                              headings=tuple(float(h) for h in turns)))
        start += group.count
    return replace(scenario, groups=tuple(groups))


def single_script_scenario(world: str, script: Path, robots: int, seed: int = 0,
                           steps: int = DEFAULT_STEPS, **extra: Any) -> Scenario:
    """The scenario of a plain `run X.bzz --world W --robots N --seed K` (and of the IDE's
    current set-up): one group running one script."""
    return Scenario(world=world, groups=(RobotGroupSpec(count=robots,
                                                        script=Path(script).resolve()),),
                    seed=seed, steps=steps, **extra)
