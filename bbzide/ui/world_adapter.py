"""The lower rooms (compiler, VM, worlds, recording) as the IDE sees them, in this one file.

Everything the UI needs from the lower rooms passes through `WorldsBackend` (which worlds exist,
compile for a world's platform, start a swarm) and `WorldsSimulation` (step, draw, inspect,
record). The names are the ones the rooms settled in ARCHITECTURE.md: `WORLDS` (`WorldSpec`:
example, profile, host_names, default_robots), `Simulation(world, program, robots=N, seed=K,
robot_factory=...)` with `step_count`, the `positions`/`headings`/`leds` arrays, `robots`
(`RobotState`: failure, robot, robot_id), `link_indexes` (robot index pairs) and `world`
(bounds, walls, robot_radius, robot_height, comm_range); `Profile` (heap_size, obj_size, rsv_actrec,
elems_per_tseg); the VM's `heap` (data, rtobj, ltseg, peak_used, gc_runs), `gsyms`, `vstig`,
`neighbors`, `queues`.

Swarms are built through the recording room's `Recordable` factory, so the IDE's Record toggle
can start recording any running swarm (robots pass their inputs through untouched until then).
`inspect_robot` builds the inspector view from any robot, live or rebuilt from a recording.

Lower rooms are imported lazily, so `bbzide --help` never waits for them.
"""

from __future__ import annotations

import functools
import json
from collections.abc import Sequence
from importlib import import_module
from pathlib import Path
from types import ModuleType
from typing import Any

import numpy as np

from bbzide.diagnostics import UserError
from bbzide.ui.heap_decode import HeapGeometry, HeapReader, HeapRoots
from bbzide.ui.inspection import FrameView, PausedAt, RobotInspection
from bbzide.ui.watches import WatchedRobot, read_watch, stigmergy_versions
from bbzide.ui.world_backend import SwarmFrame, WorldGeometry

REPO_ROOT = Path(__file__).resolve().parents[2]
#: `bbzide` with no arguments opens this world with this many robots: the Kilobot table with
#: ~25 robots, a swarm a student can follow robot by robot.
DEFAULT_WORLD_HINT = "kilobot"
DEFAULT_ROBOTS = 25


#: Instructions one entry into Buzz code (top level, init, step, a listener) may run in the
#: IDE before the robot stops with BUDGET. The example steps run 35-55 instructions; 5,000 is
#: ~100 such steps (on a Kilobot, ~0.1 s of CPU). The VM model runs ~10,000 instructions/s
#: on a loaded machine, so a script stuck in a loop costs each robot 0.5 s, not the 10 s of
#: the Robot's default budget: the swarm reloads in seconds after the fix.
IDE_INSTRUCTION_BUDGET = 5_000
#: Plain steps (no breakpoint set) keep the swarm's state for reverse stepping once every this
#: many control steps, so Back works from any pause (a Pause, a single step, an error): a
#: Kilobot swarm's checkpoint costs about five of its control steps of CPU (the debugger room's
#: CHECKPOINT_EVERY), so one in 1,000 costs ~0.5 %, within a run's noise; a step back from
#: such a pause re-executes at most 999 plain steps (well under a second for 25 Kilobots).
PAST_EVERY = 1_000


class WorldsBackend:
    """The real worlds (bbzide.worlds), compiled with the real compiler for each platform."""

    def __init__(self) -> None:
        self._compiler = import_module("bbzide.compiler")
        self._engine = import_module("bbzide.worlds.engine")
        import_module("bbzide.vm.robot")  # the firmware loop every world drives
        self._profiles = import_module("bbzide.vm.profiles").PROFILES
        self._recording = import_module("bbzide.recording.recorder")
        self._worlds: dict[str, Any] = dict(self._engine.WORLDS)

    # ---- what exists ---------------------------------------------------------------------------
    def world_names(self) -> list[str]:
        return list(self._worlds)

    def default_world(self) -> str:
        names = self.world_names()
        return next((n for n in names if DEFAULT_WORLD_HINT in n.lower()), names[0])

    def default_robots(self, world: str) -> int:
        return int(self._worlds[world].default_robots)

    def example_path(self, world: str) -> Path | None:
        example = self._worlds[world].example
        if not example:
            return None
        path = Path(example)
        return path if path.is_absolute() else REPO_ROOT / path

    def platform(self, world: str) -> Any:
        return self._profiles[self._worlds[world].profile]

    def flash_budget(self, world: str) -> int | None:
        """Bytes of flash left for the `.bbo` (the compiler room's `FLASH_BUDGETS`: flash less
        the boot section and the BBZVM), not the whole flash."""
        budgets = import_module("bbzide.compiler.footprint").FLASH_BUDGETS
        budget = budgets.get(self.platform(world).name)
        return None if budget is None else int(budget.bytes_for_bytecode)

    def host_names(self, world: str) -> list[str]:
        return list(self._worlds[world].host_names)

    # ---- compile and run -----------------------------------------------------------------------
    def compile(self, text: str, path: Path, world: str) -> tuple[Any, Any]:
        strings = self._compiler.bittybuzz_string_table(self.host_names(world))
        compiled = self._compiler.compile_source(
            text, str(path), include_path=(str(path.parent),), string_table=strings
        )
        return compiled, compiled.to_bbo()

    def create(self, world: str, program: Any, robots: int, seed: int,
               scenario: Any = None, world_options: dict[str, Any] | None = None,
               loop: str = "pop") -> WorldsSimulation:
        """A swarm of `robots` running `program` in the world with `world_options`, each robot
        in the firmware `loop`; with a `scenario` (same world and robot count), its world
        options, positions, labels and watches instead, every group with a script running
        `program` (the IDE edits one script)."""
        recordable = self._recording.Recordable(loop=loop,
                                                instruction_budget=IDE_INSTRUCTION_BUDGET)
        if scenario is not None and scenario.world == world and scenario.robots == robots:
            simulation = scenario.with_seed(seed).simulation(
                dict.fromkeys(scenario.scripts(), program), robot_factory=recordable.factory)
        else:  # a bad world option is the registry's one-line WorldConfigError
            simulation = self._engine.Simulation(
                world, program, robots=robots, seed=seed, robot_factory=recordable.factory,
                world_options=world_options or {})
        return WorldsSimulation(simulation, program, self.platform(world), recordable,
                                self._recording)


    # ---- scenarios -------------------------------------------------------------------------------
    def setup_scenario(self, world: str, robots: int, seed: int, script: Path,
                       scenario: Any = None, simulation: WorldsSimulation | None = None) -> Any:
        """The set-up the IDE runs, as a scenario (bbzide.worlds.scenario): the one it was
        opened with (same world and robot count) with `script` as every group's script, else
        one group of `robots` running `script`; with `simulation`, the robots' positions and
        headings now are pinned in it."""
        module = import_module("bbzide.worlds.scenario")
        if scenario is not None and scenario.world == world and scenario.robots == robots:
            current = scenario.with_seed(seed).with_script(script)
        else:
            current = module.single_script_scenario(world, script, robots, seed)
        if simulation is not None:
            current = module.pin_positions(current, simulation.sim)
        return current

    def save_scenario(self, scenario: Any, path: Path) -> Path:
        """Write `scenario` to `path` (read back and checked before this returns)."""
        return import_module("bbzide.worlds.scenario").save_scenario(scenario, path)


class WorldsSimulation:
    """A `bbzide.worlds.engine.Simulation` behind the UI's `SimulationHandle` interface."""

    def __init__(self, simulation: Any, program: Any, profile: Any, recordable: Any = None,
                 recording: ModuleType | None = None) -> None:
        self.sim = simulation
        self._recording = recording or import_module("bbzide.recording.recorder")
        self.program = program
        self.profile = profile
        self.recordable = recordable
        self.recorder: Any = None
        self.source_text: str | None = None
        self._overlays: tuple[str, dict[str, Any]] | None = None
        self._debugger: Any = None
        self._keeps_past = True  # False once a checkpoint failed (robots without snapshots)
        self.pause_on_error = True  # what a debugger made later starts with

    # ---- debugger ------------------------------------------------------------------------------
    def debugger(self) -> Any:
        """The debugger room's `SwarmDebugger` on this swarm (made on first use: a run without
        breakpoints never builds one)."""
        if self._debugger is None:
            self._debugger = import_module("bbzide.debugger").SwarmDebugger(self.sim)
            self._debugger.pause_on_error = self.pause_on_error
        return self._debugger

    def set_breakpoints(self, lines: Sequence[Any]) -> list[str]:
        """The IDE's breakpoints (`bbzide.ui.breakpoints.LineBreakpoint`) in the main script;
        the ones the debugger refuses (a robot id not in the swarm, a condition that does not
        parse) are left out, each with its one-line reason in the list returned."""
        room = import_module("bbzide.debugger")
        debugger = self.debugger()
        kept, refused = [], []
        for line in lines:
            breakpoint = room.Breakpoint(line.line, robot=line.robot, condition=line.condition,
                                         hit_count=line.hit_count)
            try:
                debugger.check_breakpoint(breakpoint)
            except room.DebuggerError as error:
                refused.append(error.message)
                continue
            kept.append(breakpoint)
        debugger.breakpoints = kept
        return refused

    def set_pause_on_error(self, on: bool) -> None:
        self.pause_on_error = on
        if self._debugger is not None:
            self._debugger.pause_on_error = on

    def debug(self, command: str, *arguments: Any) -> Any:
        """One debugger command (`run`, `step_over`, `step_back`, ...): its `Stop` or None.
        A step the debugger completes is recorded like any other; going back in time ends a
        recording (a recording's timeline only goes forward)."""
        before = self.step_count
        stop = getattr(self.debugger(), command)(*arguments)
        if self.recorder is not None:
            if self.step_count == before + 1:
                self.recorder.record_step()
            elif self.step_count < before:
                self.stop_recording()
        return stop

    def paused_view(self, stop: Any) -> PausedAt:
        """The debugger room's `Stop` as the IDE shows it."""
        index = self._index_of(int(stop.robot))
        return PausedAt(index, int(self.sim.robots[index].robot_id), int(stop.step),
                        _optional_int(stop.pc), _optional_int(stop.line),
                        _optional_int(getattr(stop, "column", None)), str(stop.reason),
                        tuple(FrameView(str(f.function), _optional_int(f.line),
                                        {str(k): str(v) for k, v in dict(f.locals).items()})
                              for f in getattr(stop, "frames", ()) or ()),
                        self._stop_message(index, stop), self.mid_step)

    def _stop_message(self, index: int, stop: Any) -> str | None:
        """An error stop's text, in the student's terms when the failing call is known."""
        failure = getattr(self.sim.robots[index].robot, "failure", None)
        if stop.reason != "error" or failure is None:
            return getattr(stop, "error", None) or None
        _where, message = explain_robot_failure(
            failure, self.sim.robots[index].program or self.program,
            self.sim.world.host_names, self.sim.world.name)
        return f"{getattr(failure, 'reason', 'error')}: {message}"

    def error_view(self, index: int) -> PausedAt:
        """Robot `index`, which has just failed, as a stop "error" at its failing call."""
        state = self.sim.robots[index]
        failure = state.failure
        program = state.program or self.program
        where, message = explain_robot_failure(failure, program, self.sim.world.host_names,
                                               self.sim.world.name)
        frames: tuple[FrameView, ...] = ()
        try:
            frames = self.paused_view_frames(index)
        except Exception:  # noqa: BLE001 - the frames are a bonus; the error is what counts
            frames = ()
        return PausedAt(index, int(state.robot_id), self.step_count,
                        _optional_int(getattr(failure, "pc", None)),
                        None if where is None else int(where.line),
                        None if where is None else int(where.col), "error", frames,
                        f"{getattr(failure, 'reason', 'error')}: {message}")

    def paused_view_frames(self, index: int) -> tuple[FrameView, ...]:
        """Robot `index`'s call frames as the debugger reads them."""
        frames = self.debugger().frames(self.robot_key(index))
        return tuple(FrameView(str(f.function), _optional_int(f.line),
                               {str(k): str(v) for k, v in dict(f.locals).items()})
                     for f in frames)

    def robot_key(self, index: int) -> int:
        """How the debugger room names robot `index` (its Buzz id)."""
        return int(self.sim.robots[index].robot_id)

    def _index_of(self, key: int) -> int:
        for state in self.sim.robots:
            if int(state.robot_id) == key:
                return int(state.index)
        raise KeyError(key)

    # ---- watches and the stigmergy view -----------------------------------------------------
    def watched_robots(self, max_robots: int | None = None) -> list[WatchedRobot]:
        """The robots (the first `max_robots`) as watches and the stigmergy view read them."""
        return [WatchedRobot(int(state.robot_id), getattr(state.robot, "vm", None),
                             tuple(getattr(state.program or self.program, "strings", ())
                                   or ()))
                for state in self.sim.robots[:max_robots]]

    def watch_values(self, watch: Any) -> list[float]:
        """`watch` (`bbzide.ui.watches.Watch`) read from every robot: one number per robot,
        NaN where there is none (no VM, no such global or key, not a number)."""
        return read_watch(watch, self.watched_robots())

    def stigmergy_versions(self, max_robots: int) -> list[tuple[str, int, int, str, list[int]]]:
        """Every virtual-stigmergy version the first `max_robots` robots hold
        (`bbzide.ui.watches.stigmergy_versions`)."""
        return stigmergy_versions(self.watched_robots(max_robots))

    def close_debugger(self) -> None:
        """Finish a control step the debugger holds (as the old program would) and drop the
        debugger: the swarm goes on with plain steps."""
        if self._debugger is not None:
            self._debugger.close()
            self._debugger = None

    @property
    def has_debugger(self) -> bool:
        return self._debugger is not None

    @property
    def mid_step(self) -> bool:
        """The debugger stopped inside a control step (some robots have not run it yet)."""
        return self._debugger is not None and self._debugger.paused_at is not None

    @property
    def step_count(self) -> int:
        return int(self.sim.step_count)

    def step(self) -> None:
        """One plain control step; now and then the debugger keeps the state before it
        (`PAST_EVERY`), so a pause after plain steps can be stepped back from."""
        if self._keeps_past and (self._debugger is None
                                 or self.sim.step_count % PAST_EVERY == 0):
            try:
                self.debugger().checkpoint()
            except Exception:  # noqa: BLE001 - firmware without snapshots: no past to keep
                self._keeps_past = False
        self.sim.step()
        if self.recorder is not None:
            self.recorder.record_step()

    def robot(self, index: int) -> Any:
        return self.sim.robots[index].robot

    def load_program(self, program: Any, keep_state: bool) -> None:
        self.program = program
        self.close_debugger()  # its checkpoints and source maps belong to the old program
        if self.recorder is not None and not keep_state:
            self.stop_recording()  # the world restarts at step 0: a new timeline
        self.sim.load_program(program, keep_state=keep_state)

    # ---- recording -----------------------------------------------------------------------------
    def start_recording(self, path: Path, force: bool = False) -> Any:
        """Record this swarm from its current step into `path` (a new `.rrd`)."""
        if self.recordable is None:
            raise UserError("this swarm was not built for recording")
        self.stop_recording()
        source = self.source_text
        self.recorder = self._recording.MissionRecorder(
            path, self.sim, self.recordable, force=force, source_of=lambda _program: source
        )
        return self.recorder

    def stop_recording(self) -> Path | None:
        recorder, self.recorder = self.recorder, None
        if recorder is None:
            return None
        recorder.close()
        return recorder.path

    # ---- drawing -------------------------------------------------------------------------------
    def frame(self) -> SwarmFrame:
        sim = self.sim
        states = sim.robots
        failed = np.fromiter((s.failure is not None for s in states), dtype=bool, count=len(states))
        ids = [int(s.robot_id) for s in states]
        # (sender, receiver) robot indexes as the engine keeps them: no id round trip
        links = np.asarray(sim.link_indexes, dtype=np.int32).reshape(-1, 2)
        return SwarmFrame(
            int(sim.step_count),
            np.array(sim.positions[:, :2], dtype=np.float64),
            np.array(sim.headings, dtype=np.float64),
            np.clip(np.array(sim.leds, dtype=np.float64), 0.0, 1.0),
            failed,
            links,
            ids,
            [str(role) for role in getattr(sim.world, "roles", None) or []],
        )

    def geometry(self) -> WorldGeometry:
        return world_geometry(self.sim.world)

    def overlays(self) -> dict[str, Any]:
        """The world's overlays as plain data; the same object while they do not change."""
        plain = self._recording.jsonable(self.sim.world.overlays())
        key = json.dumps(plain, sort_keys=True)
        if self._overlays is None or self._overlays[0] != key:
            self._overlays = (key, plain)
        return self._overlays[1]

    # ---- inspector ------------------------------------------------------------------------------
    def inspect(self, index: int) -> RobotInspection:
        state = self.sim.robots[index]
        if state.robot is None:
            raise UserError(f"robot #{index} has no VM (a passive body)")
        world = self.sim.world
        return inspect_robot(state.robot, self.profile, state.program or self.program, index,
                             self.step_count, _sent_last_step(self.sim, index),
                             world.host_names, world.name)

    def runtime_errors(self) -> list[tuple[Any, str, int]]:
        """The swarm's failures grouped by place and message: (location, message, robots),
        for the editor's markers (one marker per line however many robots hit it)."""
        world = self.sim.world
        counts: dict[tuple[Any, str], int] = {}
        for state in self.sim.failures:
            program = state.program or self.program
            where, message = explain_robot_failure(state.failure, program, world.host_names,
                                                   world.name)
            text = f"{getattr(state.failure, 'reason', 'error')}: {message}"
            counts[(where, text)] = counts.get((where, text), 0) + 1
        return [(where, text, count) for (where, text), count in counts.items()]


def _optional_int(value: Any) -> int | None:
    return None if value is None else int(value)


def world_geometry(world: Any) -> WorldGeometry:
    """Drawing facts of a `World` (or of a recording's `geometry` metadata, same names)."""
    get = world.get if isinstance(world, dict) else lambda name: getattr(world, name)
    segments = np.array(get("walls"), dtype=np.float64).reshape(-1, 2, 2)
    return WorldGeometry(
        float(get("robot_radius")),
        float(get("comm_range")),
        tuple(float(v) for v in get("bounds")),
        segments,
        float(get("robot_height")),
    )


def explain_robot_failure(failure: Any, program: Any, host_names: Sequence[str],
                          world_name: str) -> tuple[Any, str]:
    """(location, message) of a robot's failure: in the student's terms at the call itself
    when the compiler knows the failing call (`bbzide.compiler.call_sites`), else the debug
    map's location and the VM's message."""
    reason = getattr(failure, "reason", "error")
    call_sites = import_module("bbzide.compiler.call_sites")
    explained = call_sites.explain_failure(program, reason, int(getattr(failure, "pc", -1)),
                                           host_names, call_sites.robot_phrase(world_name))
    if explained is not None:
        return explained
    return getattr(failure, "location", None), str(getattr(failure, "message", ""))


def inspect_robot(robot: Any, profile: Any, program: Any, index: int, step: int,
                  last_sent: Sequence[bytes] = (), host_names: Sequence[str] = (),
                  world_name: str = "", recorded_source: str | None = None) -> RobotInspection:
    """The inspector's view of one robot's VM (a live robot, or one rebuilt from a recording).
    `last_sent`: the payloads it sent in its last step (the out-queue is drained by then);
    `host_names`, `world_name`: the world's, to explain a failed call in the student's terms;
    `recorded_source`: a recording's copy of the program's source (for the error's line)."""
    vm = robot.vm
    heap = vm.heap
    geometry = HeapGeometry(
        size=int(profile.heap_size),
        object_size=int(profile.obj_size),
        reserved=int(profile.rsv_actrec),
        elems_per_segment=int(profile.elems_per_tseg),
    )
    rop, lsp = int(heap.rtobj), int(heap.ltseg)
    strings = list(getattr(program, "strings", []) or [])
    reader = HeapReader(bytes(heap.data), geometry, rop, lsp, strings)
    frames = _frame_rows(vm, program)
    decoded = reader.decode(HeapRoots(
        globals_table=int(vm.gsyms),
        function_list=int(vm.flist),
        locals_table=int(vm.lsyms) if frames else -1,  # between steps no function runs
        stack=[int(vm.stack[p]) for p in range(int(vm.stackptr) + 1)],
        function_name=_function_namer(program),
    ))
    failure = robot.failure
    error_text = None
    error_line = None
    if failure is not None:
        where, message = explain_robot_failure(failure, program, host_names, world_name)
        error_text = f"{getattr(failure, 'reason', 'error')}: {message}"
        if where is not None:
            error_text += f" at {where}"
            error_line = _line_of(program, where, recorded_source)
    # the line of the pc: a call's own line when the compiler kept it (call_sites.py)
    site = getattr(program, "call_sites", {}).get(int(vm.pc))
    at_pc = site.location if site is not None else (
        program.location_of(int(vm.pc)) if hasattr(program, "location_of") else None)
    gsyms = int(vm.gsyms)
    defined = getattr(getattr(program, "symbols", None), "defined", set())
    # the script's own globals first, then the built-ins (`id`, `neighbors`, host functions)
    globals_ = sorted(reader.named_entries(gsyms), key=lambda pair: pair[0] not in defined)
    return RobotInspection(
        robot_index=index,
        robot_id=int(getattr(robot, "robot_id", index)),
        step=step,
        state=getattr(vm.state, "name", str(vm.state)).lower(),
        pc=int(vm.pc),
        heap_size=geometry.size,
        rop=rop,
        lsp=lsp,
        reserved_bytes=geometry.reserved * geometry.object_size,
        blocks=decoded.blocks,
        used_bytes=decoded.used_bytes,
        free_bytes=decoded.free_bytes,
        peak_bytes=int(heap.peak_used),
        gc_runs=int(heap.gc_runs),
        ram_bytes=import_module("bbzide.compiler.footprint").RAM_BYTES.get(profile.name),
        objects=decoded.objects,
        frames=frames + _stack_rows(vm, reader),
        globals=globals_,
        stigmergy=_stigmergy_rows(vm, reader, strings),
        neighbors=_neighbor_rows(vm),
        swarms=_swarm_rows(vm),
        in_queue=[_message_text(m) for m in vm.queues.in_messages()],
        out_queue=[_message_text(m) for m in vm.queues.out_messages()],
        last_error=error_text,
        last_error_line=error_line,
        warnings=_runtime_warnings(vm, last_sent),
        pc_line=at_pc.line if at_pc is not None and at_pc.line else None,
    )


@functools.lru_cache(maxsize=16)  # a few programs at a time (a reload, a replay's revisions)
def _named_functions(bbo: bytes, strings: tuple[str, ...]) -> dict[int, str]:
    bytecode = import_module("bbzide.compiler.bytecode")
    try:
        return import_module("bbzide.compiler.disassembler").function_names(
            bytecode.read_bbo(bbo), strings)
    except bytecode.BytecodeError:
        return {}


def _function_namer(program: Any) -> Any:
    """pc -> the function whose code starts there: a named function's name, a lambda's
    place (`function at line 12`)."""
    bbo = getattr(program, "bbo", None)
    named = {} if bbo is None else _named_functions(
        bytes(bbo), tuple(getattr(program, "strings", []) or []))

    def name(pc: int) -> str | None:
        if pc in named:
            return named[pc]
        where = program.location_of(pc) if hasattr(program, "location_of") else None
        return f"function at line {where.line}" if where is not None and where.line else None

    return name


#: The inspector lists at most this many stack entries (the top ones): a screenful.
STACK_ROWS = 24


def _stack_rows(vm: Any, reader: HeapReader) -> list[str]:
    top = int(vm.stackptr)
    rows = []
    for position in range(top, max(-1, top - STACK_ROWS), -1):
        index = int(vm.stack[position])
        rows.append(f"stack[{position}] = #{index} {reader.value_text(index)}")
    return rows


def _stigmergy_rows(vm: Any, reader: HeapReader, strings: list[str]) -> list[tuple[str, str]]:
    rows = []
    for entry in getattr(vm.vstig, "entries", []):
        key = strings[entry.key] if 0 <= entry.key < len(strings) else f"#{entry.key}"
        rows.append((f"{key} (t{entry.timestamp}, robot {entry.robot})",
                     reader.value_text(entry.value)))
    return rows


def _frame_rows(vm: Any, program: Any) -> list[str]:
    """Call frames, innermost first, with the source line each returns to (the VM room's
    `stack_frames`); empty between two steps, when no Buzz function is running."""
    frames = import_module("bbzide.vm.inspector").stack_frames(vm)
    rows = []
    for depth, frame in enumerate(frames):
        where = program.location_of(frame.return_pc) if hasattr(program, "location_of") else None
        line = f" (line {where.line})" if where is not None and where.line else ""
        rows.append(f"frame {depth}: returns to pc {frame.return_pc}{line}, base {frame.base}")
    return rows


def _neighbor_rows(vm: Any) -> list[tuple[str, str]]:
    """Neighbor data as the robot's VM holds it (the VM room's `neighbor_entries`: XTREME ring
    buffer or heap sub-table): id, distance, azimuth, elevation."""
    rows = []
    for n in import_module("bbzide.vm.inspector").neighbor_entries(vm):
        rows.append((f"robot {n.robot}", f"distance {_number(n.distance)}, azimuth "
                     f"{_number(n.azimuth)}, elevation {_number(n.elevation)}"))
    return rows


def _number(value: Any) -> str:
    return "?" if value is None else f"{value:.3g}" if isinstance(value, float) else str(value)


def _swarm_rows(vm: Any) -> list[str]:
    """Swarm memberships (`my_swarmlist`, 8 bits) and the swarm stack (`swarm.id()`)."""
    view = import_module("bbzide.vm.inspector").swarm_view(vm)
    member = ", ".join(map(str, view.member_of)) or "none"
    rows = [f"member of: {member} (bits {view.membership_bits:08b})"]
    if view.executing:
        rows.append("executing in swarm: " + " > ".join(map(str, view.executing)))
    return rows


def _sent_last_step(sim: Any, index: int) -> list[bytes]:
    """The payloads robot `index` sent in the last step (the engine's `step_outbox`)."""
    outbox = sim.step_outbox
    return [outbox.payload(k) for k in np.flatnonzero(outbox.robots == index).tolist()]


def _runtime_warnings(vm: Any, last_sent: Sequence[bytes]) -> list[str]:
    """Pitfalls only a running VM can see in its queues.

    * A table sent in a message (queued, sent in the last step, or received): the 9-byte
      payload carries one 3-byte value, so BittyBuzz sends the table's type and the robot id
      only; the receivers never see its contents.
    * The outgoing queue full: one more message hits the firmware's overflow bug (stale bytes
      sent instead of the new message).
    """
    messages = import_module("bbzide.vm.messages")
    valued = (messages.BROADCAST, messages.VSTIG_PUT, messages.VSTIG_QUERY)
    warnings = []
    queues = vm.queues
    outgoing = queues.out_messages()
    # `serialize` stops after the type and robot id when the value is a table (3 bytes); the
    # out-queue is drained at the end of each step, hence `last_sent`
    seen = outgoing + list(last_sent) + queues.in_messages()
    if any(len(m) == 3 and m[0] in valued for m in seen):
        warnings.append("a table is being sent: BittyBuzz messages carry one 3-byte value, so "
                        "only its type goes out (the receivers get no contents)")
    if len(outgoing) >= queues.out_capacity:
        warnings.append(f"outgoing queue full ({len(outgoing)}/{queues.out_capacity}): the next "
                        "message hits the firmware's overflow bug (stale bytes are sent)")
    return warnings


def _message_text(message: Any) -> str:
    if isinstance(message, bytes | bytearray):
        return f"{len(message)} B: {bytes(message).hex(' ')}"
    return str(message)


def _line_of(program: Any, location: Any, recorded_source: str | None = None) -> str | None:
    """The source line of `location` as the robot's program was compiled (the file on disk may
    have changed since): from the program, else from the recording's copy of its source, else
    from the disk (an included file)."""
    line_of = getattr(program, "source_line", None)
    line = line_of(location) if line_of is not None else None
    if line is None and recorded_source is not None:
        lines = recorded_source.splitlines()
        line = lines[location.line - 1] if 1 <= location.line <= len(lines) else None
    return line if line is not None else _source_line(location)


def _source_line(location: Any) -> str | None:
    try:
        lines = Path(location.file).read_text(encoding="utf-8").splitlines()
    except (OSError, AttributeError):
        return None
    return lines[location.line - 1] if 1 <= location.line <= len(lines) else None
