"""`SwarmDebugger`: breakpoints, source-level stepping, pause on error and reverse stepping
over a whole swarm (see the package's top comment for what a pause means to the swarm).

Design.

* **Fast path.** With no breakpoint, no stepping request and no robot stopped, `run` calls
  `Simulation.step()` as it is: the compiled swarm step, nothing added but a checkpoint every
  `CHECKPOINT_EVERY` steps and a look at the failures after each step.
* **Traced steps.** Otherwise the step runs on a worker thread with the engine's
  `turn_observer` set (robots take their turns one by one) and the robots that can stop put in
  the VM's reference mode with `VM.tracer` set: the tracer sees each robot's VM before each of
  its instructions. When a stop condition holds, the worker hands a `Stop` to the caller and
  waits; `run`/`step_*` resume it, a rewind abandons it (an exception that is not an
  `Exception`, so no firmware guard catches it). Only one thread runs at a time, so a traced
  step computes exactly what the fast one does (the reference mode leaves the same bytes:
  ARCHITECTURE.md "Two modes").
* **Source positions.** `SourceMap` maps pcs to statement lines. A robot is at a *line
  event* when its instruction starts a new line: its line or its frame (blockptr) changed,
  or it enters a function (a closure called again, e.g. by `foreach`); code of no line (a
  loop's jump back) is passed over, and a line event that only returns into the caller's
  unfinished line (after a call) is not a place to stop. Depth = the number of call frames (a host
  function such as `neighbors.foreach` has a frame of its own, so a closure it calls is one
  deeper than the line that called `foreach`).
* **Positions and reverse.** A point of the run is (control step, the robot's turn in it,
  the robot's `instructions_executed`): unique, and reached again by re-executing from the
  checkpoint at the start of that step (`checkpoints.py`) until the robot has executed that
  many instructions. Step back finds the wanted position by re-executing the step (or the
  steps before) and noting the robot's line events or the breakpoint hits, then restores and
  runs to it.
"""

from __future__ import annotations

import queue
import threading
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

import bbzide.debugger.checkpoints as checkpoints
from bbzide.debugger.source_map import SourceMap
from bbzide.debugger.values import (
    EvaluationError,
    Expression,
    decode,
    display,
    parse_expression,
    truth,
)
from bbzide.diagnostics import UserError
from bbzide.vm.inspector import globals_by_name, stack_frames, table_contents

#: A checkpoint at every this many control steps on the fast path: a Kilobot swarm's
#: checkpoint costs about five of its control steps of CPU (the pymunk space is copied), so
#: one every 100 steps keeps the fast path within a few percent
#: (benchmarks/debugger_bench.py prints it); a rewind re-executes at most 99 fast steps.
CHECKPOINT_EVERY = 100
#: A checkpoint at every this many control steps while steps are traced: a traced step costs
#: ten times a fast one, so a checkpoint every 10 adds a few percent to it, and a rewind
#: re-executes at most 9 traced steps (traced, so breakpoint hit counts stay exact).
TRACED_CHECKPOINT_EVERY = 10
#: Checkpoints kept however they fall (the recent ones); older ones are thinned to one every
#: CHECKPOINT_EVERY steps. 64 swarm states of 25 Kilobots are a few MB.
RECENT_CHECKPOINTS = 64
#: Control steps a stepping command runs at most before giving up (returns None): a robot
#: that never runs again (failed, asleep) must not hang the caller.
STEP_LIMIT = 1_000

REASONS = ("breakpoint", "step", "error", "pause")


class DebuggerError(UserError):
    """A breakpoint or a command the debugger cannot take (one line of text)."""


@dataclass(frozen=True)
class Breakpoint:
    """A source line of the program's main file (`path`: None or that file) where a robot
    stops: any robot (`robot` None) or the robot with that id; `condition`: a Buzz
    expression evaluated in the robot's context (its frame's locals, then its globals),
    stopping when true (a non-zero int); `hit_count`: stop from the Nth hit on (hits are
    counted over every robot the breakpoint applies to, condition true)."""

    line: int
    path: str | None = None
    robot: int | None = None
    condition: str | None = None
    hit_count: int | None = None


@dataclass(frozen=True)
class Frame:
    """One call frame, innermost first: the function (`step`, `lambda at line 11`, or the
    host function a closure was called from, e.g. `neighbors.foreach`), its current line and
    its locals as display text (`{name: text}`; a host function's frame has none)."""

    function: str
    line: int | None
    locals: dict[str, str] = field(default_factory=dict)
    host: bool = False


@dataclass(frozen=True)
class Stop:
    """Where the swarm stopped: robot id, control step, pc and source position of the
    robot's next instruction (for an error, the failing one), why (`REASONS`), its call
    frames, and for an error (or a condition that could not be evaluated) the text.
    `instructions` is the robot's instruction count there (its position within the run)."""

    robot: int
    step: int
    pc: int
    line: int | None
    column: int
    reason: str
    frames: tuple[Frame, ...]
    error: str | None = None
    breakpoint: Breakpoint | None = None
    instructions: int = 0

    @property
    def locals(self) -> dict[str, str]:
        """The innermost frame's locals."""
        return dict(self.frames[0].locals) if self.frames else {}


@dataclass(frozen=True)
class _Position:
    step: int
    turn: int          # the robot's turn within the step (index order, or phase order)
    instructions: int  # the robot's instructions_executed


@dataclass
class _Request:
    """What a traced run waits for. kind: "continue" (breakpoints, errors), "into", "over",
    "out", "instruction" (stepping `index`), "until" (`index` at `instructions`), "collect"
    (never stop; note robot `index`'s line events, or with index -2 the breakpoint stops,
    or with -3 nothing: hits are counted all the same), "pause"."""

    kind: str
    index: int = -1
    depth: int = 0
    instructions: int = -1
    stop_reason: str = "step"
    noted: list[tuple[_Position, Breakpoint | None]] = field(default_factory=list)
    #: "out" of a function the firmware called: (its entry pc, the control step)
    leaving: tuple[int, int] = (-1, -1)


class _Abandoned(BaseException):
    """Raised on the worker thread to drop a stopped control step (a rewind follows)."""


class _StepThread:
    """One control step on its own thread, so it can stop inside and go on later: a
    coroutine made of a thread and two queues (exactly one side runs at any time)."""

    _GO, _ABANDON = "go", "abandon"

    def __init__(self, run: Callable[[], Any]) -> None:
        self._to_step: queue.SimpleQueue[str] = queue.SimpleQueue()
        self._to_caller: queue.SimpleQueue[tuple[str, Any]] = queue.SimpleQueue()
        self._thread = threading.Thread(target=self._main, args=(run,), daemon=True,
                                        name="bbzide-debugger-step")
        self._thread.start()

    def _main(self, run: Callable[[], Any]) -> None:
        try:
            if self._to_step.get() == self._ABANDON:
                raise _Abandoned
            run()
        except _Abandoned:
            self._to_caller.put(("abandoned", None))
            return
        except BaseException as error:  # noqa: BLE001 - handed to the caller's thread
            self._to_caller.put(("raised", error))
            return
        self._to_caller.put(("finished", None))

    def go(self) -> tuple[str, Any]:
        """Let the step run until it stops (("stopped", Stop)) or ends (("finished", None))."""
        self._to_step.put(self._GO)
        outcome = self._to_caller.get()
        if outcome[0] == "raised":
            self._thread.join()
            raise outcome[1]
        if outcome[0] != "stopped":
            self._thread.join()
        return outcome

    def suspend(self, stop: Stop) -> None:
        """On the step's thread: hand `stop` to the caller and wait to go on."""
        self._to_caller.put(("stopped", stop))
        if self._to_step.get() == self._ABANDON:
            raise _Abandoned

    def abandon(self) -> None:
        self._to_step.put(self._ABANDON)
        self._to_caller.get()
        self._thread.join()


class SwarmDebugger:
    """Drives a `Simulation` (bbzide/worlds/engine.py) with breakpoints and stepping.

    Robots are named by robot id. Every command returns the `Stop` it ended at, or None
    when it ran its steps (or found nothing to go back to) without stopping; `paused_at` is
    the current stop."""

    def __init__(self, simulation: Any) -> None:
        self.simulation = simulation
        #: stop when a robot's VM enters an error (or a host function fails)
        self.pause_on_error = True
        self._breakpoints: tuple[Breakpoint, ...] = ()
        self._by_line: dict[int, list[Breakpoint]] = {}
        self._conditions: dict[str, Expression] = {}
        self._hits: dict[Breakpoint, int] = {}
        self._paused: Stop | None = None
        self._thread: _StepThread | None = None
        self._request = _Request("continue")
        self._maps: dict[int, SourceMap] = {}
        self._maps_by_content: dict[tuple[Any, ...], SourceMap] = {}
        self._programs: list[Any] = []
        self._applies_cache: dict[tuple[str | None, int], bool] = {}
        self._checkpoints: dict[int, tuple[checkpoints.Checkpoint, dict[Breakpoint, int]]] = {}
        #: per robot index: (pc, line, blockptr) of its previous traced instruction this turn
        self._last: list[tuple[int, int | None, int] | None] = [None] * simulation.count
        self._traced: dict[int, bool] = {}     # robot index -> its stress_gc before tracing
        self._pause_requested = threading.Event()
        self._checkpoint_now()

    # ---- breakpoints ----------------------------------------------------------------------
    @property
    def breakpoints(self) -> tuple[Breakpoint, ...]:
        return self._breakpoints

    @breakpoints.setter
    def breakpoints(self, breakpoints: Iterable[Breakpoint]) -> None:
        wanted = tuple(breakpoints)
        for breakpoint in wanted:
            self.check_breakpoint(breakpoint)
        self._breakpoints = wanted
        self._by_line = {}
        for breakpoint in wanted:
            self._by_line.setdefault(breakpoint.line, []).append(breakpoint)
        if self._thread is not None:
            self._trace_robots(self._robots_to_trace())

    def check_breakpoint(self, breakpoint: Breakpoint) -> None:
        """A `DebuggerError` (one line) when `breakpoint` cannot stop anything: a line
        outside the file or without code, a condition that does not parse, an unknown
        robot, a hit count below 1."""
        source_map = self._map_for(breakpoint)
        where = source_map.main_file or "the program"
        text = source_map.program.source_text
        lines = len(text.splitlines()) if text is not None else None
        if breakpoint.line < 1 or (lines is not None and breakpoint.line > lines):
            raise DebuggerError(f"{where}:{breakpoint.line}: no such line (the file has "
                                f"{lines} lines)")
        if breakpoint.line not in source_map.code_lines:
            after = source_map.nearest_code_line(breakpoint.line)
            hint = f" (the next line with code is {after})" if after is not None else ""
            raise DebuggerError(f"{where}:{breakpoint.line}: no code on this line{hint}")
        boot_only = source_map.boot_only(breakpoint.line)
        if boot_only:
            raise DebuggerError(f"{where}:{breakpoint.line}: this line runs only when the "
                                f"robots boot ({boot_only}), before the debugger runs them")
        if breakpoint.condition is not None:
            try:
                self._conditions[breakpoint.condition] = parse_expression(breakpoint.condition)
            except EvaluationError as error:
                raise DebuggerError(f"{where}:{breakpoint.line}: condition "
                                    f"{breakpoint.condition!r} does not compile: {error}"
                                    ) from None
        if breakpoint.robot is not None:
            try:
                self.simulation.state_of(breakpoint.robot)
            except KeyError:
                raise DebuggerError(f"breakpoint for robot {breakpoint.robot}: no such robot"
                                    ) from None
        if breakpoint.hit_count is not None and breakpoint.hit_count < 1:
            raise DebuggerError(f"hit count {breakpoint.hit_count}: must be at least 1")

    def _map_for(self, breakpoint: Breakpoint) -> SourceMap:
        """The program a breakpoint is in: its `path`'s (a program some robot runs), or
        the first programmed robot's."""
        if breakpoint.path is None:
            return self._main_map()
        files = []
        for state in self.simulation.robots:
            if state.program is None:
                continue
            source_map = self._map_of(state.program)
            if source_map.main_file is not None:
                if _same_file(breakpoint.path, source_map.main_file):
                    return source_map
                files.append(source_map.main_file)
        known = ", ".join(sorted(set(files))) or "none with a source file"
        raise DebuggerError(f"breakpoint in {breakpoint.path}: no robot runs that file "
                            f"(the swarm's programs: {known})")

    def _applies(self, breakpoint: Breakpoint, index: int) -> bool:
        """Whether `breakpoint` is in the program robot `index` runs."""
        key = (breakpoint.path, index)
        found = self._applies_cache.get(key)
        if found is None:
            program = self.simulation.robots[index].program
            found = self._applies_cache[key] = \
                self._map_for(breakpoint) is self._map_of(program)
        return found

    def hits(self, breakpoint: Breakpoint) -> int:
        """How many times `breakpoint` was hit so far (condition true)."""
        return self._hits.get(breakpoint, 0)

    # ---- where the swarm is -------------------------------------------------------------
    @property
    def paused_at(self) -> Stop | None:
        return self._paused

    def frames(self, robot: int) -> list[Frame]:
        """The robot's call frames now, innermost first ([] between its turns)."""
        return list(self._frames(self._index(robot)))

    def evaluate(self, robot: int, expression: str) -> Any:
        """A Buzz expression in the robot's context now (innermost frame's locals, then its
        globals): int, float, str, None (nil), a dict for a table. `DebuggerError` when it
        does not parse or cannot be evaluated."""
        try:
            parsed = self._conditions.get(expression) or parse_expression(expression)
            return parsed.evaluate(self._lookup(self._index(robot)))
        except EvaluationError as error:
            raise DebuggerError(f"{expression}: {error}") from None

    def display(self, value: Any) -> str:
        """A value as the debugger prints it (`evaluate`'s result, for instance)."""
        return display(value)

    def close(self) -> None:
        """Finish a stopped control step (nothing stops it any more) and leave the swarm
        to plain `Simulation.step` calls."""
        if self._thread is not None:
            self._request = _Request("collect", -3)
            self._resume()
        self._request = _Request("continue")

    def checkpoint(self) -> None:
        """Keep the swarm's state now (between two control steps) as a point to step back
        from: for a caller that runs plain `Simulation.step` calls itself and wants the past
        of a later pause (the same thinning as the debugger's own checkpoints)."""
        if self._thread is None:
            self._checkpoint_now()

    def request_pause(self) -> None:
        """From any thread: make a running `run` stop at the next instruction of any robot."""
        self._pause_requested.set()

    # ---- running --------------------------------------------------------------------------
    def run(self, max_steps: int) -> Stop | None:
        """Run until a stop (breakpoint, error, pause request) or `max_steps` control steps
        have ended (a stopped step counts when it ends)."""
        return self._go(_Request("continue"), max_steps)

    def step_over(self, robot: int, max_steps: int = STEP_LIMIT) -> Stop | None:
        """Run until the robot starts another line in its frame or a caller's (calls made
        by the line, host functions and the closures they call, run through)."""
        index = self._index(robot)
        depth = self._depth(index)
        return self._go(_Request("over" if depth else "into", index, depth), max_steps)

    def step_into(self, robot: int, max_steps: int = STEP_LIMIT) -> Stop | None:
        """Run until the robot starts another line anywhere: the first line of a function
        or closure the line calls (also through `neighbors.foreach`, `map`, a listener)."""
        index = self._index(robot)
        return self._go(_Request("into", index), max_steps)

    def step_out(self, robot: int, max_steps: int = STEP_LIMIT) -> Stop | None:
        """Run until the robot's current function has returned and its caller starts its
        next line; out of `step` or a listener, which the firmware calls: the first line of
        the next function it calls (the same listener's calls for the step's other messages
        run through, as `foreach`'s calls of a closure do)."""
        index = self._index(robot)
        depth = self._depth(index)
        state = self.simulation.robots[index]
        function = self._map_of(state.program).function_at(state.robot.vm.pc)
        leaving = (function.start if function else -1, self.simulation.step_count)
        return self._go(_Request("out" if depth else "into", index, depth, leaving=leaving),
                        max_steps)

    def step_instruction(self, robot: int, max_steps: int = STEP_LIMIT) -> Stop | None:
        """Run the robot's next VM instruction and stop before the one after."""
        index = self._index(robot)
        return self._go(_Request("instruction", index), max_steps)

    # ---- reverse --------------------------------------------------------------------------
    def step_back(self, robot: int, unit: str = "line") -> Stop | None:
        """Go back to the robot's previous line event (`unit="line"`), or to where its turn
        began one control step earlier (`unit="control_step"`), by re-executing from a
        checkpoint. None (nothing changed) when there is no such point."""
        if unit not in ("line", "control_step"):
            raise DebuggerError(f"step back by {unit!r}: choose 'line' or 'control_step'")
        index = self._index(robot)
        here = self._here()
        if unit == "line":
            target = self._search_back(here, lambda step: self._collect_lines(step, index),
                                       lambda found: found[-1] if found else None)
        else:
            first_step = here.step - 1
            target = self._search_back(
                _Position(first_step + 1, -1, 0),
                lambda step: self._collect_lines(step, index),
                lambda found: found[0] if found else None)
        if target is None:
            return None
        return self._run_to(target[0], index, "step")

    def run_back_to_previous_hit(self) -> Stop | None:
        """Go back to the last breakpoint stop before the current point (as `run` would
        have stopped there). None (nothing changed) when there is none."""
        if not self._breakpoints:
            return None
        here = self._here()
        target = self._search_back(here, self._collect_hits,
                                   lambda found: found[-1] if found else None)
        if target is None:
            return None
        position, breakpoint = target
        index = self._turn_order()[position.turn]
        return self._run_to(position, index, "breakpoint", breakpoint)

    # ---- the stepping machinery ---------------------------------------------------------
    def _go(self, request: _Request, max_steps: int) -> Stop | None:
        self._request = request
        ended = 0
        while ended < max_steps:
            if self._thread is not None:
                stop = self._resume()
            elif self._needs_tracing():
                stop = self._traced_step()
            else:
                stop = self._fast_step()
            if stop is not None:
                return stop
            ended += 1
        return None

    def _needs_tracing(self) -> bool:
        return bool(self._breakpoints) or self._request.kind != "continue" \
            or self._pause_requested.is_set()

    def _fast_step(self) -> Stop | None:
        sim = self.simulation
        step = sim.step_count
        sim.step()
        self._paused = None
        failed = [s for s in sim.robots if s.failure is not None and s.failure_step == step]
        if failed and self.pause_on_error:
            # stop where it happened: the same step again, robot by robot
            self._rewind_to_step(step)
            stop = self._traced_step()
            if stop is not None:
                return stop
        if sim.step_count % CHECKPOINT_EVERY == 0:
            self._checkpoint_now()
        return None

    def _traced_step(self) -> Stop | None:
        sim = self.simulation
        if sim.step_count % TRACED_CHECKPOINT_EVERY == 0:
            self._checkpoint_now()
        self._last = [None] * sim.count
        self._failed_before = [s.failure is not None or
                               (s.robot is not None and s.robot.failure is not None)
                               for s in sim.robots]
        sim.turn_observer = self._after_turn
        self._trace_robots(self._robots_to_trace())
        self._thread = _StepThread(sim.step)
        return self._outcome(self._thread.go())

    def _resume(self) -> Stop | None:
        assert self._thread is not None
        self._paused = None
        self._trace_robots(self._robots_to_trace())
        return self._outcome(self._thread.go())

    def _outcome(self, outcome: tuple[str, Any]) -> Stop | None:
        kind, stop = outcome
        if kind == "stopped":
            self._paused = stop
            return stop  # type: ignore[no-any-return]
        self._end_traced_step()
        return None

    def _end_traced_step(self) -> None:
        self._thread = None
        self._paused = None
        self.simulation.turn_observer = None
        for index, stress in self._traced.items():
            robot = self.simulation.robots[index].robot
            robot.vm.tracer = None
            robot.vm.stress_gc = stress
        self._traced = {}

    def _abandon(self) -> None:
        """Drop a stopped control step (the caller restores a checkpoint next)."""
        if self._thread is not None:
            self._thread.abandon()
            self._end_traced_step()

    def _robots_to_trace(self) -> list[int]:
        sim = self.simulation
        if any(b.robot is None for b in self._breakpoints) or self._request.kind == "pause" \
                or self._pause_requested.is_set():
            return list(range(sim.count))
        wanted = {sim.state_of(b.robot).index for b in self._breakpoints
                  if b.robot is not None}
        if self._request.index >= 0:
            wanted.add(self._request.index)
        return sorted(wanted)

    def _trace_robots(self, indexes: Sequence[int]) -> None:
        """Tracers on these robots (added only: a robot traced in this step stays so)."""
        robots = self.simulation.robots
        for index in indexes:
            robot = robots[index].robot
            if index in self._traced or robot is None or not hasattr(robot, "vm"):
                continue
            self._traced[index] = robot.vm.stress_gc
            robot.vm.stress_gc = True
            robot.vm.tracer = self._tracer(index)

    def _tracer(self, index: int) -> Callable[[Any], None]:
        state = self.simulation.robots[index]
        line_of = self._map_of(state.program).line_of
        starts = frozenset(self._map_of(state.program).entry_pcs)
        last = self._last

        def trace(vm: Any) -> None:
            pc = vm.pc
            line = line_of.get(pc)
            bp = vm.blockptr
            previous = last[index]
            request = self._request
            if line is None or (previous is not None and line == previous[1]
                                and bp == previous[2] and pc not in starts):
                if line is not None:
                    last[index] = (pc, line, bp)
                if request.index == index and request.kind in ("instruction", "until"):
                    self._check(index, vm, pc, line, False, False)
                return
            last[index] = (pc, line, bp)
            entering = pc in starts
            returned = previous is not None and bp < previous[2] and not entering
            self._check(index, vm, pc, line, True, returned, entering)

        return trace

    def _check(self, index: int, vm: Any, pc: int, line: int | None, event: bool,
               returned: bool, entering: bool = False) -> None:
        """A traced robot about to run `pc` (`entering`: a function's first instruction):
        does anything stop here? (worker thread)"""
        request = self._request
        kind = request.kind
        starts_line = event and not returned and line is not None
        hit = self._hit(index, vm, line) if starts_line and line is not None else None
        if kind == "until":
            if index == request.index and vm.instructions_executed == request.instructions:
                self._suspend(index, vm, request.stop_reason,
                              request.noted[0][1] if request.noted else None)
            return
        if kind == "collect":
            if request.index == -2 and hit is not None:
                request.noted.append((self._position(index, vm), hit))
            elif index == request.index and starts_line:
                request.noted.append((self._position(index, vm), None))
            return
        if hit is not None:
            self._suspend(index, vm, "breakpoint", hit)
            return
        if kind == "instruction" and index == request.index:
            self._suspend(index, vm, "step")
            return
        if not starts_line:
            return
        if self._pause_requested.is_set() or kind == "pause":
            self._pause_requested.clear()
            self._request = _Request("continue")
            self._suspend(index, vm, "pause")
            return
        if index != request.index:
            return
        if kind == "into" or (kind == "over" and self._depth(index) <= request.depth):
            self._suspend(index, vm, "step")
        elif kind == "out":
            depth = self._depth(index)
            # out of a function the robot's firmware called (`step`, a listener: depth 1),
            # whose caller has no line: the next function the firmware calls is its next
            # line, but for more calls of the same one in this step (a listener's other
            # messages: like `foreach`'s calls of its closure, they are run through)
            if depth < request.depth or (request.depth == 1 and entering and depth == 1
                                         and (pc, self.simulation.step_count)
                                         != request.leaving):
                self._suspend(index, vm, "step")

    def _hit(self, index: int, vm: Any, line: int) -> Breakpoint | None:
        """Count the breakpoints of `line` that apply; the first that stops, if any."""
        candidates = self._by_line.get(line)
        if not candidates:
            return None
        robot_id = self.simulation.robots[index].robot_id
        stopping = None
        for breakpoint in candidates:
            if breakpoint.robot is not None and breakpoint.robot != robot_id:
                continue
            if not self._applies(breakpoint, index):
                continue
            if breakpoint.condition is not None:
                try:
                    value = self._conditions[breakpoint.condition].evaluate(
                        self._lookup(index))
                except EvaluationError:
                    value = 1  # stop and let the user see why (Stop.error)
                if not truth(value):
                    continue
            count = self._hits[breakpoint] = self._hits.get(breakpoint, 0) + 1
            if stopping is None and (breakpoint.hit_count is None
                                     or count >= breakpoint.hit_count):
                stopping = breakpoint
        return stopping

    def _after_turn(self, index: int) -> None:
        """The engine's turn observer: the robot's turn is over (worker thread)."""
        self._last[index] = None
        state = self.simulation.robots[index]
        robot = state.robot
        if robot is None or robot.failure is None or self._failed_before[index]:
            return
        self._failed_before[index] = True
        if not self.pause_on_error or self._request.kind in ("collect", "until"):
            return
        failure = robot.failure
        source_map = self._map_of(state.program)
        stop = Stop(state.robot_id, self.simulation.step_count, failure.pc,
                    source_map.line(failure.pc), source_map.column(failure.pc), "error",
                    self._frames(index), str(failure), None,
                    int(getattr(robot.vm, "instructions_executed", 0)))
        assert self._thread is not None
        self._thread.suspend(stop)

    def _suspend(self, index: int, vm: Any, reason: str,
                 breakpoint: Breakpoint | None = None) -> None:
        state = self.simulation.robots[index]
        source_map = self._map_of(state.program)
        error = None
        if breakpoint is not None and breakpoint.condition is not None:
            try:
                self._conditions[breakpoint.condition].evaluate(self._lookup(index))
            except EvaluationError as failed:
                error = f"condition {breakpoint.condition!r}: {failed}"
        stop = Stop(state.robot_id, self.simulation.step_count, vm.pc,
                    source_map.line(vm.pc), source_map.column(vm.pc), reason,
                    self._frames(index), error, breakpoint, vm.instructions_executed)
        assert self._thread is not None
        self._thread.suspend(stop)

    # ---- reverse machinery ----------------------------------------------------------------
    def _here(self) -> _Position:
        """The current point: the stop, or the start of the next control step."""
        stop = self._paused
        if stop is None:
            return _Position(self.simulation.step_count, -1, 0)
        index = self._index(stop.robot)
        return _Position(stop.step, self._turn_order().index(index), stop.instructions)

    def _search_back(self, here: _Position,
                     collect: Callable[[int], list[tuple[_Position, Any]]],
                     choose: Callable[[list[tuple[_Position, Any]]], Any]) -> Any:
        """The chosen noted point before `here`, searching its step, then the ones before
        (each re-executed from its start); None (and the swarm where it was) if none."""
        earliest = min(self._checkpoints)
        step = here.step
        came_from = self._paused
        while step >= earliest:
            found = [item for item in collect(step)
                     if _order(item[0]) < _order(here)]
            chosen = choose(found)
            if chosen is not None:
                return chosen
            step -= 1
        if came_from is not None:   # nothing earlier: back to where we were
            self._return_to(came_from)
        else:
            self._rewind_to_step(here.step)
        return None

    def _return_to(self, stop: Stop) -> None:
        """Re-execute up to `stop` again (an error stop: its step, which stops there)."""
        if stop.reason == "error":
            self._rewind_to_step(stop.step)
            self._request = _Request("continue")
            self._traced_step()
            return
        self._run_to(self._here_of(stop), self._index(stop.robot), stop.reason,
                     stop.breakpoint)

    def _here_of(self, stop: Stop) -> _Position:
        index = self._index(stop.robot)
        return _Position(stop.step, self._turn_order().index(index), stop.instructions)

    def _collect_lines(self, step: int, index: int) -> list[tuple[_Position, Any]]:
        return self._collect(step, _Request("collect", index))

    def _collect_hits(self, step: int) -> list[tuple[_Position, Any]]:
        return self._collect(step, _Request("collect", -2))

    def _collect(self, step: int, request: _Request) -> list[tuple[_Position, Any]]:
        """Re-execute control step `step` noting what `request` asks for."""
        if step >= self.simulation.step_count and self._paused is None:
            return []
        self._rewind_to_step(step)
        self._request = request
        self._traced_step()
        return request.noted

    def _run_to(self, position: _Position, index: int, reason: str,
                breakpoint: Breakpoint | None = None) -> Stop | None:
        self._rewind_to_step(position.step)
        request = _Request("until", index, instructions=position.instructions,
                           stop_reason=reason)
        if breakpoint is not None:
            request.noted.append((position, breakpoint))
        self._request = request
        return self._traced_step()

    def _rewind_to_step(self, step: int) -> None:
        """The swarm as it was at the start of control step `step` (a checkpoint restored,
        then fast steps up to `step`)."""
        self._abandon()
        self._paused = None
        usable = [s for s in self._checkpoints if s <= step]
        if not usable:
            raise DebuggerError(f"no checkpoint at or before control step {step}")
        start = max(usable)
        checkpoint, hits = self._checkpoints[start]
        checkpoints.restore(self.simulation, checkpoint)
        self._hits = dict(hits)
        self._last = [None] * self.simulation.count
        wanted = self._request
        while self.simulation.step_count < step:
            if self._breakpoints:        # traced, so that the hit counts are the run's
                self._request = _Request("collect", -3)
                self._traced_step()
            else:
                self.simulation.step()
        self._request = wanted

    def _checkpoint_now(self) -> None:
        sim = self.simulation
        step = sim.step_count
        if step not in self._checkpoints:
            self._checkpoints[step] = (checkpoints.capture(sim), dict(self._hits))
            recent = sorted(self._checkpoints)[:-RECENT_CHECKPOINTS]
            for old in recent:
                if old % CHECKPOINT_EVERY != 0 and old != min(self._checkpoints):
                    del self._checkpoints[old]

    def _turn_order(self) -> list[int]:
        sim = self.simulation
        if getattr(sim, "asynchronous", False):
            return np.argsort(sim.phases, kind="stable").tolist()
        return list(range(sim.count))

    def _position(self, index: int, vm: Any) -> _Position:
        return _Position(self.simulation.step_count, self._turn_order().index(index),
                         vm.instructions_executed)

    # ---- reading a robot ----------------------------------------------------------------
    def _index(self, robot: int) -> int:
        try:
            state = self.simulation.state_of(robot)
        except KeyError:
            raise DebuggerError(f"no robot {robot} in this swarm") from None
        if state.robot is None:
            raise DebuggerError(f"robot {robot} has no program (a passive body)")
        return int(state.index)

    def _main_map(self) -> SourceMap:
        for state in self.simulation.robots:
            if state.program is not None:
                return self._map_of(state.program)
        raise DebuggerError("no robot of this swarm runs a program")

    def _map_of(self, program: Any) -> SourceMap:
        """The program's source map, one per distinct code (robots built from one compiled
        program may each hold a converted copy of it)."""
        found = self._maps.get(id(program))
        if found is None:
            content = (program.source_file, program.source_text, bytes(program.bbo))
            found = self._maps_by_content.get(content)
            if found is None:
                found = self._maps_by_content[content] = SourceMap(program)
            self._maps[id(program)] = found
            self._programs.append(program)  # keeps the id() keys valid
        return found

    def _depth(self, index: int) -> int:
        robot = self.simulation.robots[index].robot
        return len(stack_frames(robot.vm)) if robot is not None else 0

    def _frames(self, index: int) -> tuple[Frame, ...]:
        state = self.simulation.robots[index]
        vm = state.robot.vm
        source_map = self._map_of(state.program)
        program = source_map.program
        records = stack_frames(vm)
        frames: list[Frame] = []
        pc, lsyms = vm.pc, vm.lsyms
        for position, record in enumerate(records):
            if position > 0 and records[position - 1].return_pc == record.return_pc:
                site = program.call_sites.get(record.return_pc - 1)
                frames.append(Frame(site.callee if site else "host function",
                                    source_map.line(record.return_pc - 1), {}, True))
            else:
                function = source_map.function_at(pc)
                frames.append(Frame(function.name if function else "?", source_map.line(pc),
                                    self._locals(vm, lsyms, function, program.strings)))
            pc, lsyms = record.return_pc - 1, record.saved_lsyms
        return tuple(frames)

    def _locals(self, vm: Any, lsyms: int, function: Any, strings: list[str]
                ) -> dict[str, str]:
        return {name: display(value)
                for name, value in self._local_values(vm, lsyms, function, strings).items()}

    @staticmethod
    def _local_values(vm: Any, lsyms: int, function: Any, strings: list[str]
                      ) -> dict[str, Any]:
        if not lsyms or function is None:
            return {}
        names = function.local_names
        values: dict[str, Any] = {}
        for slot, value in table_contents(vm, lsyms):
            name = names.get(slot)
            if name is None:
                continue
            if name == "self":  # the closure's table or nil: not a variable of the script
                continue
            values[name] = decode(vm, value, strings)
        return values

    def _lookup(self, index: int) -> Callable[[str], Any]:
        """name -> value in the robot's context now (innermost frame's locals, globals)."""
        state = self.simulation.robots[index]
        vm = state.robot.vm
        source_map = self._map_of(state.program)
        strings = source_map.program.strings
        local_values: dict[str, Any] = {}
        if stack_frames(vm):
            local_values = self._local_values(vm, vm.lsyms, source_map.function_at(vm.pc),
                                              strings)

        def lookup(name: str) -> Any:
            if name in local_values:
                return local_values[name]
            where = globals_by_name(vm, strings).get(name)
            if where is None:
                raise KeyError(name)
            return decode(vm, where, strings)

        return lookup


def _order(position: _Position) -> tuple[int, int, int]:
    return (position.step, position.turn, position.instructions)


def _same_file(given: str, main: str) -> bool:
    import os

    return os.path.realpath(given) == os.path.realpath(main) or \
        os.path.basename(given) == os.path.basename(main) and not os.path.dirname(given)
