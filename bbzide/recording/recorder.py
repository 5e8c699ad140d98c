"""Writes a running `Simulation` to a Rerun `.rrd`, step by step, in batched columns.

Design: recording is an observer above the worlds room. The engine is not changed: robots are
built through the engine's `robot_factory` hook by a `Recordable`, which builds plain robots
(a `Robot` stays a `Robot`, so the engine's compiled batch of control steps still takes it)
and only wraps the world host functions it passes them (`input_log.SwarmCapture.tap`, a
pass-through until a recorder switches capture on). So a swarm started in the IDE can be
recorded from any step on, and `bbzide run --record` records from step 0.

After each `Simulation.step()`, `record_step()` writes the step's figures into the flush
window (`_Window`): positions, LED colours, headings and failure flags as rows of arrays
allocated once per window, the heap figures of every robot as plain ints, the watched labels,
message counters and radio links as the engine's arrays; and it keeps what the step's inputs
are made of: the engine's deliveries (`Simulation.step_deliveries`, numpy columns), which
robots ran a control step (`Robot.steps_done` moved), and the host calls the taps wrote as
bytes. Every `flush_every` steps (or `FLUSH_SECONDS`, whichever comes first) the inputs of all
buffered steps are encoded at once (`input_log.encode_steps_joined`: one buffer, compressed as
one zstd frame, format 4) and the window goes to Rerun as a handful of `send_columns` calls (one
chunk per entity and flush, not one `log` per robot per step: 50-100x cheaper, ui-stack-notes
§4); the stream is flushed to disk, so a process killed mid-run leaves a file readable up to
its last flush. The viewer-only arrows (headings, radio links) are sent for every
`VIEWER_ARROWS_EVERY`-th step; every per-step value bbzide reads back is sent for every step.

Exact VM state at any step = the robot's nearest earlier keyframe (its `Robot.snapshot()`,
compressed, taken when recording starts, whenever it boots, e.g. on a program reload, and
then after `keyframe_every` steps or `KEYFRAME_BUDGET_SECONDS` of its VM time, whichever
comes first) plus the recorded inputs re-executed (`rebuild.py`). Rare things (keyframes,
events, overlays when they change) wait for the next flush and leave as columns too; only a
program is logged as a single row when first used.
"""

from __future__ import annotations

import base64
import dataclasses
import gc
import json
import operator
import time
import uuid
import weakref
from collections.abc import Callable
from itertools import chain
from pathlib import Path
from types import SimpleNamespace
from typing import Any

import numpy as np

from bbzide.diagnostics import UserError
from bbzide.recording import keyframes, layout
from bbzide.recording.compression import INPUT_LEVEL, Compressor
from bbzide.recording.input_log import SwarmCapture, encode_steps, encode_steps_joined
from bbzide.vm.host import LatchedHostFunction
from bbzide.vm.vm import State

#: A robot is keyframed at least every 150 steps (15 s of Kilobot time)...
KEYFRAME_EVERY = 150
#: ...and sooner once its VM work since the last keyframe (receiving and control steps) took
#: 30 ms of CPU time: a seek re-executes at most that much live VM time, which replays in up
#: to ~2x as long (each step's inputs are decoded too; measured: a drone's 40 steps at the
#: budget replayed in 52 ms), so with restoring and the inspector (~5-10 ms) a seek stays
#: under 100 ms whatever the script costs per step (the replay's seek goal; the machine's load
#: adds to both). The step
#: bound decides for cheap firmware; SAR drones reach the budget first on busy stretches
#: (after ~40-85 steps at ~0.35 ms of VM time a step). A replay re-executes one robot at a
#: time, without the live swarm's batched compiled step: measured, ~0.2 ms a
#: step for a Kilobot and up to ~0.4 ms for a drone, two to four times its live VM time, so
#: the step bound matters for seeks too. 100 would be too often: a Kilobot's keyframe
#: (~0.2-0.4 ms) every 100 steps is a fifth of the recorder's time, the compiled swarm step
#: making its simulation ~2 ms a step. 200 made the worst SAR seek 84-101 ms (drones that
#: stay under the budget for 150-200 steps replay them in ~60 ms); 150: worst ~55-65 ms
#: for both worlds (benchmarks/record_bench.py).
#: A keyframe of an M300 drone costs ~0.4 ms (snapshot ~0.25, block delta ~0.1): keyframes
#: are the recorder's largest cost, ~0.15 ms per SAR step (benchmarks/record_bench.py).
#: (A budget of 25 ms of control steps alone, the receiving not counted, gives about the same
#: keyframe rate.)
KEYFRAME_BUDGET_SECONDS = 0.030
#: Robots are not timed one by one (an engine steps them in one batch, and a wrapper that
#: timed each would keep them off its compiled path): the engine's VM time of each step
#: (`sim.timings["vm"]`, wall clock) is shared out by the instructions each robot executed
#: in it (`vm.instructions_executed`), and a robot's share since its last keyframe is scaled
#: by the share of wall time the recording thread had the CPU meanwhile (`thread_time`,
#: 2.6 us a call on this machine, sampled once a step). On a loaded machine a step's wall
#: time holds time spent waiting for a core; counting it made the keyframe rate (the
#: recorder's largest cost) grow with the load for no gain, since a seek replays CPU work.
#: The share is floored at 5 %, so a thread starved for a while (a share that low means
#: ~20x more wall than CPU time) still keyframes.
MIN_CPU_SHARE = 0.05
#: The budget is looked at every 8th step (reading every robot's instruction counter and the
#: arithmetic are ~0.05 ms; every 4th step would be ~7 % of the recorder's time on
#: a Kilobot swarm): a keyframe comes at most 7 steps late, ~2.5 ms of one drone's VM time
#: against a 30 ms budget.
KEYFRAME_CHECK_EVERY = 8
#: ...unless keyframing that robot costs more than 1/12 of that (a robot with a huge heap):
#: then the budget grows to 12x the keyframe's cost, which keeps keyframes under ~8 % of its
#: VM time (the recording goal is <= 10 %) at the price of longer seeks for such robots.
KEYFRAME_COST_FACTOR = 12
#: Columns are sent and flushed every 500 steps (50 s of Kilobot time, ~5 s of a 25-drone SAR
#: swarm): each flush costs ~15 `send_columns` calls of Rerun's Python-side conversion and
#: our own preparation of the columns, partly a fixed cost per flush, so fewer, larger chunks
#: (measured: 100 steps cost 0.15 ms per SAR step, 250 0.10; with 25 Kilobots, 500 steps
#: take 7.5-8.0 % of the simulation's CPU time against 8.0-8.3 % for 250, three runs each)...
FLUSH_EVERY = 500
#: ...or after 10 wall-clock seconds, so a slow swarm loses at most ~10 s if killed. (Each flush
#: writes one chunk per entity, ~1.5 KB of Arrow framing each: flushing every step of a slow
#: swarm made that framing most of the file.)
FLUSH_SECONDS = 10.0
#: Program rows (logged when first used) wait in Rerun's batcher until our flush, so they too
#: leave with the flush instead of one chunk each.
BATCHER_FLUSH_BYTES = 8 * 1024 * 1024
#: World overlays (light field, targets, belief map) are recorded every 10 steps when they
#: changed: they change slowly and some are costly to build (the Kilobot light raster is
#: 32 x 32 evaluations). A world whose overlays have `targets` is polled every step until all
#: are found, so "target found" events land on their step, but in between only its found count
#: is compared (the JSON of an M300's overlays, ~1 ms, was a fifth of the recorder's time when
#: done every step; building the overlays alone is still ~50 us a step, so a world that can
#: count its found targets directly, `World.targets_found`, is asked that instead).
OVERLAY_EVERY = 10
#: Overlays that did not change when looked at are looked at half as often the next time, down
#: to every 80 steps (8 s of Kilobot time); any change brings back `OVERLAY_EVERY`, and the
#: last step is always looked at when the recording closes. A Kilobot's light field never
#: changes, and building its raster every 10 steps was ~0.02 ms a step, ~7 % of the recorder.
OVERLAY_EVERY_MAX = 80
#: The Rerun viewer's arrows (radio links, headings) are logged every 5th step only (half a
#: second of Kilobot time): at ~24 B per link per array the link arrows were a fifth of a dense
#: Kilobot recording, and the heading arrows of every step were ~150 KB a flush for Rerun's
#: writer thread to compress; `pairs` and `heading` keep every step's links and headings.
VIEWER_ARROWS_EVERY = 5

#: The label of `Robot.boot`'s last phase (`on_phase`): the boot has ended.
BOOT_DONE_PHASE = "init"

#: Robot ids below this map to indexes through an array (65,536 ids: 256 KB at most; ids are
#: u16 on the wire, so every real swarm fits).
MAX_ID_TABLE = 1 << 16


#: The heap figures read every step, from each heap in one C call: ROP, LSP, peak, GC runs
#: (its size never changes: read when the recorder attaches the robot, `_attach`).
_HEAP_FIGURES = operator.attrgetter("rtobj", "ltseg", "peak_used", "gc_runs")
_HEAP_FIGURE_COUNT = 4
#: A flush window's arrays start this many steps long (`FLUSH_EVERY`) and double when a
#: larger `flush_every` needs more.
WINDOW_ROWS = 512
_STEPS_DONE = operator.attrgetter("steps_done")
#: What the per-step pass reads of each `RobotState` (one C getter per robot and figure)
_FAILURE = operator.attrgetter("failure")
_PROGRAM = operator.attrgetter("program")
_WORLD_LABELS = operator.attrgetter("_labels")
#: A step's host calls when there were none (`CallLog.ordered` of an empty log).
_NO_CALLS: tuple[list[int], bytes] = ([], b"")
_INSTRUCTIONS = operator.attrgetter("instructions_executed")
#: What the per-step pass reads of a robot slot without a firmware loop (a passive body).
_NO_ROBOT = SimpleNamespace(steps_done=0, vm=SimpleNamespace(
    instructions_executed=0, heap=SimpleNamespace(size=0, rtobj=0, ltseg=0, peak_used=0,
                                                  gc_runs=0)))


class RecordingError(UserError):
    """A recording that cannot be written or read (exists, not writable, corrupt, foreign)."""


def build_robot(program: Any, profile: Any, robot_id: int, host_functions: Any,
                loop: str = "pop", instruction_budget: int | None = None) -> Any:
    """A `bbzide.vm.robot.Robot`, built the same way when recording and when rebuilding."""
    from bbzide.vm.robot import Robot

    kwargs: dict[str, Any] = {"host_functions": host_functions, "loop": loop}
    if instruction_budget is not None:
        kwargs["instruction_budget"] = instruction_budget
    return Robot(program, profile, robot_id, **kwargs)


class Recordable:
    """A robot factory for `Simulation(robot_factory=...)` that makes the swarm recordable.

    It builds plain robots (a `Robot` stays a `Robot`, so an engine's compiled batch of
    control steps takes it) and changes only what is passed to them: each world host
    function is wrapped by `capture.tap` (a pass-through until a recorder calls
    `capture.start()`). It also sets the robot's `on_phase` hook to learn when a boot ends,
    so that a recorder can keyframe a robot rebooted mid-recording (a program reload) and
    so that the host calls a boot makes are not taken for a step's inputs.
    """

    def __init__(self, loop: str = "pop", instruction_budget: int | None = None,
                 build: Callable[..., Any] | None = None) -> None:
        self.loop = loop
        self.instruction_budget = instruction_budget
        #: called with a robot whose boot just ended without a VM error (a recorder's)
        self.listener: Callable[[Any], None] | None = None
        self._build = build
        self.capture = SwarmCapture()
        #: the robots this factory built, weakly (a program reload replaces them)
        self.built: weakref.WeakSet[Any] = weakref.WeakSet()
        #: robots built whose boot has not ended well yet: a boot that fails (a VM error or
        #: an exception) never says so; the recorder keyframes those at its next step
        self.booting: list[Any] = []
        self.factory = self._make

    def _make(self, program: Any, profile: Any, robot_id: int, host_functions: Any) -> Any:
        live = [False]  # this robot's host calls are a step's inputs (not its boot's)
        capture = self.capture
        tapped = {}
        latched = []
        for name, fn in host_functions.items():
            # stays latched (see SwarmCapture.tap) unless some of its int calls fail: a
            # replay takes every int call of a latched function for a plain ret0
            if isinstance(fn, LatchedHostFunction) and fn.below is None:
                tapped[name] = dataclasses.replace(
                    fn, function=capture.tap(robot_id, name, fn.function, live,
                                             latched=fn.argc))
                latched.append((name, fn.argc))
            else:
                tapped[name] = capture.tap(robot_id, name, fn, live)
        if self._build is not None:
            robot = self._build(program, profile, robot_id, tapped)
        else:
            robot = build_robot(program, profile, robot_id, tapped, self.loop,
                                self.instruction_budget)
        robot.bbzide_host_names = list(host_functions)
        robot.bbzide_latched = latched
        self.built.add(robot)
        if hasattr(robot, "on_phase"):
            if self.listener is None:  # not recording: a recorder's start keyframes them all
                self.booting.clear()  # (so failed boots do not pile up in an IDE session)
            self.booting.append(robot)
            robot.on_phase = self._phase_hook(robot, live)
        else:  # a firmware loop that cannot say when it booted: all its calls are inputs
            live[0] = True
        return robot

    def _phase_hook(self, robot: Any, live: list[bool]) -> Callable[[str], None]:
        ref = weakref.ref(robot)  # the robot holds this hook: no cycle through it

        def phase(label: str) -> None:
            if label != BOOT_DONE_PHASE:
                return
            live[0] = True
            me = ref()
            if me is None:
                return
            state = getattr(getattr(me, "vm", None), "state", None)
            if state is not None and state == State.ERROR:
                return  # fails right after this hook: keyframed at the recorder's next step
            if me in self.booting:
                self.booting.remove(me)
            if self.listener is not None:
                self.listener(me)

        return phase


def check_output_path(path: Path, force: bool) -> Path:
    """The path to write, or a `RecordingError` (exists without --force, no such folder)."""
    path = Path(path)
    if path.suffix != ".rrd":
        raise RecordingError(f"{path}: a recording must end in .rrd")
    if path.is_dir():
        raise RecordingError(f"{path} is a directory")
    if path.exists() and not force:
        raise RecordingError(f"{path} exists; give --force to overwrite it")
    if not path.parent.is_dir():
        raise RecordingError(f"{path}: no such directory {path.parent}")
    return path


def program_record(program: Any, program_id: int, source: str | None) -> dict[str, Any]:
    """A BittyBuzzProgram as JSON: what a replay needs to rebuild a robot and show its lines."""
    bbo = getattr(program, "bbo", None)
    if bbo is None and hasattr(program, "to_bbo"):
        program = program.to_bbo()
        bbo = program.bbo
    debug = {str(pc): [loc.file, loc.line, loc.col]
             for pc, loc in getattr(program, "debug_map", {}).items()}
    return {"id": program_id, "bbo": base64.b64encode(bytes(bbo)).decode(),
            "strings": list(program.strings), "debug_map": debug, "source": source}


def jsonable(value: Any) -> Any:
    """Overlay data (numpy arrays, tuples) as JSON-ready lists and numbers."""
    return _jsonable(value)


def _jsonable(value: Any) -> Any:
    if isinstance(value, np.ndarray):
        return np.round(value, 6).tolist() if value.dtype.kind == "f" else value.tolist()
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, tuple | list):
        return [_jsonable(v) for v in value]
    if isinstance(value, dict):
        return {str(k): _jsonable(v) for k, v in value.items()}
    return value


def _fingerprint(value: Any) -> Any:
    """A value equal for equal overlay data (numpy arrays by dtype, shape and bytes), cheap
    to compare: which overlays changed since the last recorded ones."""
    if isinstance(value, np.ndarray):
        return (value.dtype.str, value.shape, value.tobytes())
    if isinstance(value, dict):
        return tuple((key, _fingerprint(item)) for key, item in value.items())
    if isinstance(value, list | tuple):
        return (type(value).__name__, *map(_fingerprint, value))
    return value


def found_targets(overlays: dict[str, Any]) -> int:
    """How many overlay targets are found: `targets_found` flags (the M300 field) or
    `{"targets": [{"found": true}, ...]}`."""
    flags = overlays.get("targets_found")
    if isinstance(flags, list):
        return sum(1 for f in flags if f)
    targets = overlays.get("targets")
    if not isinstance(targets, list):
        return 0
    return sum(1 for t in targets if isinstance(t, dict) and t.get("found"))


def _target_points(overlays: dict[str, Any]) -> np.ndarray | None:
    targets = overlays.get("targets")
    if not isinstance(targets, list) or not targets:
        return None
    points = []
    for target in targets:
        where = target.get("position", target.get("pose")) if isinstance(target, dict) else target
        try:
            x, y = float(where[0]), float(where[1])
        except (TypeError, ValueError, IndexError, KeyError):
            return None
        points.append((x, y, 0.0))
    return np.array(points, dtype=np.float32)


class _Window:
    """What a recorder buffers until its next flush: per-robot figures in arrays of `rows`
    steps (row k: the k-th buffered step), the rest in lists, one item per step."""

    def __init__(self, n: int, rows: int) -> None:
        self.rows = rows
        self.positions = np.empty((rows, n, 3), dtype=np.float32)
        self.headings = np.empty((rows, n), dtype=np.float32)
        self.leds = np.empty((rows, n, 3), dtype=np.float32)
        self.failed = np.zeros((rows, n), dtype=bool)  # written only while some robot failed
        #: per step and robot, its `_HEAP_FIGURES` (n x 4 ints a step, flat)
        self.heap: list[int] = []
        self.has_vm: list[np.ndarray] = []  # per step: has a recorded VM, per robot
        self.heap_sizes: list[np.ndarray] = []  # ... and its heap's size
        self.labels: list[dict[str, np.ndarray]] = []
        self.traffic: list[tuple[np.ndarray, ...]] = []
        self.links: list[np.ndarray] = []
        self.inputs: list[tuple[Any, ...] | None] = []

    def grow(self) -> None:
        """Twice as many rows (the rows written so far kept)."""
        for name in ("positions", "headings", "leds", "failed"):
            old = getattr(self, name)
            new = np.zeros((2 * self.rows, *old.shape[1:]), dtype=old.dtype)
            new[:self.rows] = old
            setattr(self, name, new)
        self.rows *= 2


class MissionRecorder:
    """Records `sim` into `path` from its current step; call `record_step()` after each step."""

    def __init__(
        self,
        path: Path,
        sim: Any,
        recordable: Recordable,
        *,
        force: bool = False,
        keyframe_every: int = KEYFRAME_EVERY,
        flush_every: int = FLUSH_EVERY,
        sources: dict[int, str] | None = None,
        source_of: Callable[[Any], str | None] | None = None,
    ) -> None:
        import rerun as rr

        from bbzide.recording.blueprint import mission_blueprint

        if keyframe_every < 1 or flush_every < 1:
            raise RecordingError("keyframe and flush intervals must be at least 1 step")
        self.path = check_output_path(Path(path), force)
        self.sim = sim
        self.recordable = recordable
        self.keyframe_every = keyframe_every
        self.flush_every = flush_every
        self._source_of = source_of or (lambda program: None)
        self.count = len(sim.robots)
        self._index_of = {s.robot_id: s.index for s in sim.robots}
        #: robot id -> index as an array, when ids are small non-negative numbers (as usual)
        self._index_by_id: np.ndarray | None = None
        if self._index_of and 0 <= min(self._index_of) and max(self._index_of) < MAX_ID_TABLE:
            self._index_by_id = np.full(max(self._index_of) + 1, -1, dtype=np.int32)
            for robot_id, index in self._index_of.items():
                self._index_by_id[robot_id] = index
        n = self.count
        self._capture = recordable.capture
        #: per robot index: its firmware loop, or a stand-in with zero figures (no VM)
        self._robots: list[Any] = [_NO_ROBOT] * n
        self._vms: list[Any] = [_NO_ROBOT.vm] * n  # ... its VM, and that VM's heap
        self._heaps: list[Any] = [_NO_ROBOT.vm.heap] * n
        self._recorded = np.zeros(n, dtype=bool)  # has a firmware loop we record
        self._recorded_now = self._recorded.copy()
        self._heap_sizes = np.zeros(n, dtype=np.int64)  # of each robot's heap (0: no VM)
        self._all_recorded = False
        self._keyframed: dict[int, int] = {}  # robot index -> step of its last keyframe
        # Per robot, as arrays (the per-step pass is a few numpy operations, not 25 loops):
        # the step and the VM seconds at which its next keyframe is due, the VM seconds it
        # ran since its last one, and the (thread CPU, wall) clocks at that keyframe.
        self._due_step = np.full(n, np.iinfo(np.int64).max, dtype=np.int64)
        self._budget = np.full(n, np.inf)
        self._busy = np.zeros(n)
        self._cpu_then = np.zeros(n)
        self._wall_then = np.zeros(n)
        # (thread CPU, wall) clocks: read when a keyframe is taken or a robot's budget is
        # looked at, not every step (a `thread_time` call is a system call, ~3 us)
        # What the last step left (to see what the next one did): each robot's
        # `steps_done` (it ran a control step) and `vm.instructions_executed` (its share of
        # the swarm's VM time), whether it had failed, and the engine's VM seconds.
        self._steps_done = [0] * n
        self._all_stepped = np.ones(n, dtype=bool)  # (never written to)
        self._instructions = np.zeros(n, dtype=np.int64)
        self._failed = np.zeros(n, dtype=bool)
        self._any_failed = False  # self._failed.any()
        self._vm_seconds = float(sim.timings.get("vm", 0.0))
        self._check_at = 0  # the next step at which `_keyframes_due` looks
        self._budget_check_at = 0  # ... and the next at which it looks at the VM budgets
        #: messages come from `sim.step_deliveries` (else from receive hooks on the robots)
        self._packed = hasattr(sim, "step_deliveries") and not getattr(sim, "asynchronous",
                                                                       False)
        self._keyframe_counts: dict[int, int] = {}
        self._snapshot_seconds: dict[int, float] = {}  # robot -> cost of its last keyframe
        self._bases: dict[int, tuple[int, bytes]] = {}  # robot -> its previous keyframe
        self._inputs_compressor = Compressor(INPUT_LEVEL)
        # Rare rows wait here until the next flush and leave as columns with the steps (one
        # `log` call per row cost ~0.5 ms of Rerun's Python-side conversion).
        self._keyframe_rows: list[tuple[int, list[int], list[bytes], list[int], list[int]]] = []
        self._event_rows: list[tuple[int, str, int, str]] = []
        self._overlay_rows: list[tuple[int, str, np.ndarray | None]] = []
        self._viewer_labels: list[str] | None = None  # the labels last sent to the viewer
        self._radii_sent = False
        for state in sim.robots:
            if state.robot is not None and state.robot not in recordable.built:
                raise RecordingError("this swarm was not built for recording (its robots have "
                                     "no input capture); restart it, then record")
        self.rr = rr
        import datetime

        batching = rr.ChunkBatcherConfig(flush_tick=datetime.timedelta(hours=1),
                                         flush_num_bytes=BATCHER_FLUSH_BYTES)
        self.rec = rr.RecordingStream(layout.APPLICATION_ID, recording_id=str(uuid.uuid4()),
                                      batcher_config=batching)
        try:
            self.rec.save(str(self.path), default_blueprint=mission_blueprint())
        except Exception as error:  # noqa: BLE001 - any sink failure is the user's file system
            raise RecordingError(f"cannot write {self.path}: {error}") from None
        self.start_step = int(sim.step_count)
        self._programs: dict[int, int] = {}
        self._program_objects: list[Any] = []
        self._window = _Window(n, min(flush_every, WINDOW_ROWS))
        self._steps: list[int] = []
        self._last_flush = time.monotonic()
        self._last_texts: dict[str, list[str]] = {}  # each watched label, per robot
        self._label_arrays: dict[str, np.ndarray] = {}  # ... as buffered
        self._known_failures: set[int] = {s.index for s in sim.robots if s.failure is not None}
        self._last_overlays: str | None = None
        self._overlay_fingerprint: Any = None
        self._targets_found = 0
        self._watch_in_program: dict[int, bool] = {}
        # A robot's program changes only with the robot (the engine boots a new one, which the
        # recorder attaches): which programs can have watched globals is looked at again then
        self._programs_changed = True
        self._globals_watched = True  # some robot's program can have a watched global
        self._has_targets = False  # targets still to find: poll every step (found events)
        self._overlay_every = OVERLAY_EVERY // 2  # doubled at the first look
        self._overlays_due = self.start_step + OVERLAY_EVERY  # the next look at the overlays
        self._last_step = self.start_step  # the last step recorded
        self.closed = False
        self.steps_recorded = 0
        self.seconds_spent = 0.0
        self._write_meta()
        self._capture.start()
        recordable.booting.clear()  # booted before recording: their keyframes are below
        for state in sim.robots:
            if state.robot is not None:
                self._attach(state.index, state.robot)
        recordable.listener = self._robot_booted
        self._keyframe(np.flatnonzero(self._recorded).tolist(), self.start_step)
        self._event(self.start_step, layout.EVENT_PROGRAM, -1,
                    f"recording starts at step {self.start_step}")
        self._frame(self.start_step, first=True)
        self._flush()
        # Starting a recording imports Rerun and pyarrow (~100,000 new objects): the garbage
        # collector's next full pass, ~100-150 ms, would otherwise fall on some step soon after
        # (measured); pay it here, with the rest of the start.
        gc.collect()
        # The CPU share of the first keyframes' budget is counted from here: the set-up above
        # is all CPU work and would make any waiting of the robots look like CPU time.
        self._cpu_then[:], self._wall_then[:] = time.thread_time(), time.perf_counter()
        self._vm_seconds = float(sim.timings.get("vm", 0.0))

    # ---- static parts ---------------------------------------------------------------------------
    def _write_meta(self) -> None:
        sim = self.sim
        world = sim.world
        states = sim.robots
        meta = {
            "format": layout.FORMAT,
            "version": layout.FORMAT_VERSION,
            "world": world.name,
            "robots": self.count,
            "robot_ids": [int(s.robot_id) for s in states],
            "profiles": [getattr(s.profile, "name", str(s.profile)) for s in states],
            "latched": [[list(pair) for pair in getattr(s.robot, "bbzide_latched", [])]
                        if s.robot is not None else [] for s in states],
            "host_names": [list(getattr(s.robot, "bbzide_host_names", []) or [])
                           if s.robot is not None else [] for s in states],
            "seed": int(getattr(sim, "seed", 0)),
            "watch": list(getattr(sim, "watch", ())),
            "loop": self.recordable.loop,
            "instruction_budget": self.recordable.instruction_budget,
            "keyframe_every": self.keyframe_every,
            "start_step": self.start_step,
            "step_seconds": float(world.step_seconds),
            "geometry": {
                "bounds": [float(v) for v in world.bounds],
                "walls": _jsonable([list(map(list, w)) for w in world.walls]),
                "robot_radius": float(world.robot_radius),
                "robot_height": float(getattr(world, "robot_height", 0.0)),
                "comm_range": float(world.comm_range),
            },
            "created": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()),
        }
        self.rec.log(layout.MISSION, self.rr.AnyValues(meta=json.dumps(meta)), static=True)
        # For the Rerun viewer: the table's walls (so the 3D view frames the whole world) and
        # series names for the plots.
        rr = self.rr
        walls = [[(a[0], a[1], 0.0), (b[0], b[1], 0.0)] for a, b in world.walls]
        if walls:
            self.rec.log(layout.WALLS, rr.LineStrips3D(walls, colors=(90, 90, 110)), static=True)
        names = [f"robot {s.robot_id}" for s in states]
        for figure in layout.HEAP_FIGURES:
            self.rec.log(f"{layout.HEAP}/{figure}", rr.SeriesLines(names=names), static=True)
        self.rec.log(layout.MESSAGE_TOTALS, rr.SeriesLines(
            names=["sent", "received", "dropped", "bytes"]), static=True)

    def _program_id(self, program: Any, step: int) -> int:
        key = id(program)
        found = self._programs.get(key)
        if found is not None:
            return found
        program_id = len(self._program_objects)
        self._programs[key] = program_id
        self._program_objects.append(program)  # keeps id() unique while we record
        record = program_record(program, program_id, self._source_of(program))
        self._set_time(step)
        self.rec.log(layout.PROGRAMS, self.rr.AnyValues(program=json.dumps(record)))
        return program_id

    def _set_time(self, step: int) -> None:
        self.rec.set_time(layout.TIMELINE, sequence=step)
        self.rec.set_time(layout.TIME_SECONDS, duration=step * float(self.sim.world.step_seconds))

    # ---- keyframes and events -------------------------------------------------------------------
    def _attach(self, index: int, robot: Any) -> None:
        """Record robot `index`'s firmware loop `robot` from now on."""
        self._robots[index] = robot
        self._vms[index] = robot.vm  # a Robot's VM and its heap live as long as the robot
        self._heaps[index] = robot.vm.heap
        self._recorded[index] = True
        self._recorded_now = self._recorded.copy()  # what the steps from now on hold
        self._programs_changed = True
        self._heap_sizes = self._heap_sizes.copy()  # (the buffered steps keep the old one)
        self._heap_sizes[index] = robot.vm.heap.size
        self._all_recorded = bool(self._recorded.all())
        if not self._packed:
            self._capture.hook_receive(robot, index)

    def _robot_booted(self, robot: Any) -> None:
        """A robot (re)booted between steps (program reload): keyframe its fresh state."""
        if self.closed:
            return
        for state in self.sim.robots:
            if state.robot is robot:
                self._rebooted(state.index, int(self.sim.step_count))
                return

    def _rebooted(self, index: int, step: int) -> None:
        self._attach(index, self.sim.robots[index].robot)
        self._keyframe_counts[index] = 0
        self._keyframe([index], step, full=True)
        if index == int(np.flatnonzero(self._recorded)[0]):
            self._event(step, layout.EVENT_PROGRAM, -1, f"program loaded at step {step}")

    def _keyframe(self, indexes: list[int], step: int, full: bool = False) -> None:
        """Snapshot robots `indexes` now. A robot's first keyframe after (re)boot and every
        `keyframes.FULL_KEYFRAME_EVERY`-th are full; the others store the blocks that changed
        since the robot's previous keyframe (`bases` = its step; see keyframes.py)."""
        if not indexes:
            return
        snapshots, programs, bases = [], [], []
        clocks = (time.thread_time(), time.perf_counter())
        for index in indexes:
            state = self.sim.robots[index]
            self._keyframed[index] = step
            robot = state.robot
            self._busy[index] = 0.0
            self._cpu_then[index], self._wall_then[index] = clocks
            self._steps_done[index] = getattr(robot, "steps_done", 0)
            self._instructions[index] = getattr(robot.vm, "instructions_executed", 0)
            started = time.thread_time()
            snapshot = robot.snapshot()
            count = self._keyframe_counts.get(index, 0)
            previous = self._bases.get(index)
            if full or previous is None or count % keyframes.FULL_KEYFRAME_EVERY == 0:
                snapshots.append(keyframes.encode_full(snapshot))
                bases.append(-1)
            else:
                snapshots.append(keyframes.encode_delta(snapshot, previous[1]))
                bases.append(previous[0])
            self._bases[index] = (step, snapshot)
            self._keyframe_counts[index] = count + 1
            cost = self._snapshot_seconds[index] = time.thread_time() - started
            self._due_step[index] = step + self.keyframe_every
            self._check_at = min(self._check_at, step + self.keyframe_every)
            self._budget[index] = max(KEYFRAME_BUDGET_SECONDS, KEYFRAME_COST_FACTOR * cost)
            programs.append(self._program_id(state.program, step))
        self._keyframe_rows.append((step, list(indexes), snapshots, programs, bases))

    def _event(self, step: int, kind: str, robot: int, text: str) -> None:
        self._event_rows.append((step, kind, int(robot), text))

    # ---- per step -------------------------------------------------------------------------------
    def record_step(self) -> None:
        """Call after each `sim.step()`: buffer this step, flush every `flush_every` steps."""
        if self.closed:
            return
        started = time.perf_counter()
        self._frame(int(self.sim.step_count))
        if (len(self._steps) >= self.flush_every
                or time.monotonic() - self._last_flush > FLUSH_SECONDS):
            self._flush()
        self.steps_recorded += 1
        self.seconds_spent += time.perf_counter() - started

    def _frame(self, step: int, first: bool = False) -> None:
        """The state at `step` and the inputs that led here (from step - 1): positions,
        failures, heap figures, labels, the robots' inputs, which keyframes are due, and the
        events (new failure, label change). The first frame takes no inputs and only notes
        the labels. Per-robot figures are read by one C getter per robot into one array
        each; the rest is numpy over those arrays (a Python pass over the robots with
        several branches each was a quarter of the recorder's time)."""
        sim = self.sim
        states = sim.robots
        n = self.count
        if self.recordable.booting:
            self._failed_boots(step)
        robots = self._robots
        # Each numpy call costs several us here, with the caches cold after the simulation
        # step: the common case (no failure, every robot recorded) makes as few as it can, and
        # what can wait (stacking, the heap's `has VM` column) waits for the flush.
        failures = list(map(_FAILURE, states))
        if failures.count(None) == n and not self._any_failed:
            failed = new_failures = self._failed  # none, as before (never written to)
        else:
            failed = np.fromiter((f is not None for f in failures), dtype=bool, count=n)
            new_failures = failed & ~self._failed
            self._failed = failed
            self._any_failed = bool(failed.any())
            for i in np.flatnonzero(new_failures).tolist():
                if i not in self._known_failures:
                    self._known_failures.add(i)
                    self._event(step, layout.EVENT_ERROR, i,
                                f"robot {states[i].robot_id}: {_failure_text(failures[i])}")
        window = self._window
        row = len(self._steps)
        if row == window.rows:
            window.grow()
        # Plain ints in one list, made into one array at the flush: converting 100 ints to
        # numpy here, with the caches cold after the simulation step, took as long as reading
        # them (~10 us); kept as tuples, they made the garbage collector run every ~30 steps.
        window.heap.extend(chain.from_iterable(map(_HEAP_FIGURES, self._heaps)))
        labels = self._labels(states, step, first) if sim.watch else {}
        inputs = None  # the first frame has none
        due: list[int] = []
        if not first:
            steps_done = list(map(_STEPS_DONE, robots))
            if all(map(operator.ne, steps_done, self._steps_done)):
                stepped = self._all_stepped  # the usual case: every robot stepped
            else:
                stepped = np.fromiter(map(operator.ne, steps_done, self._steps_done),
                                      dtype=bool, count=n)
            if new_failures is not failed or not self._all_recorded:
                stepped = (stepped | new_failures) & self._recorded
            self._steps_done = steps_done
            inputs = self._step_inputs(stepped)
            due = self._keyframes_due(step, self._vms, failed)
        stats = sim.stats
        self._steps.append(step)
        self._last_step = step
        # Written into the flush window's arrays (one copy each, stacked already), which the
        # garbage collector does not track: lists kept alive until the flush made it run
        # (full passes of ~100 ms) several times more often.
        window.positions[row] = sim.positions
        window.headings[row] = sim.headings
        window.leds[row] = sim.leds
        if self._any_failed:
            window.failed[row] = failed
        window.has_vm.append(self._recorded_now)  # (the same array until a robot is attached)
        window.heap_sizes.append(self._heap_sizes)
        window.labels.append(labels)
        # the engine's counters: new arrays every step, stacked at the flush
        window.traffic.append((stats.sent, stats.received, stats.dropped, stats.bytes_sent))
        pairs = getattr(sim, "link_indexes", None)  # (sender, receiver) indexes, if given
        window.links.append(self._link_indexes(sim.links) if pairs is None else pairs)
        window.inputs.append(inputs)
        self._keyframe(due, step)
        if first:  # a replay starts with the world's overlays (belief map, light field...)
            self._record_overlays(step, due=True)
        elif self._has_targets or step >= self._overlays_due:
            self._record_overlays(step)

    def _step_inputs(self, stepped: np.ndarray) -> tuple[Any, ...]:
        """What the step's inputs are made of, kept as is until the flush encodes all the
        buffered steps at once (`input_log.encode_steps`): which robots stepped, the
        engine's deliveries (a new `PackedMessages` every step, never changed afterwards)
        or the hooked receives, and the host calls, already encoded by the capture."""
        calls, received = self._capture.take()
        # (an empty `received` is the capture's next step's too: not kept, see `take`)
        deliveries = self.sim.step_deliveries if self._packed else (received or None)
        return (stepped, deliveries,
                calls.ordered(self._index_of) if calls.robots else _NO_CALLS)

    def _keyframes_due(self, step: int, vms: list[Any], failed: np.ndarray) -> list[int]:
        """The robots whose keyframe is due: `keyframe_every` steps since their last one, or
        `KEYFRAME_BUDGET_SECONDS` of VM CPU time. A robot's VM time is the engine's VM time
        of the step (`sim.timings["vm"]`, wall clock) shared out by the instructions each
        robot executed in it (robots are not timed one by one: an engine steps them in one
        batch), scaled by this thread's CPU share since the robot's last keyframe. The budget
        is looked at every `KEYFRAME_CHECK_EVERY` steps; at the steps where some robot's step
        bound falls in between, only the step bounds are (robots keyframed at different steps
        made those a third of the looks, each reading every robot's instruction counter)."""
        if step < self._check_at:
            return []
        if step < self._budget_check_at:  # a step bound falls due: nothing else to look at
            self._check_at = min(self._budget_check_at, int(self._due_step.min()))
            due = self._due_step <= step
            return np.flatnonzero(due & self._recorded & ~failed).tolist()
        self._budget_check_at = step + KEYFRAME_CHECK_EVERY
        self._check_at = min(self._budget_check_at, int(self._due_step.min()))
        instructions = np.fromiter(map(_INSTRUCTIONS, vms), dtype=np.int64, count=self.count)
        ran = np.maximum(instructions - self._instructions, 0)
        self._instructions = instructions
        vm_seconds = float(self.sim.timings.get("vm", 0.0))
        spent = max(0.0, vm_seconds - self._vm_seconds)
        self._vm_seconds = vm_seconds
        total = int(ran.sum())
        if total:
            self._busy += ran * (spent / total)
        due = self._due_step <= step
        over = self._busy >= self._budget  # wall >= CPU time: the CPU share only for these
        if over.any():
            cpu, wall = time.thread_time(), time.perf_counter()
            for i in np.flatnonzero(over).tolist():
                span = wall - self._wall_then[i]
                share = 1.0 if span <= 0 else min(1.0, max(
                    MIN_CPU_SHARE, (cpu - self._cpu_then[i]) / span))
                due[i] |= self._busy[i] * share >= self._budget[i]
        if not due.any():
            return []
        return np.flatnonzero(due & self._recorded & ~failed).tolist()

    def _labels(self, states: list[Any], step: int, first: bool) -> dict[str, np.ndarray]:
        """The watched labels of every robot as one text array per name (the last step's
        array again when nothing changed), and a `role` event per change."""
        if self._programs_changed:  # (re)loaded: which robots can have them?
            self._programs_changed = False
            programs = list(map(_PROGRAM, states))
            self._globals_watched = any(
                self._can_have_watched(p) for p in {id(p): p for p in programs}.values())
        if self._globals_watched or not hasattr(states[0], "_labels"):
            current = [state.labels for state in states]
        else:  # no watched global in any program: the world's labels (read only)
            current = list(map(_WORLD_LABELS, states))
        labels = {}
        unlabelled = not any(current)  # no robot has any label (a Kilobot world's usual case)
        for name in self.sim.watch:
            texts = ([""] * len(current) if unlabelled else
                     ["" if (value := c.get(name)) is None else str(value) for c in current])
            last = self._last_texts.get(name)
            if texts != last:
                if last is not None and not first:
                    for i, (before, text) in enumerate(zip(last, texts, strict=True)):
                        if before != text:
                            self._event(step, layout.EVENT_ROLE, i,
                                        f"robot {states[i].robot_id} {name}: {before} -> {text}")
                self._last_texts[name] = texts
                self._label_arrays[name] = np.array(texts, dtype=object)
            labels[name] = self._label_arrays[name]
        return labels

    def _failed_boots(self, step: int) -> None:
        """Robots whose boot ended in a failure (no hook said it ended well): keyframed now,
        their state no longer changes."""
        booting = self.recordable.booting
        for state in self.sim.robots:
            if state.robot is not None and state.robot in booting:
                booting.remove(state.robot)
                self._rebooted(state.index, step)
        booting.clear()  # built for another swarm, or replaced already

    def _link_indexes(self, links: list[tuple[int, int]]) -> np.ndarray:
        """The engine's (sender id, receiver id) links as an (M, 2) array of robot indexes:
        the ids flattened in C, then mapped through a lookup array (hundreds of links a step
        in a 25-drone swarm; a dict look-up per id was a tenth of the recorder's time)."""
        ids = np.fromiter(chain.from_iterable(links), dtype=np.int64, count=2 * len(links))
        if self._index_by_id is not None:
            return self._index_by_id[ids].reshape(-1, 2)
        index_of = self._index_of
        return np.array([index_of[i] for i in ids.tolist()], dtype=np.int32).reshape(-1, 2)

    def _can_have_watched(self, program: Any) -> bool:
        """Whether robots running `program` can have a watched global. Reading the labels
        makes the engine look each watched name up in the VM's globals (0.6 ms for a 60 KB
        M300 heap); when the program's string table lacks every watched name, no such global
        can exist and the world's own labels (`set_label`) are all there is."""
        key = id(program)
        can_have = self._watch_in_program.get(key)
        if can_have is None:
            strings = set(getattr(_bbo(program), "strings", []) or [])
            can_have = any(name in strings for name in self.sim.watch)
            self._watch_in_program[key] = can_have
        return can_have

    def _record_overlays(self, step: int, due: bool | None = None) -> None:
        if due is None:
            due = step >= self._overlays_due
        if due:  # unchanged since the last look: look half as often (see OVERLAY_EVERY_MAX)
            self._overlay_every = min(2 * self._overlay_every, OVERLAY_EVERY_MAX)
            self._overlays_due = step + self._overlay_every
        if not due:  # a poll for a found target: cheap when the world can count them itself
            count = getattr(self.sim.world, "targets_found", None)  # a world of the World ABC
            found = count() if count is not None else None
            if found is not None and found <= self._targets_found:
                return
        overlays = self.sim.world.overlays()
        if not overlays:
            return
        targets = overlays.get("targets")
        # Polled every step while a target may still be found (none are lost again).
        self._has_targets = (isinstance(targets, list)
                             and found_targets(overlays) < len(targets))
        if not due and found_targets(overlays) <= self._targets_found:
            return  # a poll between two recordings: only "target found" matters now
        # The JSON of the overlays only when they changed: turning a Kilobot's 32 x 32 light
        # raster into JSON text is ~0.3 ms, comparing its bytes a few us.
        fingerprint = _fingerprint(overlays)
        if fingerprint == self._overlay_fingerprint:
            return
        self._overlay_fingerprint = fingerprint
        self._overlay_every = OVERLAY_EVERY  # changing: look every OVERLAY_EVERY steps again
        self._overlays_due = step + OVERLAY_EVERY
        text = json.dumps(_jsonable(overlays))
        if text == self._last_overlays:
            return
        self._last_overlays = text
        self._overlay_rows.append((step, text, _target_points(overlays)))
        found = found_targets(overlays)
        if found > self._targets_found:
            self._event(step, layout.EVENT_TARGET, -1, f"target found ({found} so far)")
        self._targets_found = max(self._targets_found, found)

    # ---- columns --------------------------------------------------------------------------------
    def _flush(self) -> None:
        if not self._steps:
            if self._keyframe_rows or self._event_rows or self._overlay_rows:
                self._send_rare_rows()  # e.g. the last step's overlays, looked at by close()
                self.rec.flush()
            return
        rr = self.rr
        import pyarrow as pa

        steps = np.array(self._steps, dtype=np.int64)
        rows = len(steps)
        n = self.count
        indexes = self._time_columns(steps)
        b = self._window
        self._window = _Window(n, min(self.flush_every, WINDOW_ROWS))  # (Rerun may keep b's)
        per_robot = [n] * rows
        positions = b.positions[:rows].reshape(-1, 3)
        headings = b.headings[:rows].reshape(-1)
        colors = (np.clip(b.leds[:rows].reshape(-1, 3), 0, 1) * 255).astype(np.uint8)
        radius = float(self.sim.world.robot_radius)
        watch = list(b.labels[0])
        send = self.rec.send_columns
        # The keyframes and events first: a writer killed mid-flush then leaves the flush's
        # per-step rows only with them (a step whose reload keyframe is lost would rebuild
        # with the old program), so the reader's last complete step is complete in both.
        self._send_rare_rows()
        self._send_viewer_labels(steps, b.labels, radius)
        # Arrow arrays, not numpy: rerun turns a 1-D numpy column into a Python list of
        # one-element lists (a third of the flush time of a 25-drone recording).
        extra = {"heading": pa.array(headings),
                 "failed": pa.array(b.failed[:rows].reshape(-1))}
        for name in watch:  # (the label arrays are object arrays, often the same one)
            extra[f"label:{name}"] = pa.array(
                np.concatenate([labels[name] for labels in b.labels]), type=pa.string())
        # The points and the other per-robot values in one chunk (one send each was twice
        # Rerun's per-call work for the same rows)
        send(layout.ROBOTS, indexes=indexes, columns=[
            *self._points(positions, colors, np.full(rows, n)),
            *rr.AnyValues.columns(**extra).partition(per_robot)])
        # The viewer's arrows, at every VIEWER_ARROWS_EVERY-th step
        links = b.links
        link_counts = [len(x) for x in links]
        sampled = [r for r in range(rows) if steps[r] % VIEWER_ARROWS_EVERY == 0]
        if sampled:
            sampled_indexes = self._time_columns(steps[sampled])
            angles = b.headings[sampled].reshape(-1)
            reach = radius * 2.5
            vectors = np.stack([np.cos(angles), np.sin(angles), np.zeros_like(angles)], 1)
            send(layout.HEADINGS, indexes=sampled_indexes, columns=self._arrows(
                b.positions[sampled].reshape(-1, 3), (vectors * reach).astype(np.float32),
                np.full(len(sampled), n)))
            linked = [r for r in sampled if link_counts[r]]
            if linked:  # both ends of every link of those steps, in one gather
                counts = [link_counts[r] for r in linked]
                ends = b.positions[np.repeat(linked, counts)[:, None],
                                   np.concatenate([links[r] for r in linked])]
                if len(linked) < len(sampled):
                    sampled_indexes = self._time_columns(steps[linked])
                send(layout.LINKS, indexes=sampled_indexes,
                     columns=self._arrows(ends[:, 0], ends[:, 1] - ends[:, 0], counts))
        flat_pairs = (np.concatenate([p.reshape(-1) for p in links]) if links
                      else np.zeros(0, np.uint16)).astype(np.uint16)
        send(layout.LINKS, indexes=indexes, columns=rr.AnyValues.columns(
            pairs=pa.array(flat_pairs, type=pa.uint16())).partition([2 * c for c in link_counts]))
        traffic = np.array(b.traffic)  # rows, (sent, received, dropped, bytes_sent), n
        send(layout.MESSAGES, indexes=indexes, columns=rr.AnyValues.columns(
            sent=pa.array(traffic[:, 0].reshape(-1).astype(np.int32)),
            received=pa.array(traffic[:, 1].reshape(-1).astype(np.int32)),
            bytes_sent=pa.array(traffic[:, 3].reshape(-1).astype(np.int32))).partition(per_robot))
        totals = traffic.sum(axis=2).astype(np.float64)  # rows, 4: the same four, summed
        send(layout.MESSAGE_TOTALS, indexes=indexes,
             columns=self._scalars(totals.reshape(-1), np.full(rows, 4)))
        rop, lsp, peak, gc_runs = np.array(b.heap, dtype=np.int64).reshape(
            rows, n, _HEAP_FIGURE_COUNT).transpose(2, 0, 1)  # each: rows, n
        size = np.array(b.heap_sizes)
        has_vm = np.array(b.has_vm)
        used = (rop + size - lsp) * has_vm
        lengths = np.full(rows, n)
        for figure, values in zip(layout.HEAP_FIGURES, (used, size - used, peak, rop, lsp,
                                                        gc_runs), strict=True):
            send(f"{layout.HEAP}/{figure}", indexes=indexes,
                 columns=self._scalars(values.reshape(-1).astype(np.float64), lengths))
        self._send_inputs(steps, indexes, b.inputs)
        self._steps = []
        self.rec.flush()
        self._last_flush = time.monotonic()

    def _send_inputs(self, steps: np.ndarray, indexes: list[Any],
                     buffered: list[tuple[Any, ...] | None]) -> None:
        """The buffered steps' inputs as `input_log` bytes (b"" for the recording's first
        step), laid out as `layout.FORMAT_VERSION` says. Format 4: the steps' bytes back to
        back (`encode_steps_joined`), zstd-compressed as one frame and sent as one row at the
        flush's first step, with the steps and where each one's bytes end (one zstd call per
        step was ~13 us of a Kilobot step, a call's fixed cost; left uncompressed, the ~650 KB
        a flush cost Rerun's writer thread ~14 us a step to compress, against ~5 us for zstd
        here and ~4 for the writer). Formats 2-3 (written only by tests, to check that they
        still read): one zstd frame per step, one row each."""
        rr = self.rr
        import pyarrow as pa

        kept = [parts for parts in buffered if parts is not None]
        version = layout.FORMAT_VERSION
        compress = self._inputs_compressor.compress
        if not layout.inputs_per_flush(version):
            encoded = iter(encode_steps(*zip(*kept, strict=True),
                                        layout=layout.input_layout(version)) if kept else [])
            blobs = pa.array([b"" if parts is None else compress(next(encoded))
                              for parts in buffered], type=pa.binary())
            self.rec.send_columns(layout.INPUTS, indexes=indexes, columns=rr.AnyValues.columns(
                inputs=blobs).partition([1] * len(buffered)))
            return
        data, ends = (encode_steps_joined(*zip(*kept, strict=True),
                                          layout=layout.input_layout(version))
                      if kept else (b"", []))
        if len(kept) < len(buffered):  # the recording's first step has no inputs
            kept_ends = iter(ends)
            end = 0
            ends = []
            for parts in buffered:
                if parts is not None:
                    end = next(kept_ends)
                ends.append(end)
        self.rec.send_columns(layout.INPUTS, indexes=self._time_columns([int(steps[0])]),
                              columns=[
            *rr.AnyValues.columns(inputs=pa.array([compress(data)], type=pa.binary())
                                  ).partition([1]),
            *rr.AnyValues.columns(input_steps=pa.array(steps, type=pa.int64()),
                                  input_ends=pa.array(ends, type=pa.int64())
                                  ).partition([len(buffered)])])

    def _send_viewer_labels(self, steps: np.ndarray, labels: list[dict[str, np.ndarray]],
                            radius: float) -> None:
        """The Rerun viewer's point labels ("id role") and radii, only at the steps where they
        change: the viewer shows a component's latest value, and a label per robot and step
        was ~20 % of a flush (the radii never change)."""
        n = self.count
        ids = [str(s.robot_id) for s in self.sim.robots]
        first = next(iter(labels[0]), None)
        rows: list[int] = []
        texts: list[str] = []
        previous = None
        for row, step_labels in enumerate(labels):
            if first:
                if step_labels[first] is previous:
                    continue  # the same array as the step before: nothing changed
                previous = step_labels[first]
            current = ([f"{ids[i]} {step_labels[first][i]}".rstrip() for i in range(n)]
                       if first else ids)
            if current != self._viewer_labels:
                self._viewer_labels = current
                rows.append(row)
                texts.extend(current)
        if not rows:
            return
        columns: dict[str, Any] = {"labels": texts}
        if not self._radii_sent:  # once, with the first labels: at the recording's first step
            self._radii_sent = True
            columns["radii"] = np.full(len(texts), radius, np.float32)
        self.rec.send_columns(layout.ROBOTS, indexes=self._time_columns(steps[rows].tolist()),
                              columns=self.rr.Points3D.columns(**columns).partition(
                                  [n] * len(rows)))

    # The per-step archetypes' columns are built from their components (the same Arrow
    # columns and descriptors as `Archetype.columns(...).partition(...)`): the archetypes'
    # machinery cost ~0.1-0.2 ms more per column and flush, and sending its Scalars ~0.08 ms
    # more (about 12 such columns a flush).
    def _scalars(self, values: np.ndarray, lengths: Any) -> list[Any]:
        """`Scalars` `values` (float64) as a column of batches of `lengths`."""
        rr = self.rr
        return [rr.ComponentColumn(rr.Scalars.descriptor_scalars(),
                                   rr.components.ScalarBatch(values), lengths=lengths)]

    def _points(self, positions: np.ndarray, colors: np.ndarray, lengths: Any) -> list[Any]:
        """`Points3D` positions and colours (RGB u8) as columns of batches of `lengths`."""
        rr = self.rr
        return [rr.ComponentColumn(rr.Points3D.descriptor_positions(),
                                   rr.components.Position3DBatch(positions), lengths=lengths),
                rr.ComponentColumn(rr.Points3D.descriptor_colors(),
                                   rr.components.ColorBatch(colors), lengths=lengths)]

    def _arrows(self, origins: np.ndarray, vectors: np.ndarray, lengths: Any) -> list[Any]:
        """`Arrows3D` from `origins` along `vectors` as columns of batches of `lengths`."""
        rr = self.rr
        return [rr.ComponentColumn(rr.Arrows3D.descriptor_origins(),
                                   rr.components.Position3DBatch(origins), lengths=lengths),
                rr.ComponentColumn(rr.Arrows3D.descriptor_vectors(),
                                   rr.components.Vector3DBatch(vectors), lengths=lengths)]

    def _time_columns(self, steps: list[int] | np.ndarray) -> list[Any]:
        """The step and time index columns of rows at `steps`."""
        at = np.array(steps, dtype=np.int64)
        dt = float(self.sim.world.step_seconds)
        return [self.rr.TimeColumn(layout.TIMELINE, sequence=at),
                self.rr.TimeColumn(layout.TIME_SECONDS, duration=at * dt)]

    def _send_rare_rows(self) -> None:
        """Keyframes, events and overlays since the last flush, one chunk per entity."""
        rr, send = self.rr, self.rec.send_columns
        import pyarrow as pa

        rows = self._keyframe_rows
        if rows:
            sizes = [len(row[1]) for row in rows]
            send(layout.KEYFRAMES, indexes=self._time_columns([row[0] for row in rows]),
                 columns=rr.AnyValues.columns(
                     robots=pa.array([i for row in rows for i in row[1]], type=pa.int32()),
                     snapshots=pa.array([b for row in rows for b in row[2]], type=pa.binary()),
                     programs=pa.array([p for row in rows for p in row[3]], type=pa.int32()),
                     bases=pa.array([b for row in rows for b in row[4]], type=pa.int32()),
                 ).partition(sizes))
        events = self._event_rows
        if events:
            indexes = self._time_columns([e[0] for e in events])
            ones = [1] * len(events)
            send(layout.EVENTS, indexes=indexes, columns=rr.TextLog.columns(
                text=[e[3] for e in events],
                level=["ERROR" if e[1] == layout.EVENT_ERROR else "INFO" for e in events],
            ).partition(ones))
            send(layout.EVENTS, indexes=indexes, columns=rr.AnyValues.columns(
                kind=pa.array([e[1] for e in events], type=pa.string()),
                robot=pa.array([e[2] for e in events], type=pa.int64())).partition(ones))
        overlays = self._overlay_rows
        if overlays:
            send(layout.OVERLAYS, indexes=self._time_columns([o[0] for o in overlays]),
                 columns=rr.AnyValues.columns(
                     overlays=pa.array([o[1] for o in overlays], type=pa.string()),
                 ).partition([1] * len(overlays)))
            targets = [o for o in overlays if o[2] is not None]
            if targets:
                points = np.concatenate([o[2] for o in targets])
                send(layout.TARGETS, indexes=self._time_columns([o[0] for o in targets]),
                     columns=rr.Points3D.columns(
                         positions=points, radii=np.full(len(points), 0.02, np.float32),
                         colors=np.tile(np.array([230, 60, 60, 255], np.uint8),
                                        (len(points), 1)),
                     ).partition([len(o[2]) for o in targets]))
        self._keyframe_rows, self._event_rows, self._overlay_rows = [], [], []

    def close(self) -> None:
        """Send what is buffered, write the file's footer, stop capturing."""
        if self.closed:
            return
        if self._last_step > self.start_step:  # the last step's overlays, whatever the interval
            self._record_overlays(self._last_step, due=True)
        self._flush()
        self.closed = True
        self.recordable.listener = None
        self._capture.stop()
        self.rec.flush()
        self.rec.disconnect()

    def __enter__(self) -> MissionRecorder:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def _bbo(program: Any) -> Any:
    return program.to_bbo() if hasattr(program, "to_bbo") and not hasattr(program, "bbo") \
        else program


def _failure_text(failure: Any) -> str:
    reason = getattr(failure, "reason", str(failure))
    where = getattr(failure, "location", None)
    message = getattr(failure, "message", "")
    text = str(reason)
    if where is not None:
        text += f" at {where}"
    if message:
        text += f": {message}"
    return text
