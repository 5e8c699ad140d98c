"""The IDE's breakpoints: the lines the user marked in the editor's gutter, kept on the server.

Design: the editor page owns where a breakpoint sits while the user types (CodeMirror maps its
markers through every edit), and sends the whole list after each change and each save, naming
the text revision the lines belong to. `BreakpointBook` keeps that list, drops the lines that
hold no code in the program compiled from that revision (a breakpoint on a comment or a blank
line could never stop), and hands the page the list back in every state it polls, so the page
shows what the debugger really uses. One book per IDE: every tab sees the same breakpoints.
"""

from __future__ import annotations

import threading
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from typing import Any

from bbzide.compiler.program import BittyBuzzProgram
from bbzide.debugger.source_map import SourceMap

#: More breakpoints than a person sets by hand; bounds what one message can make the run check.
MAX_BREAKPOINTS = 200
#: A condition is one Buzz expression; a longer text is a paste gone wrong, not a condition.
MAX_CONDITION_CHARS = 500


class BadBreakpoint(ValueError):
    """A breakpoint the page sent that the IDE cannot use (said in one line)."""


@dataclass(frozen=True)
class LineBreakpoint:
    """A breakpoint on `line` (1-based) of the edited file; optionally only for the robot with
    Buzz id `robot`, only when `condition` (a Buzz expression in that robot's context) is
    true, and only from its `hit_count`-th hit on."""

    line: int
    condition: str | None = None
    robot: int | None = None
    hit_count: int | None = None

    def as_json(self) -> dict[str, Any]:
        return {"line": self.line, "condition": self.condition, "robot": self.robot,
                "hit_count": self.hit_count}

    @classmethod
    def from_json(cls, data: object) -> LineBreakpoint:
        if not isinstance(data, dict):
            raise BadBreakpoint("a breakpoint is an object {line, condition, robot, hit_count}")
        line = _whole(data.get("line"), "line", minimum=1)
        if line is None:
            raise BadBreakpoint("a breakpoint needs \"line\": a line number from 1")
        condition = data.get("condition")
        if condition is not None and not isinstance(condition, str):
            raise BadBreakpoint("a breakpoint's \"condition\" is a Buzz expression (text)")
        condition = (condition or "").strip() or None
        if condition is not None and len(condition) > MAX_CONDITION_CHARS:
            raise BadBreakpoint(f"a condition has at most {MAX_CONDITION_CHARS} characters")
        return cls(line, condition, _whole(data.get("robot"), "robot", minimum=0),
                   _whole(data.get("hit_count"), "hit_count", minimum=1))

    def describe(self) -> str:
        """How the Debug panel lists it: `line 12 · robot 3 · when x > 2 · from hit 5`."""
        parts = [f"line {self.line}"]
        if self.robot is not None:
            parts.append(f"robot {self.robot}")
        if self.condition:
            parts.append(f"when {self.condition}")
        if self.hit_count:
            parts.append(f"from hit {self.hit_count}")
        return " · ".join(parts)


def _whole(value: object, name: str, minimum: int) -> int | None:
    if value is None or value == "":
        return None
    if isinstance(value, bool) or not isinstance(value, int) or value < minimum:
        raise BadBreakpoint(f"a breakpoint's \"{name}\" is a whole number from {minimum}")
    return value


def parse_breakpoints(items: object) -> list[LineBreakpoint]:
    """The page's list as breakpoints, one per line (the last one sent for a line wins)."""
    if not isinstance(items, list):
        raise BadBreakpoint("\"breakpoints\" is a list of {line, condition, robot, hit_count}")
    if len(items) > MAX_BREAKPOINTS:
        raise BadBreakpoint(f"at most {MAX_BREAKPOINTS} breakpoints")
    by_line = {b.line: b for b in map(LineBreakpoint.from_json, items)}
    return [by_line[line] for line in sorted(by_line)]


def code_lines(program: Any) -> set[int] | None:
    """The lines of the program's main file where the debugger can stop: the lines a
    statement starts on (the debugger room's `SourceMap`; the raw debug map puts a
    statement's last instructions on the next statement's line). None for a program that
    is not BittyBuzz bytecode with its source (nothing to check the lines against)."""
    if not isinstance(program, BittyBuzzProgram):
        return None
    return set(SourceMap(program).code_lines)


class BreakpointBook:
    """The breakpoints of the edited file for one text revision, thread-safe. `on_change` is
    called (outside the lock) whenever the list the debugger should use changes."""

    def __init__(self, on_change: Callable[[list[LineBreakpoint]], None] | None = None) -> None:
        self._lock = threading.Lock()
        self._items: list[LineBreakpoint] = []
        self._revision = -1
        #: bumps on every change, so a page ignores a state older than its own last change
        self.generation = 0
        self._on_change = on_change
        self._programs: dict[int, set[int]] = {}  # revision -> its code lines (the last few)

    @property
    def items(self) -> list[LineBreakpoint]:
        with self._lock:
            return list(self._items)

    def set(self, revision: int, items: Iterable[LineBreakpoint]) -> list[LineBreakpoint]:
        """The page's breakpoints for text `revision` (kept: the ones on lines with code, when
        that revision's program is known); the list now in force."""
        with self._lock:
            if revision < self._revision:
                return list(self._items)  # an answer overtaken by a newer text's list
            lines = self._programs.get(revision)
            kept = sorted((b for b in items if lines is None or b.line in lines),
                          key=lambda b: b.line)
            changed = kept != self._items
            self._items, self._revision = kept, revision
            self.generation += 1
            result = list(kept)
        if changed and self._on_change is not None:
            self._on_change(result)
        return result

    def program_compiled(self, revision: int, program: Any) -> None:
        """A program compiled from text `revision`: the book's lines on no code go."""
        lines = code_lines(program)
        if lines is None:
            return
        with self._lock:
            self._programs = {r: v for r, v in self._programs.items() if r > revision - 4}
            self._programs[revision] = lines
            if revision != self._revision:
                return
            kept = [b for b in self._items if b.line in lines]
            changed = kept != self._items
            self._items = kept
            self.generation += changed
            result = list(kept)
        if changed and self._on_change is not None:
            self._on_change(result)

    def state(self) -> dict[str, Any]:
        """What the editor page polls: the list in force and the revision it belongs to."""
        with self._lock:
            return {"breakpoints": [b.as_json() for b in self._items],
                    "breakpoints_revision": self._revision,
                    "breakpoints_generation": self.generation}
