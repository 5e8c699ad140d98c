"""Runs the simulation on its own thread, so the browser controls never wait for a robot.

The controller owns the `SimulationHandle`. Everything the UI asks for (play, pause, one step,
reset, new settings, a freshly compiled program) becomes a command in a queue that the
simulation thread applies *between* steps; the UI thread never steps the world itself. A slow or
looping Buzz script therefore slows only this thread: viser's callbacks keep answering, and the
status line shows how long the current step has been running.

Readers that need a consistent view (the inspector) take `locked()`, which waits for the end of
the current step; while the swarm runs that gives a live view, while paused an exact one.
Frames go to `on_frame` at most `MAX_FRAME_HZ` times a second (and after every single step and
on pause, so a paused scene always shows the current step).
A new world drops the program: bytecode names host functions by the old world's string ids, so
the new world is built only when the program compiled for it arrives.

The debugger (the debugger room's `SwarmDebugger`, reached through the simulation handle's
`debug`) runs the steps only while it is needed: while breakpoints are set, or while it has
the swarm paused inside a control step. Otherwise a step is the plain `step()`, which keeps
a checkpoint of the swarm once every `world_adapter.PAST_EVERY` steps (so Back works from any
pause) and costs nothing else. Stepping commands (`debug`) apply on this thread like every
other command; a stop pauses the run and lands in `status.paused_at`. With `pause_on_error`,
a robot whose VM fails pauses the run too: inside the step at the failing instruction when
the debugger drives the step, at the end of that step otherwise (the failed robot's state is
the same: it runs no further).
"""

from __future__ import annotations

import contextlib
import queue
import threading
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

from bbzide.diagnostics import UserError
from bbzide.ui.inspection import PausedAt
from bbzide.ui.world_backend import SimulationHandle, SwarmFrame, WorldBackend

#: The scene needs no more than a screen's worth of updates; 30 Hz is smooth and cheap (~1 ms).
MAX_FRAME_HZ = 30.0
#: Steps/s is averaged over this window so the figure is readable, not jittery.
RATE_WINDOW_SECONDS = 1.0
#: How long `stop` waits by default for the simulation thread's current step: a step of a
#: Buzz loop without an instruction budget may never end, and a test or a rebuild must not
#: hang on it; ten seconds covers any ordinary step on a loaded machine.
STOP_WAIT_S = 10.0


class StepInProgress(Exception):
    """The simulation is inside a step that did not end within the caller's patience."""


@dataclass(frozen=True)
class RunSettings:
    world: str
    robots: int
    seed: int
    steps_per_second: float = 0.0  # 0 = as fast as the machine goes
    keep_state_on_reload: bool = True  # a new program keeps poses (True) or resets the world
    #: A scenario (bbzide.worlds.scenario.Scenario) pinning the world's options and the robots;
    #: dropped when the world or the robot count changes (the seed is taken from `seed`).
    scenario: Any = None
    #: The world's options (`bbzide run --set KEY=VALUE`: layout, light, width, …) when no
    #: scenario pins them; a change rebuilds the world.
    world_options: dict[str, Any] = field(default_factory=dict)
    #: The firmware loop (`bbzide run --loop`): "pop" drops each step's return value, "robot"
    #: keeps it on the stack as the Kilobot firmware does; a change rebuilds the world.
    loop: str = "pop"


@dataclass
class RunStatus:
    """What the status line shows; written by the simulation thread, read by anyone."""

    step: int = 0
    running: bool = False
    steps_per_second: float = 0.0
    robots: int = 0
    robots_in_error: int = 0
    step_started_at: float | None = None  # monotonic time the current step began (None = idle)
    error: str | None = None  # a world/engine failure (not a robot's VM error)
    program_generation: int = 0  # bumps when a new program is loaded
    recording: str | None = None  # the .rrd being written (None = not recording)
    #: A one-line note for the status line until the next Play or Reset: why the run paused by
    #: itself (the scenario's steps reached), or why a link opened nothing.
    notice: str | None = None
    last_recording: str | None = None  # the last .rrd written to its end (shown after a stop)
    paused_at: PausedAt | None = None  # where the debugger stopped the swarm (None = it did not)
    breakpoint_errors: tuple[str, ...] = ()  # breakpoints the debugger refused, and why
    debug_note: str | None = None  # what the last debugger command could not do
    stops: int = 0  # bumps at every debugger stop, so a listener sees a new one


#: What the Debug folder says when a command ended without a stop.
NOTHING_THERE = {
    "step_back_line": "nothing to step back to: the swarm's past starts at the run's start "
                      "or the last program load",
    "step_back_control_step": "nothing to step back to: the swarm's past starts at the run's "
                              "start or the last program load",
    "run_back_to_previous_hit": "no earlier breakpoint hit",
}

#: The debugger commands `RunController.debug` takes, each the debugger room's method of that
#: name but the two back-steps, which are `step_back(robot, unit)`.
STEP_COMMANDS = ("step_over", "step_into", "step_out", "step_instruction", "step_back_line",
                 "step_back_control_step", "run_back_to_previous_hit")


class RunController:
    def __init__(
        self,
        backend: WorldBackend,
        settings: RunSettings,
        on_frame: Callable[[SwarmFrame], None] | None = None,
    ) -> None:
        self.backend = backend
        self.settings = settings
        self.status = RunStatus(robots=settings.robots)
        self._on_frame: list[Callable[[SwarmFrame], None]] = [on_frame] if on_frame else []
        self._on_step: list[Callable[[SimulationHandle], None]] = []
        self._commands: queue.Queue[tuple[str, Any]] = queue.Queue()
        self._wake = threading.Event()
        self._stop = threading.Event()
        self._sim_lock = threading.RLock()
        self._sim: SimulationHandle | None = None
        self._program: Any = None
        self._running = False
        self._pending_steps = 0
        self._rate_marks: list[tuple[float, int]] = []
        self._last_frame_time = 0.0
        self.last_frame: SwarmFrame | None = None
        self._breakpoints: list[Any] = []
        self._pause_on_error = True
        self._failed_before = 0  # failed robots after the last step (pause on a new one)
        self._thread = threading.Thread(target=self._loop, name="bbzide-simulation", daemon=True)

    # ---- UI side: every call only queues a command --------------------------------------------
    def start(self) -> RunController:
        self._thread.start()
        return self

    def stop(self, wait_s: float | None = STOP_WAIT_S) -> None:
        """End the simulation thread after its current work, waiting at most `wait_s`
        seconds for it (None: as long as it takes), then end the recording."""
        self._stop.set()
        self._wake.set()
        self._thread.join(timeout=wait_s)
        self._stop_recording()

    def add_frame_listener(self, listener: Callable[[SwarmFrame], None]) -> None:
        self._on_frame.append(listener)

    def add_step_listener(self, listener: Callable[[SimulationHandle], None]) -> None:
        """Call `listener(sim)` after every step (on the simulation thread, under the run
        lock) until `remove_step_listener`: for watches, which read every step."""
        self._on_step = [*self._on_step, listener]

    def remove_step_listener(self, listener: Callable[[SimulationHandle], None]) -> None:
        # `!=`, not `is not`: each read of a bound method makes a new, equal object
        self._on_step = [known for known in self._on_step if known != listener]

    def play(self) -> None:
        self._send("play")

    def pause(self) -> None:
        """Stop starting steps at once (a long step or program load in progress finishes)."""
        self._running = False
        self.status.running = False
        self._send("pause")

    def single_step(self) -> None:
        self._send("step")

    def set_breakpoints(self, breakpoints: list[Any]) -> None:
        """The editor's breakpoints (`bbzide.ui.breakpoints.LineBreakpoint`), for every robot."""
        self._send("breakpoints", list(breakpoints))

    @property
    def pause_on_error(self) -> bool:
        return self._pause_on_error

    @pause_on_error.setter
    def pause_on_error(self, on: bool) -> None:
        """A robot entering an error pauses the run (on by default)."""
        self._pause_on_error = on
        self._send("pause_on_error", on)

    def debug(self, command: str, robot: int | None = None) -> None:
        """Pause and apply a debugger command (`STEP_COMMANDS`) to robot index `robot` (None:
        the robot the debugger stopped, else robot 0). "Continue" is `play`."""
        if command not in STEP_COMMANDS:
            raise ValueError(f"unknown debugger command {command!r}")
        self._running = False
        self.status.running = False
        self._send("debug", (command, robot))

    def reset(self) -> None:
        self._send("reset")

    def load_program(self, program: Any) -> None:
        """A new compiled program for every robot (world kept or reset per the settings)."""
        self._send("program", program)

    def set_recording(self, path: Any, source: str | None = None) -> None:
        """Start recording the swarm into `path` (a new .rrd), or stop when `path` is None."""
        self._send("record", (path, source))

    def update_settings(self, **changes: Any) -> None:
        """Change world/robots/seed (rebuilds the world) or speed/keep_state (takes effect now)."""
        self._send("settings", changes)

    def save_setup(self, path: Path, script: Path, pin_positions: bool = False) -> Path:
        """Save the running set-up (world, options, robots, seed, `script`) as a scenario file
        at `path`; with `pin_positions`, where the robots stand now too. Needs a backend with
        scenarios (`WorldsBackend`); a bad path is a `UserError`."""
        settings = self.settings
        with self._sim_lock:
            scenario = self.backend.setup_scenario(  # type: ignore[attr-defined]
                settings.world, settings.robots, settings.seed, script, settings.scenario,
                self._sim if pin_positions else None)
        return self.backend.save_scenario(scenario, path)  # type: ignore[attr-defined]

    def flush(self, timeout: float | None = None) -> bool:
        """Wait until the simulation thread has applied every command sent before this call
        (False if `timeout` passed first): then the status shows what those commands did, and
        after a pause or a single step no further step can start until the next command."""
        applied = threading.Event()
        self._send("flush", applied)
        return applied.wait(timeout)

    @contextlib.contextmanager
    def locked(self, timeout: float | None = None) -> Iterator[SimulationHandle | None]:
        """The simulation between two steps (None before the first program arrives).

        With `timeout`, raise `StepInProgress` instead of waiting longer for a step to end.
        """
        if not self._sim_lock.acquire(timeout=-1 if timeout is None else timeout):
            raise StepInProgress
        try:
            yield self._sim
        finally:
            self._sim_lock.release()

    @property
    def scenario_steps(self) -> int | None:
        """Where a run pauses by itself: the scenario's `steps` (None: no scenario, or 0)."""
        steps = getattr(self.settings.scenario, "steps", None)
        return steps or None

    @property
    def watches(self) -> tuple[str, ...]:
        """The script globals the scenario watches (its `watch` list; empty without one)."""
        return tuple(getattr(self.settings.scenario, "watch", ()) or ())

    @property
    def has_program(self) -> bool:
        return self._program is not None

    def _send(self, command: str, argument: Any = None) -> None:
        self._commands.put((command, argument))
        self._wake.set()

    # ---- simulation thread --------------------------------------------------------------------
    def _loop(self) -> None:
        while not self._stop.is_set():
            self._apply_commands()
            if self._sim is not None and (self._running or self._pending_steps > 0):
                self._step_once()
                self._pace()
            else:
                self._wake.wait(0.1)
                self._wake.clear()

    def _apply_commands(self) -> None:
        while True:
            try:
                command, argument = self._commands.get_nowait()
            except queue.Empty:
                return
            try:
                self._apply(command, argument)
            except UserError as error:  # bad settings (a swarm that does not fit): as written
                self.status.error = error.message
                self._running = False
                self.status.running = False
            except Exception as error:  # noqa: BLE001 - a world failure is shown, not fatal
                self.status.error = f"{type(error).__name__}: {error}"
                self._running = False
                self.status.running = False

    def _apply(self, command: str, argument: Any) -> None:
        if command == "play":
            self._running = True
            self.status.notice = None
            self.status.paused_at = None
            self.status.debug_note = None
        elif command == "pause":
            self._running = False
            self._pending_steps = 0
            if hasattr(self._sim, "debugger"):  # its past starts here: step back reaches it
                with self._sim_lock:
                    self._sim.debugger()
            # The last step's frame may have been skipped by the frame-rate limit; a paused view
            # must show the state the inspector reads, not the one a step before.
            self._publish(force=True)
        elif command == "step":
            self._running = False
            self._pending_steps += 1
        elif command == "pause_on_error":
            if hasattr(self._sim, "set_pause_on_error"):
                with self._sim_lock:
                    self._sim.set_pause_on_error(argument)
        elif command == "reset":
            self.status.notice = None
            self._rebuild()
        elif command == "flush":
            argument.set()
        elif command == "breakpoints":
            self._breakpoints = argument
            self._give_breakpoints()
        elif command == "debug":
            self._debug_command(*argument)
        elif command == "program":
            self._program = argument
            self.status.program_generation += 1
            self.status.step_started_at = time.monotonic()  # booting runs Buzz code too
            try:
                if self._sim is None or not self.settings.keep_state_on_reload:
                    self._rebuild()
                else:
                    with self._sim_lock:
                        self._sim.load_program(argument, keep_state=True)
                    self._give_breakpoints()
                    self.status.paused_at = None
                    self._publish(force=True)
            finally:
                self.status.step_started_at = None
        elif command == "record":
            path, source = argument
            if path is None:
                self._stop_recording()
            elif self._sim is not None:
                start = getattr(self._sim, "start_recording", None)
                if start is None:
                    raise RuntimeError("this world cannot be recorded")
                with self._sim_lock:
                    self._sim.source_text = source  # type: ignore[attr-defined]
                    start(path)
                self.status.recording = str(path)
        elif command == "settings":
            old = self.settings
            self.settings = replace(old, **argument)
            changed_swarm = (old.world, old.robots, old.world_options) != (
                self.settings.world, self.settings.robots, self.settings.world_options)
            if changed_swarm and "scenario" not in argument:
                self.settings = replace(self.settings, scenario=None)
            if old.world != self.settings.world:
                # The program was compiled for the old world's host-function ids: the new world
                # waits for the one compiled for it (`load_program`); none runs meanwhile.
                self._stop_recording()
                self._program = None
                with self._sim_lock:
                    self._sim = None
            elif ((old.robots, old.seed, old.world_options, old.loop)
                  != (self.settings.robots, self.settings.seed, self.settings.world_options,
                      self.settings.loop)
                  or old.scenario is not self.settings.scenario):
                self._rebuild()
        self.status.running = self._running

    def _rebuild(self) -> None:
        """A fresh world from the settings and the current program (step 0)."""
        if self._program is None:
            return
        settings = self.settings
        self._stop_recording()  # a rebuilt world starts a new timeline at step 0
        pinned: dict[str, Any] = {} if settings.scenario is None else {
            "scenario": settings.scenario}
        if settings.world_options:
            pinned["world_options"] = settings.world_options
        if settings.loop != "pop":
            pinned["loop"] = settings.loop
        sim = self.backend.create(settings.world, self._program, settings.robots, settings.seed,
                                  **pinned)
        with self._sim_lock:
            close = getattr(self._sim, "close_debugger", None)
            if close is not None:
                close()  # the old swarm's held step (a thread of its own) ends
            self._sim = sim
            if hasattr(sim, "set_pause_on_error"):
                sim.set_pause_on_error(self._pause_on_error)
        self._give_breakpoints()
        self.status.paused_at = None
        self._failed_before = 0
        self.status.error = None
        self.status.robots = settings.robots
        self._rate_marks.clear()
        self._publish(force=True)

    def _stop_recording(self) -> None:
        stop = getattr(self._sim, "stop_recording", None)
        if stop is not None:
            with self._sim_lock:
                stop()
        if self.status.recording is not None:
            self.status.last_recording = self.status.recording
        self.status.recording = None

    def _step_once(self) -> None:
        assert self._sim is not None
        self.status.step_started_at = time.monotonic()
        try:
            with self._sim_lock:
                if self._debugging():
                    stop = self._sim.debug("run", 1)  # type: ignore[attr-defined]
                    if stop is not None:
                        self._stopped(self._sim.paused_view(stop))  # type: ignore[attr-defined]
                else:
                    self._sim.step()
                    if self._pause_on_error:
                        self._pause_on_new_failure()
        except Exception as error:  # noqa: BLE001 - shown in the status line; the UI lives on
            self.status.error = f"{type(error).__name__}: {error}"
            self._running = False
            self.status.running = False
        finally:
            self.status.step_started_at = None
        self._after_step()
        forced = self._pending_steps > 0
        self._pending_steps = max(0, self._pending_steps - 1)
        stop_at = self.scenario_steps
        if self._running and stop_at is not None and self._sim.step_count == stop_at:
            self._running = False  # the scenario's run ends here; Play runs on past it
            self.status.running = False
            self.status.notice = (f"⏸ paused at step {stop_at}: the scenario's `steps` "
                                  "(Play runs on)")
            forced = True
        self._publish(force=forced or not self._running)

    # ---- debugger (simulation thread, under the run lock where the swarm is touched) ---------
    def _give_breakpoints(self) -> None:
        """The breakpoints to the swarm's debugger (made only once there are some)."""
        sim = self._sim
        if sim is None or not hasattr(sim, "set_breakpoints"):
            return
        if not self._breakpoints and not getattr(sim, "has_debugger", False):
            self.status.breakpoint_errors = ()
            return
        with self._sim_lock:
            self.status.breakpoint_errors = tuple(sim.set_breakpoints(self._breakpoints))

    def _debugging(self) -> bool:
        """The debugger must drive this step: breakpoints are set, or it paused mid-step."""
        sim = self._sim
        if not hasattr(sim, "debug"):
            return False
        return bool(self._breakpoints) or bool(getattr(sim, "mid_step", False))

    def _pause_on_new_failure(self) -> None:
        """After a plain step: a robot that failed in it pauses the run (the first such)."""
        states = _robot_states(self._sim)
        failed = [state for state in states if state.failure is not None]
        if len(failed) > self._failed_before and hasattr(self._sim, "error_view"):
            latest = max(failed, key=lambda state: state.failure_step or 0)
            self._stopped(self._sim.error_view(int(latest.index)))  # type: ignore[attr-defined]
        self._failed_before = len(failed)

    def _stopped(self, paused: PausedAt) -> None:
        self._running = False
        self._pending_steps = 0
        self.status.running = False
        self.status.paused_at = paused
        self.status.stops += 1

    def _debug_command(self, command: str, robot: int | None) -> None:
        sim = self._sim
        if sim is None or not hasattr(sim, "debug"):
            return
        self._running = False
        self._pending_steps = 0
        paused = self.status.paused_at
        index = robot if robot is not None else paused.robot_index if paused else 0
        self.status.step_started_at = time.monotonic()
        try:
            with self._sim_lock:
                key = sim.robot_key(index)  # type: ignore[attr-defined]
                if command == "step_back_line":
                    stop = sim.debug("step_back", key, "line")  # type: ignore[attr-defined]
                elif command == "step_back_control_step":
                    stop = sim.debug("step_back", key, "control_step")  # type: ignore
                elif command == "run_back_to_previous_hit":
                    stop = sim.debug(command)  # type: ignore[attr-defined]
                else:
                    stop = sim.debug(command, key)  # type: ignore[attr-defined]
                still = stop is None and sim.debugger().paused_at  # type: ignore[attr-defined]
                self._failed_before = sum(s.failure is not None for s in _robot_states(sim))
        finally:
            self.status.step_started_at = None
        if stop is not None:
            self._stopped(sim.paused_view(stop))  # type: ignore[attr-defined]
            self.status.debug_note = None
        else:  # nothing found: where the swarm is stays shown (mid-step, or between steps)
            self.status.paused_at = sim.paused_view(still) if still else None  # type: ignore
            self.status.debug_note = NOTHING_THERE.get(command, "the robot did not stop")
        self._after_step()
        self._publish(force=True)

    def _after_step(self) -> None:
        listeners = self._on_step
        if not listeners or self._sim is None:
            return
        with self._sim_lock:
            for listener in listeners:
                try:
                    listener(self._sim)
                except Exception as error:  # noqa: BLE001 - a watch must not stop the swarm
                    self.status.error = f"watch: {type(error).__name__}: {error}"

    def _pace(self) -> None:
        target = self.settings.steps_per_second
        if target and target > 0:
            self._wake.wait(1.0 / target)
            self._wake.clear()
        else:
            time.sleep(0)  # let viser's threads in even at full speed

    def _publish(self, force: bool) -> None:
        if self._sim is None:
            return
        now = time.monotonic()
        step = self._sim.step_count
        self.status.step = step
        self._rate_marks.append((now, step))
        while self._rate_marks and now - self._rate_marks[0][0] > RATE_WINDOW_SECONDS:
            self._rate_marks.pop(0)
        if len(self._rate_marks) >= 2:
            (t0, s0), (t1, s1) = self._rate_marks[0], self._rate_marks[-1]
            self.status.steps_per_second = (s1 - s0) / (t1 - t0) if t1 > t0 else 0.0
        if not self._running:
            self.status.steps_per_second = 0.0
        if not force and now - self._last_frame_time < 1.0 / MAX_FRAME_HZ:
            return
        self._last_frame_time = now
        with self._sim_lock:
            frame = self._sim.frame()
        self.last_frame = frame
        self.status.robots = frame.count
        self.status.robots_in_error = int(frame.failed.sum())
        for listener in self._on_frame:
            try:
                listener(frame)
            except Exception as error:  # noqa: BLE001 - a drawing bug must not stop the swarm
                self.status.error = f"display: {type(error).__name__}: {error}"


def _robot_states(sim: Any) -> list[Any]:
    """The engine's per-robot states behind a simulation handle (none for a double)."""
    return list(getattr(getattr(sim, "sim", None), "robots", ()))
