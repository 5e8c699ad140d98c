"""Rebuilds one robot's exact VM at any recorded step: keyframe + recorded inputs re-executed.

Design: `robot_at(index, step)` takes the robot's last keyframe at or before `step` (a
`Robot.snapshot()`), builds a fresh `Robot` for the keyframe's program whose world host
functions are `ReplayHostFunctions` (they repeat the recorded effects instead of reading a
world), restores the snapshot and re-executes the recorded inputs of the steps after it
(`input_log.replay_step`). The VM is deterministic given those inputs, so the result is the
live robot's state byte for byte (tests/recording compare snapshots at random steps).

Stepping forward one step at a time (the replay's play button with a robot selected) reuses
the last rebuilt robot when no newer keyframe lies in between, so each frame re-executes one
step, not up to `keyframe_every`. The rebuilt Robot of each robot is booted once and then only
restored: a returned robot is valid until the next `robot_at` call for the same index.
"""

from __future__ import annotations

import base64
import bisect
import io
import pickle
from collections.abc import Callable
from typing import Any

from bbzide.diagnostics import SourceLocation
from bbzide.recording import keyframes, layout
from bbzide.recording.compression import CompressionError, decompress
from bbzide.recording.input_log import (
    InputLogError,
    ReplayDivergence,
    ReplayHostFunctions,
    decode_step,
    replay_step,
)
from bbzide.recording.reader import Keyframe, Recording
from bbzide.recording.recorder import RecordingError, build_robot
from bbzide.vm.snapshot_layout import (
    ROBOT_MAGIC,
    VM_MAGICS,
    SnapshotError,
    decode_robot,
    decode_vm,
)

#: (program, profile, robot_id, host_functions) -> a firmware loop (default: bbzide's Robot).
Builder = Callable[[Any, Any, int, Any], Any]


def program_from_record(record: dict[str, Any]) -> Any:
    from bbzide.compiler.program import BittyBuzzProgram

    debug = {int(pc): SourceLocation(loc[0], int(loc[1]), int(loc[2]))
             for pc, loc in record.get("debug_map", {}).items()}
    return BittyBuzzProgram(base64.b64decode(record["bbo"]), list(record["strings"]), debug)


#: What a VM snapshot pickle may name besides the VM room's own classes (`bbzide.vm.*`).
_SAFE_GLOBALS = {("builtins", "set"), ("builtins", "frozenset"), ("builtins", "bytearray"),
                 ("builtins", "complex"), ("collections", "deque"),
                 ("collections", "OrderedDict"), ("copyreg", "_reconstructor"),
                 ("builtins", "object"), ("bbzide.diagnostics", "SourceLocation")}
#: Nested pickles are checked too, down to this depth (a snapshot of a snapshot at most).
_NESTED_PICKLES = 4


class _SnapshotUnpickler(pickle.Unpickler):
    def find_class(self, module: str, name: str) -> Any:
        if module.startswith("bbzide.vm.") or (module, name) in _SAFE_GLOBALS:
            return super().find_class(module, name)
        raise pickle.UnpicklingError(f"it names {module}.{name}")


def check_snapshot(snapshot: bytes, what: str, depth: int = 0) -> None:
    """Refuse a pickled snapshot that names anything but VM-room classes and plain containers,
    and a flat one (`snapshot_layout`) that does not decode.

    `Robot.restore` unpickles; a recording is a file from anywhere, and unpickling can run any
    code a crafted file names. This loads it with an allow-list first (nested pickles too).
    """
    if depth == 0 and snapshot.startswith((ROBOT_MAGIC, *VM_MAGICS)):
        # the flat layout holds no pickle; decoding it checks every length
        try:
            if snapshot.startswith(ROBOT_MAGIC):
                decode_robot(snapshot)
            else:
                decode_vm(snapshot)
        except SnapshotError as error:
            raise RecordingError(f"the {what} is damaged ({error})") from None
        return
    # a pickle of protocol 0 or 1 has no 0x80 prefix: not checked here, so `Robot` and `VM`
    # `decode_snapshot` refuse it (every snapshot bbzide writes is flat or a protocol 2+ one)
    if not snapshot.startswith(b"\x80") or depth > _NESTED_PICKLES:
        return
    try:
        loaded = _SnapshotUnpickler(io.BytesIO(snapshot)).load()
    except Exception as error:  # noqa: BLE001 - any failure means "not a VM snapshot"
        raise RecordingError(f"the {what} is not a VM snapshot ({error})") from None
    stack = [loaded]
    while stack:
        item = stack.pop()
        if isinstance(item, bytes | bytearray) and bytes(item[:1]) == b"\x80":
            check_snapshot(bytes(item), what, depth + 1)
        elif isinstance(item, list | tuple | set | frozenset):
            stack.extend(item)
        elif isinstance(item, dict):
            stack.extend(item.values())


#: A Buzz script that makes a VM register every library C closure that scripts create at run
#: time (`stigmergy.create` and `swarm.create` register their methods when first called).
_LIBRARY_PROBE = "s = stigmergy.create(1)\nw = swarm.create(1)\n"
_library_cache: dict[str, dict[str, Any]] = {}


def library_closures(profile: Any) -> dict[str, Any]:
    """symbol -> host function of the BittyBuzz library closures with fixed addresses, taken
    from a probe robot that created one stigmergy and one swarm."""
    found = _library_cache.get(profile.name)
    if found is None:
        from bbzide import compiler
        from bbzide.vm.host import LIBRARY_ADDRESSES
        from bbzide.vm.robot import Robot

        probe = compiler.compile_source(
            _LIBRARY_PROBE, "<library probe>",
            string_table=compiler.bittybuzz_string_table([])).to_bbo()
        robot = Robot(probe, profile, 0)
        robot.boot()
        found = {symbol: entry.function for symbol, entry in robot.vm.host.by_symbol.items()
                 if symbol in LIBRARY_ADDRESSES}
        _library_cache[profile.name] = found
    return found


def _register_library(robot: Any, profile: Any) -> None:
    """`Robot.restore` brings back the heap, whose C closures hold addresses, but not the VM's
    address -> function registry. Closures a script created after boot (its stigmergy's
    `get`/`put`, a swarm's methods) were registered in the live VM when created; the rebuilt
    VM, booted with other host answers, may never have created them. Library closures always
    sit at their fixed addresses, so registering any missing one makes the registry match."""
    from bbzide.vm.host import HostRegistry

    registry = getattr(robot.vm, "host", None)
    if not isinstance(registry, HostRegistry):
        return  # not a BittyBuzz VM (a test double)
    for symbol, function in library_closures(profile).items():
        if symbol not in registry.by_symbol:
            registry.register(symbol, function)


class RobotRebuilder:
    def __init__(self, recording: Recording, build: Builder | None = None) -> None:
        self.recording = recording
        meta = recording.meta
        self._build = build or (lambda program, profile, robot_id, host: build_robot(
            program, profile, robot_id, host, meta.get("loop", "pop"),
            meta.get("instruction_budget")))
        #: how the input blobs are laid out (formats 2-3: full, 4: compact)
        self._input_layout = layout.input_layout(int(meta.get("version", 0)))
        self._inputs_compressed = layout.inputs_compressed(int(meta.get("version", 0)))
        self._programs: dict[int, Any] = {}
        self._cache: dict[int, tuple[int, Any, ReplayHostFunctions, int]] = {}
        self._decoded: dict[tuple[int, int], dict[int, Any]] = {}
        self._booted: dict[tuple[int, int], tuple[Any, ReplayHostFunctions]] = {}
        #: robot index -> (step, the payloads it sent in that step), from the last rebuild
        self._sent: dict[int, tuple[int, list[bytes]]] = {}

    def program(self, program_id: int) -> Any:
        if program_id not in self._programs:
            try:
                record = self.recording.programs[program_id]
            except KeyError:
                raise RecordingError(f"the recording lacks program {program_id}") from None
            self._programs[program_id] = program_from_record(record)
        return self._programs[program_id]

    def keyframe(self, index: int, step: int) -> Keyframe:
        frames = self.recording.keyframes.get(index)
        if not frames:
            raise RecordingError(f"robot #{index} has no VM in this recording (passive body?)")
        at = bisect.bisect_right([k.step for k in frames], step) - 1
        if at < 0:
            raise RecordingError(f"robot #{index} has no keyframe at or before step {step}")
        return frames[at]

    def has_vm(self, index: int) -> bool:
        return bool(self.recording.keyframes.get(index))

    def robot_at(self, index: int, step: int) -> Any:
        """A robot whose VM is exactly robot `index`'s at recorded `step` (do not step it).

        At a keyframe's own step the step is re-executed from the keyframe before when that
        gives the keyframe's bytes, so that what the robot sent in it is known (the inspector's
        warnings read it); where it does not (a reboot, a new program) the keyframe is taken."""
        self.recording.row(step)
        keyframe = self.keyframe(index, step)
        frames = self.recording.keyframes[index]
        if keyframe.step == step and frames[0].step < step:
            earlier = self.keyframe(index, step - 1)
            if earlier.program == keyframe.program:
                try:
                    robot = self._rebuilt_from(index, earlier, step)
                    if robot.snapshot() == self.snapshot(index, keyframe):
                        return robot
                except RecordingError:
                    pass
                self._cache.pop(index, None)
                self._sent.pop(index, None)
        return self._rebuilt_from(index, keyframe, step)

    def _rebuilt_from(self, index: int, keyframe: Keyframe, step: int) -> Any:
        """Robot `index` at `step`: `keyframe` restored (or the cached robot, when it lies
        between them) and the recorded inputs of the steps after it re-executed."""
        cached = self._cache.get(index)
        if cached is not None and keyframe.step <= cached[0] <= step and cached[3] == id(
                keyframe):
            at, robot, host, _ = cached
        else:
            robot, host = self._restore(index, keyframe)
            at = keyframe.step
        try:
            for t in range(at + 1, step + 1):
                inputs = self._inputs(t, index).get(index)
                if inputs is not None:
                    self._sent[index] = (t, replay_step(robot, inputs, host))
        except ReplayDivergence as error:
            self._cache.pop(index, None)
            raise RecordingError(f"robot #{index} cannot be rebuilt at step {step}: {error}"
                                 ) from None
        self._cache[index] = (step, robot, host, id(keyframe))
        return robot

    def scratch_robot(self, index: int, step: int) -> tuple[Any, ReplayHostFunctions]:
        """Robot `index` rebuilt at `step` with its replaying host functions, handed over:
        this rebuilder forgets it (its next rebuild of that robot boots a new one), so the
        caller may run it on (`bbzide.recording.recorded_swarm`)."""
        robot = self.robot_at(index, step)
        _at, cached, host, _keyframe = self._cache.pop(index)
        assert cached is robot
        for key in [key for key, (booted, _host) in self._booted.items() if booted is robot]:
            del self._booted[key]
        self._sent.pop(index, None)
        return robot, host

    def inputs(self, step: int, index: int) -> Any:
        """Robot `index`'s recorded inputs of `step` (`input_log.StepInputs`), None if the
        step holds none for it."""
        return self._inputs(step, index).get(index)

    def sent_at(self, index: int, step: int) -> list[bytes]:
        """The payloads robot `index` sent in recorded `step`, as its last rebuild re-executed
        them (empty when that step was not re-executed: the first keyframe's step, a reboot
        or a new program)."""
        at, sent = self._sent.get(index, (-1, []))
        return sent if at == step else []

    def prepare(self, index: int, step: int) -> None:
        """Boot the robot that rebuilds robot `index` near `step` now (booting runs the
        script's top level and `init`: ~70 ms for an M300 SAR drone), so that its first seek
        only restores and re-executes."""
        keyframe = self.keyframe(index, step)
        if (index, keyframe.program) not in self._booted:
            self._cache.pop(index, None)
            self._restore(index, keyframe)

    def program_at(self, index: int, step: int) -> Any:
        return self.program(self.keyframe(index, step).program)

    def _restore(self, index: int, keyframe: Keyframe) -> tuple[Any, ReplayHostFunctions]:
        """Robot `index` at `keyframe`. One booted Robot per (robot, program) is kept and
        restored again for every seek: booting runs the script's top level and `init` (tens
        of ms for the SAR script), restoring only decodes the snapshot."""
        from bbzide.vm.profiles import PROFILES

        meta = self.recording.meta
        name = meta["profiles"][index]  # one string per robot (reader._check_robots)
        try:
            profile = PROFILES[name]
        except KeyError:
            raise RecordingError(f"unknown platform profile {name!r}") from None
        key = (index, keyframe.program)
        booted = self._booted.get(key)
        if booted is None:
            latched = meta.get("latched")  # format 3; none in format 2
            try:
                host = ReplayHostFunctions(meta["host_names"][index],
                                           dict(latched[index]) if latched else None)
                robot = self._build(self.program(keyframe.program), profile,
                                    int(meta["robot_ids"][index]), host.functions())
            except (KeyError, IndexError, TypeError, ValueError) as error:
                # a crafted recording's metadata or program (the reader checks their shape,
                # not every value: a loop mode, a budget, a host function's name, a program)
                raise RecordingError(f"robot #{index} cannot be rebuilt from this recording's "
                                     f"metadata or program ({error})") from None
            robot.boot()
            booted = self._booted[key] = (robot, host)
        robot, host = booted
        try:
            robot.restore(self.snapshot(index, keyframe))
        except (SnapshotError, TypeError, ValueError, AttributeError, IndexError) as error:
            # e.g. a heap of another profile's size; or a pickled keyframe (formats 2-3)
            # that passed the allow-list but holds another shape than a robot's state
            raise RecordingError(f"robot #{index}: the keyframe at step {keyframe.step} does "
                                 f"not fit its robot ({error})") from None
        _register_library(robot, profile)
        return robot, host

    def snapshot(self, index: int, keyframe: Keyframe) -> bytes:
        """The keyframe's `Robot.snapshot()` bytes (a delta chain is applied from its last full
        keyframe), checked against the allow-list."""
        chain = [keyframe]
        by_step = {k.step: k for k in self.recording.keyframes[index]}
        while chain[-1].base >= 0:
            base = by_step.get(chain[-1].base)
            if (base is None or base.step >= chain[-1].step
                    or len(chain) > 4 * keyframes.FULL_KEYFRAME_EVERY):
                raise RecordingError(f"robot #{index}: the keyframe at step {keyframe.step} "
                                     f"refers to a missing keyframe (step {chain[-1].base})")
            chain.append(base)
        try:
            snapshot = keyframes.decode_full(chain[-1].snapshot)
            for delta in reversed(chain[:-1]):
                snapshot = keyframes.decode_delta(delta.snapshot, snapshot)
        except keyframes.KeyframeError as error:
            raise RecordingError(f"corrupt keyframe of robot #{index} at step "
                                 f"{keyframe.step}: {error}") from None
        check_snapshot(snapshot, f"keyframe of robot #{index} at step {keyframe.step}")
        return snapshot

    def _inputs(self, step: int, index: int) -> dict[int, Any]:
        """Robot `index`'s inputs of `step` (only its record is decoded: an M300 step holds
        25 robots' hundreds of messages, 3 ms to decode whole, ~0.3 ms to step over)."""
        key = (step, index)
        decoded = self._decoded.get(key)
        if decoded is None:
            try:
                blob = self.recording.inputs[self.recording.row(step)]
                if blob and self._inputs_compressed:
                    blob = decompress(blob)
                decoded = decode_step(blob, only=index, layout=self._input_layout) if blob else {}
            except (InputLogError, CompressionError) as error:
                raise RecordingError(f"corrupt inputs at step {step}: {error}") from None
            if len(self._decoded) > 4096:  # a bounded memo: seeks revisit nearby steps
                self._decoded.clear()
            self._decoded[key] = decoded
        return decoded
