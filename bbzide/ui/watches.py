"""Watches across the swarm: a value read from every robot after every step, kept as a series.

Design: a `Watch` names what to read: a Buzz expression (a global, `size(x)`, arithmetic;
evaluated with the debugger room's expression evaluator on the robot's globals, a plain global
read directly), a virtual-stigmergy key, or the heap in use (bytes between the two heap
pointers, as the inspector counts them). `read_watch` and `stigmergy_versions` read a list of
`WatchedRobot`s (id, VM, string table): the live swarm's robots after a step, or a replay's
robots rebuilt at a recorded step, so both read the very same way. `WatchBook` samples every
watch after each control step on the simulation thread (the run controller's step
listeners, registered only while a watch exists, so a run without watches pays nothing) and
keeps the last `MAX_SAMPLES` steps as arrays, one column per robot. The panel (`WatchPanel`)
draws each watch with viser's uPlot: every robot's line, or the swarm's min, mean and max,
redrawn by the app's ticker.
"""

from __future__ import annotations

import math
import threading
from collections import deque
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import viser

#: Steps kept per watch: ~80 s of a Kilobot run at 30 steps/s, and a plot of 2,500 points per
#: line still draws in a few ms.
MAX_SAMPLES = 2_500
#: Watches at once: each is a chart in the panel and a read of every robot after every step.
MAX_WATCHES = 4
#: Above this many robots a per-robot chart is unreadable: it shows min, mean and max instead.
MAX_ROBOT_LINES = 32
#: Robots whose stigmergy the Stigmergy folder reads: a table about this many robots stays
#: readable, and reading them costs well under a millisecond.
STIGMERGY_ROBOTS = 64
#: Versions listed in the Stigmergy folder (newest per key first).
STIGMERGY_ROWS = 40
#: What a watch reads (the dropdown's labels).
KINDS = {"Buzz expression": "expression", "stigmergy key": "stigmergy", "heap in use (B)": "heap"}
SHOWS = ("every robot", "min · mean · max")


class BadWatch(ValueError):
    """A watch that cannot be read (said in one line)."""


@dataclass(frozen=True)
class Watch:
    kind: str  # "expression" | "stigmergy" | "heap"
    text: str = ""  # the expression or the key
    aggregate: bool = False  # min · mean · max instead of one line per robot

    @property
    def label(self) -> str:
        if self.kind == "heap":
            return "heap in use (B)"
        return f"stigmergy[{self.text!r}]" if self.kind == "stigmergy" else self.text


def number(value: Any) -> float:
    """A watched value as a plot's number: numbers as they are, true/false as 1/0, anything
    else (nil, a table, a string, an error) as a gap."""
    if isinstance(value, bool):
        return float(value)
    if isinstance(value, int | float) and math.isfinite(value):
        return float(value)
    return math.nan


@dataclass(frozen=True)
class WatchedRobot:
    """One robot as a watch reads it: its Buzz id, its VM (None: a passive body) and the
    string table of the program it runs."""

    robot_id: int
    vm: Any
    strings: Sequence[str]


def read_watch(watch: Watch, robots: Sequence[WatchedRobot]) -> list[float]:
    """`watch` read from every robot (between two control steps): one number per robot, NaN
    where there is none (no VM, no such global or key, not a number). `BadWatch` when the
    expression does not parse or cannot be evaluated."""
    from bbzide.debugger.values import EvaluationError, parse_expression
    from bbzide.worlds.engine import read_global

    expression = None
    if watch.kind == "expression" and not watch.text.isidentifier():
        try:
            expression = parse_expression(watch.text)
        except EvaluationError as error:
            raise BadWatch(f"{watch.text}: {error}") from None
    values = []
    for robot in robots:
        vm = robot.vm
        if vm is None:
            values.append(math.nan)
        elif watch.kind == "heap":
            values.append(float(vm.heap.size - (vm.heap.ltseg - vm.heap.rtobj)))
        elif watch.kind == "stigmergy":
            values.append(number(_stigmergy_value(vm, robot.strings, watch.text)))
        elif expression is None:
            values.append(number(read_global(vm, list(robot.strings), watch.text)))
        else:
            try:
                values.append(number(expression.evaluate(_globals_lookup(vm, robot.strings))))
            except EvaluationError as error:
                raise BadWatch(f"{watch.text}: {error}") from None
    return values


def _globals_lookup(vm: Any, strings: Sequence[str]) -> Callable[[str], Any]:
    """name -> the robot's global of that name, decoded (`KeyError` when none)."""
    from bbzide.debugger.values import decode
    from bbzide.vm.inspector import globals_by_name

    table = list(strings)
    by_name = globals_by_name(vm, table)

    def lookup(name: str) -> Any:
        where = by_name.get(name)
        if where is None:
            raise KeyError(name)
        return decode(vm, where, table)

    return lookup


def stigmergy_versions(robots: Sequence[WatchedRobot]
                       ) -> list[tuple[str, int, int, str, list[int]]]:
    """Every virtual-stigmergy version the robots hold: (key, Lamport timestamp, writer
    robot id, value, ids of the robots holding that version), by key and newest first."""
    holders: dict[tuple[str, int, int, str], list[int]] = {}
    for robot in robots:
        vm = robot.vm
        if vm is None:
            continue
        strings = list(robot.strings)
        for entry in getattr(vm.vstig, "entries", []):
            key = strings[entry.key] if 0 <= entry.key < len(strings) else f"#{entry.key}"
            value = heap_text(vm, strings, entry.value)
            holders.setdefault((key, int(entry.timestamp), int(entry.robot), value),
                               []).append(robot.robot_id)
    rows = [(key, stamp, writer, value, ids)
            for (key, stamp, writer, value), ids in holders.items()]
    return sorted(rows, key=lambda row: (row[0], -row[1], row[2]))


def stigmergy_markdown(rows: list[tuple[str, int, int, str, list[int]]]) -> str:
    """The Stigmergy folder: each key's versions (Lamport timestamp, writer, value) and the
    robots holding each, newest first."""
    if not rows:
        return "*no robot holds a stigmergy entry*"
    lines = ["| key | t | by | value | held by |", "|---|---:|---:|---|---|"]
    for key, stamp, writer, value, holders in rows[:STIGMERGY_ROWS]:
        held = ", ".join(map(str, holders[:12])) + (f" +{len(holders) - 12}"
                                                    if len(holders) > 12 else "")
        lines.append(f"| `{key}` | {stamp} | {writer} | `{value}` | {held} |")
    if len(rows) > STIGMERGY_ROWS:
        lines.append(f"\n*{len(rows) - STIGMERGY_ROWS} older versions not shown*")
    return (f"Versions held by the first {STIGMERGY_ROBOTS} robots (t = Lamport timestamp, "
            "by = the robot that wrote it)\n\n" + "\n".join(lines))


def heap_value(vm: Any, strings: Sequence[str], index: int) -> Any:
    """The heap object `index` as a Python value (int, float, string; None otherwise)."""
    from bbzide.compiler.bbzfloat import to_float
    from bbzide.vm import heap as heap_room

    heap = vm.heap
    if not 0 <= index < heap.object_count:
        return None
    kind = heap.obj_type(index)
    if kind == heap_room.INT:
        return heap.int_value(index)
    if kind == heap_room.FLOAT:
        return to_float(heap.u16(index))
    if kind == heap_room.STRING:
        sid = heap.u16(index)
        return strings[sid] if sid < len(strings) else f"#{sid}"
    return None


def heap_text(vm: Any, strings: Sequence[str], index: int) -> str:
    """The heap object `index` as the stigmergy view prints it (a kind name for a table)."""
    value = heap_value(vm, strings, index)
    if value is None:
        kind = vm.heap.obj_type(index) if 0 <= index < vm.heap.object_count else -1
        names = ("nil", "int", "float", "string", "table", "closure", "userdata")
        return names[kind] if 0 <= kind < len(names) else "?"
    return f"{value:.4g}" if isinstance(value, float) else repr(value) \
        if isinstance(value, str) else str(value)


def _stigmergy_value(vm: Any, strings: Sequence[str], key: str) -> Any:
    """The value the robot's stigmergy holds for `key` (None when it holds none)."""
    for entry in getattr(vm.vstig, "entries", []):
        if 0 <= entry.key < len(strings) and strings[entry.key] == key:
            return heap_value(vm, strings, entry.value)
    return None


class WatchBook:
    """The watches of one run and their samples; `sample` runs on the simulation thread,
    everything else on any thread."""

    def __init__(self, on_first: Callable[[], None] = lambda: None,
                 on_empty: Callable[[], None] = lambda: None) -> None:
        self._lock = threading.Lock()
        self._watches: list[Watch] = []
        self._samples: dict[Watch, deque[tuple[int, np.ndarray]]] = {}
        self._on_first, self._on_empty = on_first, on_empty
        self.errors: dict[Watch, str] = {}
        self.generation = 0  # bumps when the list of watches changes

    @property
    def watches(self) -> list[Watch]:
        with self._lock:
            return list(self._watches)

    def add(self, watch: Watch) -> None:
        if watch.kind != "heap" and not watch.text.strip():
            raise BadWatch("type what to watch first (a global, an expression or a key)")
        with self._lock:
            if watch in self._watches:
                return
            if len(self._watches) >= MAX_WATCHES:
                raise BadWatch(f"at most {MAX_WATCHES} watches: clear one first")
            first = not self._watches
            self._watches.append(watch)
            self._samples[watch] = deque(maxlen=MAX_SAMPLES)
            self.generation += 1
        if first:
            self._on_first()

    def clear(self) -> None:
        with self._lock:
            had = bool(self._watches)
            self._watches, self._samples, self.errors = [], {}, {}
            self.generation += 1
        if had:
            self._on_empty()

    def clear_samples(self) -> None:
        """Forget every series, keep the watches (a replay shows the series anew at a seek)."""
        with self._lock:
            for series in self._samples.values():
                series.clear()
            self.errors = {}

    def sample(self, step: int, read: Callable[[Watch], Sequence[float]]) -> None:
        """Read every watch at `step` (after it) with `read(watch) -> one number per robot`;
        a step seen again (a step back, a reset) starts the series again from there."""
        for watch in self.watches:
            try:
                values = np.asarray(read(watch), dtype=np.float64)
            except BadWatch as error:
                self.errors[watch] = str(error)
                continue
            with self._lock:
                series = self._samples.get(watch)
                if series is None:
                    continue
                while series and series[-1][0] >= step:
                    series.pop()
                series.append((step, values))
                self.errors.pop(watch, None)

    def series(self, watch: Watch) -> tuple[np.ndarray, np.ndarray]:
        """(steps, values[step, robot]) of `watch`, robots padded with gaps to the widest."""
        with self._lock:
            samples = list(self._samples.get(watch, ()))
        if not samples:
            return np.zeros(0), np.zeros((0, 0))
        width = max(len(values) for _, values in samples)
        table = np.full((len(samples), width), np.nan)
        for row, (_, values) in enumerate(samples):
            table[row, :len(values)] = values
        return np.array([step for step, _ in samples], dtype=np.float64), table


def chart_data(watch: Watch, steps: np.ndarray, table: np.ndarray, robot_ids: Sequence[int]
               ) -> tuple[tuple[np.ndarray, ...], tuple[dict[str, Any], ...]]:
    """uPlot's data and series for one watch: one line per robot, or min, mean and max."""
    x_series: dict[str, Any] = {"label": "step"}
    if watch.aggregate or table.shape[1] > MAX_ROBOT_LINES:
        with np.errstate(all="ignore"):
            present = ~np.all(np.isnan(table), axis=1, keepdims=True) if table.size else None
            filled = np.where(np.isnan(table), np.inf, table)
            low = np.where(present, filled.min(axis=1, initial=np.inf, keepdims=True), np.nan)
            filled = np.where(np.isnan(table), -np.inf, table)
            high = np.where(present, filled.max(axis=1, initial=-np.inf, keepdims=True), np.nan)
            mean = np.nanmean(table, axis=1) if table.size else np.zeros(0)
        lines = (low.ravel(), mean, high.ravel())
        series = ({"label": "min", "stroke": "#74c0fc", "width": 1},
                  {"label": "mean", "stroke": "#1864ab", "width": 2},
                  {"label": "max", "stroke": "#e8590c", "width": 1})
        return (steps, *lines), (x_series, *series)
    lines = tuple(table[:, column] for column in range(table.shape[1]))
    series = tuple({"label": f"robot {robot_ids[c] if c < len(robot_ids) else c}",
                    "stroke": _colour(c), "width": 1} for c in range(table.shape[1]))
    return (steps, *lines), (x_series, *series)


def _colour(column: int) -> str:
    """Distinct line colours: hues around the wheel by the golden angle."""
    hue = (column * 137.508) % 360
    return f"hsl({hue:.0f}, 65%, 45%)"


class WatchPanel:
    """The Watches folder: what to watch, how to show it, and one chart per watch."""

    def __init__(self, server: viser.ViserServer, book: WatchBook,
                 robot_ids: Callable[[], Sequence[int]]) -> None:
        self.book = book
        self.robot_ids = robot_ids
        self._gui = server.gui
        self._charts: dict[Watch, viser.GuiUplotHandle] = {}
        self._generation = -1
        with self._gui.add_folder("Watches", order=2.5, expand_by_default=False) as folder:
            self.folder = folder
            self.what = self._gui.add_text("Watch", initial_value="",
                                           hint="A global (gradient), an expression (size(t)), "
                                                "or a stigmergy key")
            self.kind = self._gui.add_dropdown("Reads", tuple(KINDS))
            self.show = self._gui.add_dropdown("Show", SHOWS)
            self.add = self._gui.add_button("Add watch", icon=viser.Icon.CHART_LINE)
            self.clear = self._gui.add_button("Clear watches", icon=viser.Icon.TRASH)
            self.note = self._gui.add_markdown("")
        self.add.on_click(lambda _: self.add_watch(
            Watch(KINDS[str(self.kind.value)], str(self.what.value).strip(),
                  self.show.value == SHOWS[1])))
        self.clear.on_click(lambda _: self.book.clear())

    def add_watch(self, watch: Watch) -> None:
        try:
            self.book.add(watch)
            self.note.content = ""
        except BadWatch as error:
            self.note.content = f"⚠ {error}"

    def refresh(self) -> None:
        """Redraw every chart from its samples (the app's ticker)."""
        if self.book.generation != self._generation:
            self._generation = self.book.generation
            for chart in self._charts.values():
                chart.remove()
            self._charts = {}
        errors = self.book.errors
        notes = [f"⚠ `{w.label}`: {text}" for w, text in errors.items()]
        text = "  \n".join(notes)
        if self.note.content != text and (notes or self.note.content.startswith("⚠ `")):
            self.note.content = text
        ids = list(self.robot_ids())
        for watch in self.book.watches:
            steps, table = self.book.series(watch)
            if len(steps) < 2:
                continue  # uPlot needs two points to draw a line
            data, series = chart_data(watch, steps, table, ids)
            chart = self._charts.get(watch)
            if chart is None or len(chart.series) != len(series):
                if chart is not None:
                    chart.remove()
                with self.folder:
                    chart = self._gui.add_uplot(
                        data, series, title=watch.label, aspect=1.6,
                        scales={"x": {"time": False}},  # control steps, not a date
                        axes=({"label": "control step"}, {}),
                        legend={"show": len(series) <= 8})
                self._charts[watch] = chart
            else:
                chart.data = data
