"""Watches across the swarm: a value read from every robot after every step, kept as a series.

Design: a `Watch` names what to read: a Buzz expression (a global, `size(x)`, arithmetic;
evaluated by the debugger room in each robot's context, a plain global read directly), a
virtual-stigmergy key, or the heap in use (bytes between the two heap pointers, as the
inspector counts them). `WatchBook` samples every watch after each control step on the
simulation thread (the run controller's step listeners, registered only while a watch exists,
so a run without watches pays nothing) and keeps the last `MAX_SAMPLES` steps as arrays, one
column per robot. The panel (`WatchPanel`) draws each watch with viser's uPlot: every robot's
line, or the swarm's min, mean and max, redrawn by the app's ticker.
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
