"""Capture and replay of everything that enters a robot's VM from outside, for exact time travel.

Design: a BittyBuzz robot is a deterministic machine once its inputs are fixed. Its firmware
loop (`bbzide.vm.robot.Robot`) takes input from the world through exactly two doors:

* `receive(message, distance, azimuth, elevation)`: one wire message with its situated data
  (`receive_all(deliveries)`: the same for a step's messages, each noted the same way);
* the world's host functions (C closures such as `rand`, `light`, `led`), which read the
  world and act on the VM only through their `HostCall`: `expect_args(n)` (may raise LNUM),
  `ret(value)` and `fail(kind)`.

The library closures the VM registers itself (neighbors, vstig, swarm, table functions) are
pure functions of the VM state. So the VM state after a control step is a function of the state
before it and of those inputs. `CapturingRobot` wraps a Robot (the engine builds it through its
`robot_factory` hook, so neither the VM nor the worlds change) and writes, per control step, the
received messages and each host call's effects on the VM into a `StepInputs`. `replay_step`
applies a `StepInputs` to a robot restored from a snapshot: the same `receive` calls, then
`control_step` with host functions that repeat the recorded effects instead of asking the
world. Replaying a host function also checks that the script calls the same function it
called when recorded, so a diverging replay is an error, never a silently wrong state.

`encode_step` / `decode_step` turn the inputs of every robot for one step into bytes with a
fixed little-endian layout (no pickle: a recording is a file a user may get from anywhere).
"""

from __future__ import annotations

import struct
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

#: One host-call effect: ("expect", n) | ("ret", value) | ("fail", kind) | ("ret0",).
HostEffect = tuple[Any, ...]


@dataclass
class HostCallRecord:
    """One call of a world host function: its name and its effects on the VM, in order."""

    name: str
    effects: list[HostEffect] = field(default_factory=list)


@dataclass
class StepInputs:
    """What entered one robot during one control step of the engine."""

    received: list[tuple[bytes, float, float, float]] = field(default_factory=list)
    stepped: bool = False  # control_step() ran (False: asleep, failed, or passive)
    host_calls: list[HostCallRecord] = field(default_factory=list)

    @property
    def empty(self) -> bool:
        return not self.received and not self.stepped


class ReplayDivergence(Exception):
    """A replayed robot asked for other inputs than the recorded robot did (a bug, not user
    input): the recording cannot rebuild this state exactly."""


class _CapturingCall:
    """A `HostCall` stand-in that forwards everything and notes the calls that touch the VM."""

    __slots__ = ("_call", "_record")

    def __init__(self, call: Any, record: HostCallRecord) -> None:
        self._call = call
        self._record = record

    def expect_args(self, n: int) -> bool:
        self._record.effects.append(("expect", int(n)))
        return self._call.expect_args(n)

    def ret(self, value: Any = None) -> None:
        self._record.effects.append(("ret", value))
        self._call.ret(value)

    def fail(self, kind: str) -> None:
        self._record.effects.append(("fail", str(kind)))
        self._call.fail(kind)

    def __getattr__(self, name: str) -> Any:  # arg, args, arg_count, robot_id, vm, ...
        return getattr(self._call, name)


class HostCallTap:
    """Wraps a robot's world host functions; while `log` is a list, each call is noted in it."""

    def __init__(self) -> None:
        self.log: list[HostCallRecord] | None = None

    def wrap(self, name: str, function: Callable[[Any], None]) -> Callable[[Any], None]:
        def tapped(call: Any) -> None:
            log = self.log
            if log is None:
                function(call)
                return
            record = HostCallRecord(name)
            log.append(record)
            function(_CapturingCall(call, record))

        return tapped


class CapturingRobot:
    """A firmware loop that notes its inputs while `capturing` (otherwise a thin pass-through).

    `on_boot(robot)` is called after every boot, so a recorder can keyframe the fresh state.
    """

    def __init__(self, robot: Any, tap: HostCallTap,
                 on_boot: Callable[[CapturingRobot], None] | None = None) -> None:
        self.robot = robot
        self.tap = tap
        self.capturing = False
        self.current = StepInputs()
        self._on_boot = on_boot
        #: Seconds spent in captured control steps (the recorder keyframes by this budget).
        self.busy_seconds = 0.0
        #: The payloads the last control step sent (the inspector reads them: the out-queue is
        #: drained at the end of every step).
        self.last_sent: list[bytes] = []

    # the engine's FirmwareLoop protocol ---------------------------------------------------------
    def boot(self) -> None:
        self.tap.log = None
        self.robot.boot()
        self.current = StepInputs()
        if self._on_boot is not None:
            self._on_boot(self)

    def receive(self, message: bytes, distance: float, azimuth: float, elevation: float) -> None:
        if self.capturing:
            self.current.received.append(
                (bytes(message), float(distance), float(azimuth), float(elevation)))
        self.robot.receive(message, distance, azimuth, elevation)

    def receive_all(self, deliveries: Sequence[tuple[Any, bytes, float, float, float]]
                    ) -> None:
        """``receive`` of each ``(sender, message, distance, azimuth, elevation)``, noted one
        by one (the engine calls this when present; without it ``__getattr__`` would hand
        the engine the robot's own ``receive_all`` and the messages would go unrecorded)."""
        if self.capturing:
            self.current.received.extend(
                (bytes(message), float(distance), float(azimuth), float(elevation))
                for _sender, message, distance, azimuth, elevation in deliveries)
        receive_all = getattr(self.robot, "receive_all", None)
        if receive_all is not None:
            receive_all(deliveries)
            return
        for _sender, message, distance, azimuth, elevation in deliveries:
            self.robot.receive(message, distance, azimuth, elevation)

    def control_step(self) -> list[bytes]:
        if not self.capturing:
            self.last_sent = self.robot.control_step()
            return self.last_sent
        self.current.stepped = True
        self.tap.log = self.current.host_calls
        started = time.perf_counter()
        try:
            self.last_sent = self.robot.control_step()
            return self.last_sent
        finally:
            self.tap.log = None
            self.busy_seconds += time.perf_counter() - started

    def take_inputs(self) -> StepInputs:
        """The inputs since the last call (one engine step), and start a new record."""
        inputs, self.current = self.current, StepInputs()
        return inputs

    @property
    def failure(self) -> Any:
        return self.robot.failure

    def __getattr__(self, name: str) -> Any:  # vm, robot_id, snapshot, restore, ...
        return getattr(self.robot, name)


#: The engine's robot factory: (program, profile, robot_id, host functions) -> firmware loop.
Factory = Callable[[Any, Any, int, Mapping[str, Callable[[Any], None]]], Any]


def capturing_factory(
    build: Factory,
    on_created: Callable[[CapturingRobot], None] = lambda robot: None,
    on_boot: Callable[[CapturingRobot], None] | None = None,
) -> Factory:
    """A robot factory that builds robots with `build` and wraps them in `CapturingRobot`s."""

    def factory(program: Any, profile: Any, robot_id: int,
                host_functions: Mapping[str, Callable[[Any], None]]) -> CapturingRobot:
        tap = HostCallTap()
        tapped = {name: tap.wrap(name, fn) for name, fn in host_functions.items()}
        robot = CapturingRobot(build(program, profile, robot_id, tapped), tap, on_boot)
        on_created(robot)
        return robot

    return factory


# ---- replay ------------------------------------------------------------------------------------
class ReplayHostFunctions:
    """Host functions for a rebuilt robot: each call repeats the next recorded call's effects.

    Before `load` (e.g. while the rebuilt robot boots, before its snapshot is restored) a call
    only returns 0 (its effects are overwritten by the restore).
    """

    def __init__(self, names: Sequence[str]) -> None:
        self.names = list(names)
        self._pending: list[HostCallRecord] | None = None

    def load(self, calls: list[HostCallRecord]) -> None:
        self._pending = list(reversed(calls))

    def leftover(self) -> int:
        return len(self._pending or [])

    def functions(self) -> dict[str, Callable[[Any], None]]:
        return {name: self._replayer(name) for name in self.names}

    def _replayer(self, name: str) -> Callable[[Any], None]:
        def replay(call: Any) -> None:
            pending = self._pending
            if pending is None:
                call.ret(0)
                return
            if not pending:
                raise ReplayDivergence(f"the replayed script called {name}() once more than "
                                       "the recorded one")
            record = pending.pop()
            if record.name != name:
                raise ReplayDivergence(
                    f"the replayed script called {name}() where the recorded one called "
                    f"{record.name}()")
            for effect in record.effects:
                kind = effect[0]
                if kind == "expect":
                    if not call.expect_args(effect[1]):
                        return
                elif kind == "ret":
                    call.ret(effect[1])
                elif kind == "fail":
                    call.fail(effect[1])

        return replay


def replay_step(robot: Any, inputs: StepInputs, host: ReplayHostFunctions) -> None:
    """Apply one recorded control step to `robot` (restored to the state before that step)."""
    for message, distance, azimuth, elevation in inputs.received:
        robot.receive(message, distance, azimuth, elevation)
    if inputs.stepped:
        host.load(inputs.host_calls)
        try:
            robot.control_step()
        finally:
            left = host.leftover()
            host._pending = None
        if left:
            raise ReplayDivergence(f"the replayed step made {left} host call(s) fewer than "
                                   "the recorded one")


# ---- bytes -------------------------------------------------------------------------------------
# Layout of one step (all little-endian):
#   u16 robot records
#   per record: u16 robot index, u8 flags (1 = stepped), u16 messages, u16 host calls
#     message: u16 length, bytes, u8 which (1 = azimuth, 2 = elevation follow), f64 distance,
#              [f64 azimuth], [f64 elevation]   (a Kilobot has no bearing: both are 0.0)
#     host call: u8 name length, name (UTF-8), u8 effects
#       effect: b"E" u8 n | b"F" u8 length, kind | b"R" value
#       value:  b"N" | b"I" i64 | b"D" f64 | b"T" u8 entries, (u8 length, key, value)*
_U16 = struct.Struct("<H")
_HEAD = struct.Struct("<HBHH")
_I64 = struct.Struct("<q")
_F64 = struct.Struct("<d")


#: One received message in one `pack` call (the same bytes as the layout above), by (payload
#: length, which): an M300 swarm receives hundreds of messages a step, and three packs and
#: four concatenations each were most of the encoding time.
_MESSAGE_LAYOUTS: dict[tuple[int, int], struct.Struct] = {}


def _message_layout(length: int, which: int) -> struct.Struct:
    extra = "d" * (bin(which).count("1"))
    layout = _MESSAGE_LAYOUTS[(length, which)] = struct.Struct(f"<H{length}sBd{extra}")
    return layout


class InputLogError(ValueError):
    """Bytes that are not an input log (a corrupt recording)."""


def _encode_value(value: Any, out: bytearray) -> None:
    if value is None:
        out += b"N"
    elif isinstance(value, bool | int):
        out += b"I" + _I64.pack(int(value))
    elif isinstance(value, float):
        out += b"D" + _F64.pack(value)
    elif isinstance(value, dict):
        out += b"T" + bytes([len(value)])
        for key, item in value.items():
            name = str(key).encode()
            out += bytes([len(name)]) + name
            _encode_value(item, out)
    else:
        out += b"N"  # HostCall.ret turns anything else into nil too


def encode_step(records: Sequence[tuple[int, StepInputs]]) -> bytes:
    """The inputs of the robots of one step (robots with none may be left out)."""
    out = bytearray(_U16.pack(len(records)))
    for index, inputs in records:
        out += _HEAD.pack(index, 1 if inputs.stepped else 0, len(inputs.received),
                          len(inputs.host_calls))
        for message, distance, azimuth, elevation in inputs.received:
            which = (1 if azimuth != 0.0 else 0) | (2 if elevation != 0.0 else 0)
            layout = _MESSAGE_LAYOUTS.get((len(message), which)) or _message_layout(
                len(message), which)
            if which == 0:
                out += layout.pack(len(message), message, which, distance)
            elif which == 1:
                out += layout.pack(len(message), message, which, distance, azimuth)
            elif which == 2:
                out += layout.pack(len(message), message, which, distance, elevation)
            else:
                out += layout.pack(len(message), message, which, distance, azimuth, elevation)
        for call in inputs.host_calls:
            name = call.name.encode()
            out += bytes([len(name)]) + name + bytes([len(call.effects)])
            for effect in call.effects:
                if effect[0] == "expect":
                    out += b"E" + bytes([effect[1] & 0xFF])
                elif effect[0] == "fail":
                    kind = effect[1].encode()
                    out += b"F" + bytes([len(kind)]) + kind
                else:
                    out += b"R"
                    _encode_value(effect[1], out)
    return bytes(out)


class _Reader:
    __slots__ = ("data", "at")

    def __init__(self, data: bytes) -> None:
        self.data = data
        self.at = 0

    def take(self, n: int) -> bytes:
        end = self.at + n
        if end > len(self.data):
            raise InputLogError("input log ends in the middle of a record")
        chunk = self.data[self.at:end]
        self.at = end
        return chunk

    def unpack(self, layout: struct.Struct) -> tuple[Any, ...]:
        return layout.unpack(self.take(layout.size))

    def byte(self) -> int:
        return self.take(1)[0]

    def value(self) -> Any:
        tag = self.take(1)
        if tag == b"N":
            return None
        if tag == b"I":
            return self.unpack(_I64)[0]
        if tag == b"D":
            return self.unpack(_F64)[0]
        if tag == b"T":
            return {self.take(self.byte()).decode(): self.value() for _ in range(self.byte())}
        raise InputLogError(f"unknown value tag {tag!r} in input log")


def _skip_value(data: bytes, at: int) -> int:
    """The offset after the value at `at` (index arithmetic only: nothing is built)."""
    tag = data[at]
    if tag == 0x49 or tag == 0x44:  # b"I", b"D"
        return at + 9
    if tag == 0x54:  # b"T"
        at += 2
        for _ in range(data[at - 1]):
            at = _skip_value(data, at + 1 + data[at])
        return at
    if tag != 0x4E:  # b"N"
        raise InputLogError(f"unknown value tag {bytes([tag])!r} in input log")
    return at + 1


def _skip_record(reader: _Reader, messages: int, calls: int) -> None:
    """Step over one robot's record without building it (a seek needs one robot of 25)."""
    data, at = reader.data, reader.at
    try:
        for _ in range(messages):
            length = data[at] | data[at + 1] << 8
            which = data[at + 2 + length]
            at += 3 + length + 8 * (1 + (which & 1) + (which >> 1 & 1))
        for _ in range(calls):
            at += 1 + data[at]
            effects = data[at]
            at += 1
            for _ in range(effects):
                tag = data[at]
                if tag == 0x45:  # b"E"
                    at += 2
                elif tag == 0x46:  # b"F"
                    at += 2 + data[at + 1]
                elif tag == 0x52:  # b"R"
                    at = _skip_value(data, at + 1)
                else:
                    raise InputLogError(f"unknown host effect {bytes([tag])!r} in input log")
    except IndexError:
        raise InputLogError("input log ends in the middle of a record") from None
    if at > len(data):
        raise InputLogError("input log ends in the middle of a record")
    reader.at = at


def decode_step(data: bytes, only: int | None = None) -> dict[int, StepInputs]:
    """`encode_step`'s bytes back: robot index -> its inputs (with `only`, just that robot's:
    the other records are stepped over, not built)."""
    reader = _Reader(data)
    result: dict[int, StepInputs] = {}
    for _ in range(reader.unpack(_U16)[0]):
        index, flags, messages, calls = reader.unpack(_HEAD)
        if only is not None and index != only:
            _skip_record(reader, messages, calls)
            continue
        inputs = StepInputs(stepped=bool(flags & 1))
        for _ in range(messages):
            message = reader.take(reader.unpack(_U16)[0])
            which = reader.byte()
            distance = reader.unpack(_F64)[0]
            azimuth = reader.unpack(_F64)[0] if which & 1 else 0.0
            elevation = reader.unpack(_F64)[0] if which & 2 else 0.0
            inputs.received.append((message, distance, azimuth, elevation))
        for _ in range(calls):
            try:
                record = HostCallRecord(reader.take(reader.byte()).decode())
            except UnicodeDecodeError:
                raise InputLogError("host function name is not UTF-8") from None
            for _ in range(reader.byte()):
                tag = reader.take(1)
                if tag == b"E":
                    record.effects.append(("expect", reader.byte()))
                elif tag == b"F":
                    record.effects.append(("fail", reader.take(reader.byte()).decode()))
                elif tag == b"R":
                    record.effects.append(("ret", reader.value()))
                else:
                    raise InputLogError(f"unknown host effect {tag!r} in input log")
            inputs.host_calls.append(record)
        result[index] = inputs
    if reader.at != len(data):
        raise InputLogError(f"{len(data) - reader.at} stray bytes after the input log")
    return result
