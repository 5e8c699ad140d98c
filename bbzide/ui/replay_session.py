"""A recording seen the way the IDE sees a live swarm: frames, geometry, inspections by step.

Design: `ReplaySession` is the replay's stand-in for `WorldsSimulation`. A frame is a row of the
recording's arrays (no simulation, so any step is as cheap as the next: a seek is an index);
an inspection rebuilds the clicked robot's VM at that step from its keyframe and the recorded
inputs (`bbzide.recording.rebuild`) and decodes it with the same `inspect_robot` the live
inspector uses, so what a user sees at a recorded step is what the live inspector showed.
Event lists (errors, role changes, targets found) give the timeline's jump targets.

Breakpoints in a replay are "seek to the next hit": `next_hit` re-executes the recorded steps
after the current one, robot by robot, with the debugger's tracer on the rebuilt VM (the
reference mode, which leaves the same bytes), until a robot runs a statement of the line; the
seek then shows the step in which it did. A rebuild is exact, so a hit found here is the hit
the live run had.

Watches and the stigmergy view read the robots rebuilt at a recorded step with the live IDE's
readers (`bbzide.ui.watches`), so a recorded run's series and versions are the live run's.
A watch's value at a step is kept once read (a recording never changes); reading steps in
order re-executes one step per robot each (the rebuilder goes on from its last robot).
"""

from __future__ import annotations

import bisect
import gc
import threading
from typing import Any

import numpy as np

from bbzide.debugger.source_map import SourceMap
from bbzide.recording import layout
from bbzide.recording.reader import Recording
from bbzide.recording.rebuild import RobotRebuilder
from bbzide.ui.inspection import RobotInspection
from bbzide.ui.watches import (
    MAX_SAMPLES,
    Watch,
    WatchedRobot,
    read_watch,
    stigmergy_versions,
)
from bbzide.ui.world_adapter import inspect_robot, world_geometry
from bbzide.ui.world_backend import SwarmFrame, WorldGeometry
from bbzide.worlds.registry import WORLDS

#: Recorded steps a "next hit" search re-executes at most: every robot of a step is replayed
#: instruction by instruction (a 25-Kilobot step in ~0.1 s), so 500 steps is under a minute.
MAX_HIT_SEARCH_STEPS = 500

#: Recorded steps a watch's series reaches back from the shown step: the live IDE keeps this
#: many (`watches.MAX_SAMPLES`), so a replay's chart is the live one at the same step. The work
#: is bounded by it: a seek reads only the steps not read before (values are kept), and reading
#: a span in order re-executes each robot once per step (the rebuilder goes on from its last
#: robot), so a jump far ahead costs at most this many recorded steps of every robot, about
#: what a seek to a step that far past its keyframe costs; playing on costs one step a frame.
WATCH_STEPS = MAX_SAMPLES

#: The jump buttons, in the order shown: (event kind, button label).
JUMP_KINDS = (
    (layout.EVENT_TARGET, "Target found"),
    (layout.EVENT_ERROR, "Robot error"),
    (layout.EVENT_ROLE, "Role change"),
)


class ReplaySession:
    def __init__(self, recording: Recording, rebuilder: RobotRebuilder | None = None) -> None:
        self.recording = recording
        self.rebuilder = rebuilder or RobotRebuilder(recording)
        self._lock = threading.Lock()  # one rebuild at a time (the cache is not thread-safe)
        self._compiled_programs: dict[int, Any] = {}  # program id -> with call sites (inspect)
        self._warmed: set[int] = set()  # robots `warm_up` has done
        self._source_maps: dict[int, SourceMap | None] = {}  # program id -> statement lines
        #: (watch, step) -> its values there, one per robot (`watch_values`)
        self._watch_values: dict[tuple[Watch, int], list[float]] = {}
        self._event_steps = {
            kind: sorted({e.step for e in recording.events if e.kind == kind})
            for kind, _ in JUMP_KINDS
        }

    @property
    def first_step(self) -> int:
        return self.recording.first_step

    @property
    def last_step(self) -> int:
        return self.recording.last_step

    @property
    def step_seconds(self) -> float:
        return float(self.recording.meta.get("step_seconds", 0.1))

    def geometry(self) -> WorldGeometry:
        return world_geometry(self.recording.meta["geometry"])

    def frame(self, step: int) -> SwarmFrame:
        recording = self.recording
        row = recording.row(step)
        return SwarmFrame(
            step,
            recording.positions[row, :, :2].astype(np.float64),
            recording.headings[row].astype(np.float64),
            recording.leds[row].astype(np.float64) / 255.0,
            recording.failed[row].copy(),
            recording.links[row],
            [int(i) for i in recording.meta["robot_ids"]],
            [str(role) for role in recording.labels["role"][row]]
            if "role" in recording.labels else [],
        )

    def labels(self, step: int) -> dict[str, list[str]]:
        row = self.recording.row(step)
        return {name: values[row].tolist() for name, values in self.recording.labels.items()}

    def inspect(self, index: int, step: int) -> RobotInspection:
        from bbzide.vm.profiles import PROFILES

        with self._lock:
            robot = self.rebuilder.robot_at(index, step)
            program = self.rebuilder.program_at(index, step)
            profile = PROFILES[self.recording.meta["profiles"][index]]
            world_name = str(self.recording.meta.get("world", ""))
            spec = WORLDS.get(world_name)
            program_id = self.rebuilder.keyframe(index, step).program
            recorded = self.recording.programs.get(program_id) or {}
            host_names = spec.host_names if spec else ()
            program = self._with_call_sites(program_id, program, recorded.get("source"),
                                            host_names)
            view = inspect_robot(robot, profile, program, index, step,
                                 self.rebuilder.sent_at(index, step),  # as live: last step's
                                 host_names=host_names, world_name=world_name,
                                 recorded_source=recorded.get("source"))
        row = self.recording.row(step)
        view.notes.append(
            f"rebuilt from the keyframe at step {self.rebuilder.keyframe(index, step).step}; "
            f"heap used {self.recording.heap['used'][row][index]} B as recorded")
        return view

    def _with_call_sites(self, program_id: int, program: Any, source: str | None,
                         host_names: tuple[str, ...]) -> Any:
        """The recorded program with what the compiler knows beside the bytecode (call sites,
        globals, source lines), by compiling the recorded source again: used only when that
        gives the very `.bbo` the robots ran. Once per program."""
        cache = self._compiled_programs
        if program_id not in cache:
            cache[program_id] = program
            files = {location.file for location in getattr(program, "debug_map", {}).values()
                     if location.file != "(null)"}  # (the end-of-file token's annotation)
            if source is not None and len(files) == 1:
                from bbzide.compiler import bittybuzz_string_table, compile_source
                from bbzide.diagnostics import UserError

                try:
                    again = compile_source(source, files.pop(),
                                           string_table=bittybuzz_string_table(host_names))
                    rebuilt = again.to_bbo()
                    if rebuilt.bbo == program.bbo:
                        cache[program_id] = rebuilt
                except UserError:
                    pass  # an include that is not here any more: keep the recorded program
        return cache[program_id]

    def next_hit(self, line: int, after: int, robots: list[int] | None = None,
                 limit: int = MAX_HIT_SEARCH_STEPS) -> tuple[int, int] | None:
        """(step, robot index) of the first recorded step after `after` (within `limit`
        steps) in which one of `robots` (indexes; None: every robot with a VM) runs a
        statement on `line` of the recorded program, or None."""
        indexes = [i for i in (robots if robots is not None else
                               range(int(self.recording.meta["robots"])))
                   if self.has_vm(i)]
        last = min(self.last_step, after + limit)
        for step in range(after + 1, last + 1):
            for index in indexes:
                if self._runs_line(index, step, line):
                    return step, index
        return None

    def _runs_line(self, index: int, step: int, line: int) -> bool:
        """Whether robot `index` runs a statement of `line` in recorded `step` (re-executed
        from its state before it, traced)."""
        with self._lock:
            keyframe = self.rebuilder.keyframe(index, step)
            if keyframe.step == step and (
                    self.recording.keyframes[index][0].step >= step
                    or self.rebuilder.keyframe(index, step - 1).program != keyframe.program):
                return False  # no recorded state before this step (its first, a new program)
            # at a keyframe's own step too: `robot_at(step)` re-executes it from the state
            # before (the robot rebuilt here, traced) when that gives the keyframe's bytes
            robot = self.rebuilder.robot_at(index, step - 1)
            program_id = self.rebuilder.keyframe(index, step).program
            program = self._source_map(program_id, index, step)
            if program is None or line not in program.code_lines:
                return False
            lines = program.line_of
            seen: list[bool] = []

            def trace(vm: Any) -> None:
                if not seen and lines.get(vm.pc) == line:
                    seen.append(True)

            vm = robot.vm
            stress = vm.stress_gc
            vm.tracer, vm.stress_gc = trace, True
            try:
                self.rebuilder.robot_at(index, step)
            finally:
                vm.tracer, vm.stress_gc = None, stress
            return bool(seen)

    def debugger_at(self, step: int) -> Any:
        """The debugger room's `SwarmDebugger` on the swarm rebuilt at recorded `step` (after
        it): scratch copies of the robots, driven through the recorded steps after it
        (`bbzide.recording.recorded_swarm`); the recording and this session's rebuilds are
        left as they are."""
        from bbzide.debugger import SwarmDebugger
        from bbzide.recording.recorded_swarm import RecordedSwarm

        world = WORLDS.get(str(self.recording.meta.get("world", "")))
        host_names = world.host_names if world else ()

        def program_for(program_id: int, program: Any) -> Any:
            recorded = self.recording.programs.get(program_id) or {}
            return self._with_call_sites(program_id, program, recorded.get("source"),
                                         host_names)

        with self._lock:
            swarm = RecordedSwarm(self.recording, step, program_for)
        return SwarmDebugger(swarm)

    def _source_map(self, program_id: int, index: int, step: int) -> SourceMap | None:
        """The debugger's statement map of a recorded program (None without its source)."""
        maps = self._source_maps
        if program_id not in maps:
            recorded = self.recording.programs.get(program_id) or {}
            world = WORLDS.get(str(self.recording.meta.get("world", "")))
            program = self._with_call_sites(program_id, self.rebuilder.program_at(index, step),
                                            recorded.get("source"),
                                            world.host_names if world else ())
            maps[program_id] = SourceMap(program) if program.source_text else None
        return maps[program_id]

    # ---- watches and the stigmergy view ---------------------------------------------------------
    def _watched_robots(self, step: int, count: int | None = None) -> list[WatchedRobot]:
        """The robots (the first `count`) rebuilt at `step`, as watches read them (call with
        the lock held; a robot's VM is valid until its next rebuild)."""
        ids = [int(i) for i in self.recording.meta["robot_ids"]]
        robots = []
        for index in range(len(ids) if count is None else min(count, len(ids))):
            if not self.has_vm(index):
                robots.append(WatchedRobot(ids[index], None, ()))
                continue
            robot = self.rebuilder.robot_at(index, step)
            robots.append(WatchedRobot(ids[index], robot.vm,
                                       tuple(self.rebuilder.program_at(index, step).strings)))
        return robots

    def watch_values(self, watch: Watch, step: int) -> list[float]:
        """`watch` read from every robot rebuilt at recorded `step` (after it), as the live
        IDE read it after that step; `BadWatch` for an expression that cannot be read."""
        key = (watch, step)
        found = self._watch_values.get(key)
        if found is None:
            with self._lock:
                found = read_watch(watch, self._watched_robots(step))
            self._watch_values[key] = found
        return found

    def watch_steps(self, step: int) -> range:
        """The recorded steps a watch's series shows at `step` (the last `WATCH_STEPS`)."""
        return range(max(self.first_step, step - WATCH_STEPS + 1), step + 1)

    def forget_watches(self, keep: list[Watch]) -> None:
        """Drop the values read for watches not in `keep` (cleared from the panel)."""
        self._watch_values = {key: values for key, values in self._watch_values.items()
                              if key[0] in keep}

    def stigmergy_versions(self, step: int, count: int
                           ) -> list[tuple[str, int, int, str, list[int]]]:
        """The stigmergy versions the first `count` robots hold at recorded `step`."""
        with self._lock:
            return stigmergy_versions(self._watched_robots(step, count))

    def warm_up(self, stop: threading.Event | None = None, count: int | None = None) -> None:
        """Get every robot's rebuild ready ahead of its first click (call from a background
        thread when the replay opens), one robot at a time under the lock, so a user's seek
        waits for at most one robot's share of this (`count`: only the first `count` robots
        with a VM not warmed yet; the replay app warms one before it serves the page, which
        pays the process's one-off costs, ~0.4-0.6 s, measured as a fresh process's first
        seek; the rest in the background):

        * boot its rebuild robot (the script's top level and `init`: ~70 ms for an M300 SAR
          drone), so a seek only restores and re-executes;
        * rebuild it once over its first keyframe's span. A replay receives and steps each
          robot on its own, through compiled VM functions the live swarm's batched step does
          not use; the first call of each in the process loads it from numba's cache (30-100
          ms each; measured, the worst first seeks, 111-153 ms, were these).
          Different robots' inputs take different ones, so every robot is re-executed once.
        """
        recording = self.recording
        for index in range(int(recording.meta["robots"])):
            if stop is not None and stop.is_set():
                return
            if not self.has_vm(index) or index in self._warmed:
                continue
            if count is not None:
                if count <= 0:
                    return
                count -= 1
            with self._lock:
                self._warmed.add(index)
                try:
                    self.rebuilder.prepare(index, self.first_step)
                    self.rebuilder.robot_at(index, self._first_span_end(index))
                except Exception:  # noqa: BLE001 - a damaged keyframe shows when clicked
                    continue
        if count is not None:
            return
        # The recording and the booted robots now live as long as the replay: move them out
        # of the garbage collector's full passes, which otherwise walk them all (~100 ms for
        # a 25-drone recording, measured as the worst seeks) whenever one runs mid-seek.
        gc.freeze()

    def _first_span_end(self, index: int) -> int:
        """The last step rebuilt from robot `index`'s first keyframe: the step before its
        second keyframe, or the recording's last step."""
        frames = self.recording.keyframes.get(index) or []
        if len(frames) > 1:
            return max(frames[0].step, frames[1].step - 1)
        return self.last_step

    def has_vm(self, index: int) -> bool:
        return self.rebuilder.has_vm(index)

    def event_steps(self, kind: str) -> list[int]:
        return self._event_steps.get(kind, [])

    def jump(self, kind: str, step: int, forward: bool) -> int | None:
        """The next (or previous) step with an event of `kind`, or None."""
        steps = self.event_steps(kind)
        if forward:
            at = bisect.bisect_right(steps, step)
            return steps[at] if at < len(steps) else None
        at = bisect.bisect_left(steps, step) - 1
        return steps[at] if at >= 0 else None

    def source(self) -> str | None:
        programs: dict[int, dict[str, Any]] = self.recording.programs
        for program_id in sorted(programs, reverse=True):
            text = programs[program_id].get("source")
            if text:
                return text
        return None

    def events_text(self, limit: int = 200) -> list[str]:
        return [f"step {e.step}: {e.text}" for e in self.recording.events[:limit]]

    def event_choices(self, limit: int = 200) -> list[tuple[str, int]]:
        """(text, step) of each event, in order, for a list that seeks to the chosen one."""
        return [(f"step {e.step}: {e.text}", int(e.step)) for e in self.recording.events[:limit]]

    def jump_kinds(self) -> list[tuple[str, str]]:
        """The jump rows that apply to this recording: robot errors always (none is news too);
        found targets and role changes only when the recording has some (a Kilobot run has no
        targets and no roles)."""
        return [(kind, label) for kind, label in JUMP_KINDS
                if kind == layout.EVENT_ERROR or self.event_steps(kind)]
