"""Capture and replay of everything that enters a robot's VM from outside, for exact time travel.

Design: a BittyBuzz robot is a deterministic machine once its inputs are fixed. Its firmware
loop (`bbzide.vm.robot.Robot`) takes input from the world through exactly two doors:

* `receive(message, distance, azimuth, elevation)` (or `receive_all` of a step's
  deliveries): wire messages with their situated data;
* the world's host functions (C closures such as `rand`, `light`, `led`), which read the
  world and act on the VM only through their `HostCall`: `expect_args(n)` (may raise LNUM),
  `ret(value)` and `fail(kind)`.

The library closures the VM registers itself (neighbors, vstig, swarm, table functions) are
pure functions of the VM state. So the VM state after a control step is a function of the state
before it and of those inputs. `SwarmCapture` notes them for a whole swarm without wrapping
the robots (a wrapped robot would leave an engine's compiled batch of control steps): it taps
the host functions the robot factory passes to each robot, writing each call's effects
straight into the input log's bytes (`CallLog`), and a recorder takes the received messages
from the engine (`Simulation.step_deliveries`), or, for an engine without them, from
receive hooks it puts on the robot instances (`ReceivedColumns`). `replay_step` applies one
robot's recorded `StepInputs` to a robot restored from a snapshot: the same `receive` calls,
then `control_step` with host functions that repeat the recorded effects instead of asking
the world. Replaying a host function also checks that the script calls the same function it
called when recorded, so a diverging replay is an error, never a silently wrong state.

`encode_steps_joined` / `encode_steps` (columns of whole steps, back to back or one bytes object
per step) / `encode_step` (per-robot records, the reference) / `decode_step` turn the inputs of
every robot for one step into bytes with a fixed little-endian layout (no pickle: a recording
is a file a user may get from anywhere), in one of two layouts: `LAYOUT_COMPACT` (recording
format 4 on) or `LAYOUT_FULL` (formats 2 and 3, still read).
"""

from __future__ import annotations

import struct
import sys
from array import array
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from itertools import accumulate, chain, repeat
from typing import Any

import numpy as np

from bbzide.vm.host import HostCall
from bbzide.vm.messages import PAYLOAD_SIZE
from bbzide.vm.swarm_batch import PackedMessages

#: One host-call effect: ("expect", n) | ("ret", value) | ("fail", kind) | ("ret0",).
HostEffect = tuple[Any, ...]


@dataclass(slots=True)
class HostCallRecord:
    """One call of a world host function: its name and its effects on the VM, in order."""

    name: str
    effects: list[HostEffect] = field(default_factory=list)


@dataclass(slots=True)  # one per robot and step: slots make it cheaper to build and read
class StepInputs:
    """What entered one robot during one control step of the engine.

    The received messages are two columns, not a tuple each: `payloads` and `situation`, the
    situated data of message k at `situation[3k:3k + 3]` (distance, azimuth, elevation). An
    M300 swarm receives ~300 messages a step: capturing is two appends per message, and
    writing them out is one copy per robot instead of a conversion per message.
    """

    payloads: list[bytes] = field(default_factory=list)
    situation: array = field(default_factory=lambda: array("d"))
    stepped: bool = False  # control_step() ran (False: asleep, failed, or passive)
    host_calls: list[HostCallRecord] = field(default_factory=list)

    @classmethod
    def of(cls, received: Sequence[tuple[bytes, float, float, float]], stepped: bool = False,
           host_calls: list[HostCallRecord] | None = None) -> StepInputs:
        """From (message, distance, azimuth, elevation) tuples."""
        inputs = cls(stepped=stepped, host_calls=list(host_calls or []))
        for message, distance, azimuth, elevation in received:
            inputs.payloads.append(bytes(message))
            inputs.situation.extend((distance, azimuth, elevation))
        return inputs

    @property
    def received(self) -> list[tuple[bytes, float, float, float]]:
        """The messages as (message, distance, azimuth, elevation) tuples."""
        s = self.situation
        return [(message, s[3 * k], s[3 * k + 1], s[3 * k + 2])
                for k, message in enumerate(self.payloads)]

    @property
    def empty(self) -> bool:
        return not self.payloads and not self.stepped


class ReplayDivergence(Exception):
    """A replayed robot asked for other inputs than the recorded robot did (a bug, not user
    input): the recording cannot rebuild this state exactly."""


class _CapturingCall:
    """A `HostCall` stand-in that forwards everything and writes the calls that touch the VM
    into the step's encoded host calls (`CallLog`)."""

    __slots__ = ("_call", "_log", "_count_at")

    def __init__(self, call: Any, log: CallLog, count_at: int) -> None:
        self._call = call
        self._log = log
        self._count_at = count_at

    def expect_args(self, n: int) -> bool:
        self._log.effect(self._count_at, _EXPECT[int(n) & 0xFF])
        return self._call.expect_args(n)

    def ret(self, value: Any = None) -> None:
        self._log.ret(self._count_at, value)
        self._call.ret(value)

    def fail(self, kind: str) -> None:
        self._log.effect(self._count_at, b"F" + _length_prefixed(str(kind)))
        self._call.fail(kind)

    def __getattr__(self, name: str) -> Any:  # arg, args, arg_count, robot_id, vm, ...
        return getattr(self._call, name)


class _CapturingHostCall(HostCall):
    """The same for a real `HostCall`, without a second object: the tap switches the call's
    class to this subclass for the duration of the host function (and gives it `_log` and
    `_count_at`), so reading arguments (`arg`, `args`, `robot_id`, `vm`) stays a plain
    attribute or method of the call (an M300 SAR step makes ~20 host calls with several
    reads each). (Switching classes, 0.6 us, replaced building a forwarding copy of the
    call, 1.3 us, per host call: measured with timeit.)"""

    _log: CallLog
    _count_at: int

    def expect_args(self, n: int) -> bool:  # CallLog.effect inlined: ~20 calls a SAR step
        data, at = self._log.data, self._count_at
        if data[at] == 0xFF:
            raise ValueError("a host call with more than 255 effects cannot be recorded")
        data[at] += 1
        data += _EXPECT[int(n) & 0xFF]
        return HostCall.expect_args(self, n)

    def ret(self, value: Any = None) -> None:
        data, at = self._log.data, self._count_at
        if type(value) is int and data[at] != 0xFF:  # CallLog.ret's usual case, inlined
            data[at] += 1
            data += b"RI"
            data += _I64.pack(value)
        else:
            self._log.ret(at, value)
        HostCall.ret(self, value)

    def fail(self, kind: str) -> None:
        self._log.effect(self._count_at, b"F" + _length_prefixed(str(kind)))
        HostCall.fail(self, kind)

    # ret_object: HostCall's own, not recorded (no world host returns objects)


class CallLog:
    """The world host calls of one engine step, written in the input log's byte layout as
    they happen (name, effect count, effects: see "bytes" below), so no record object is
    built per call and the step's host calls are ready to copy. `robots[k]` is the robot
    key of call k and `starts[k]` where it begins in `data` (to put calls in robot order
    when an engine steps robots out of index order)."""

    __slots__ = ("data", "robots", "starts")

    def __init__(self) -> None:
        self.data = bytearray()
        self.robots: list[int] = []
        self.starts: list[int] = []

    def __len__(self) -> int:
        return len(self.robots)

    def begin(self, key: int, name: bytes) -> int:
        """A call of robot `key` to the function whose length-prefixed name is `name`; the
        offset of its effect count."""
        data = self.data
        self.robots.append(key)
        self.starts.append(len(data))
        data += name
        data.append(0)
        return len(data) - 1

    def effect(self, count_at: int, encoded: bytes) -> None:
        data = self.data
        if data[count_at] == 0xFF:
            raise ValueError("a host call with more than 255 effects cannot be recorded")
        data[count_at] += 1
        data += encoded

    def ret(self, count_at: int, value: Any) -> None:
        data = self.data
        if data[count_at] == 0xFF:
            raise ValueError("a host call with more than 255 effects cannot be recorded")
        data[count_at] += 1
        _encode_ret(value, data)

    def ordered(self, index_of: Mapping[int, int]) -> tuple[list[int], bytes]:
        """(robot index of each call, the calls' bytes) with robots in index order, each
        robot's calls in call order; `index_of` maps keys to indexes."""
        indexes = [index_of[key] for key in self.robots]
        if all(indexes[k] <= indexes[k + 1] for k in range(len(indexes) - 1)):
            return indexes, bytes(self.data)
        ends = [*self.starts[1:], len(self.data)]
        order = sorted(range(len(indexes)), key=indexes.__getitem__)  # stable
        data = self.data
        return ([indexes[k] for k in order],
                b"".join(data[self.starts[k]:ends[k]] for k in order))


def latch_happy_path(call: Any, argc: int) -> bool:
    """Whether a compiled swarm step may run this call of a latched host function with
    `argc` arguments itself: exactly `argc` arguments, all ints (`fasthost`)."""
    if call.arg_count != argc:
        return False
    return all(type(call.arg(i)) is int for i in range(1, argc + 1))


class ReceivedColumns:
    """Messages received by hooked robots during one step, as columns (a step of a 25-drone
    swarm receives ~250): receiver keys, payloads, (distance, azimuth, elevation) triples."""

    __slots__ = ("robots", "payloads", "situation", "ordered")

    def __init__(self) -> None:
        self.robots: list[int] = []
        self.payloads: list[bytes] = []
        self.situation = array("d")
        self.ordered = True  # receivers came in nondecreasing key order

    def __len__(self) -> int:
        return len(self.robots)

    def add(self, key: int, deliveries: Sequence[tuple[Any, bytes, float, float, float]]
            ) -> None:
        """Robot `key`'s (sender, payload, distance, azimuth, elevation) deliveries."""
        robots = self.robots
        if robots and robots[-1] > key:
            self.ordered = False
        robots.extend(repeat(key, len(deliveries)))
        self.payloads.extend([bytes(d[1][:PAYLOAD_SIZE]) for d in deliveries])
        self.situation.extend(chain.from_iterable([d[2:] for d in deliveries]))

    def sorted(self) -> ReceivedColumns:
        """The same messages by receiver (stable: each robot's in arrival order)."""
        if self.ordered:
            return self
        order = sorted(range(len(self.robots)), key=self.robots.__getitem__)
        result = ReceivedColumns()
        result.robots = [self.robots[k] for k in order]
        result.payloads = [self.payloads[k] for k in order]
        s = self.situation
        result.situation = array("d", chain.from_iterable(s[3 * k:3 * k + 3] for k in order))
        return result


class SwarmCapture:
    """Notes the inputs of every robot of a swarm during one engine step, robots left as they
    are (plain `Robot`s, so an engine's compiled batch of control steps still takes them).

    * Host calls: the robot factory passes each robot host functions wrapped by `tap` (the
      world's mapping, not the Robot, is what changes); while `calls` is a `CallLog`, each
      call is written into it, encoded, in call order (a robot's calls all happen in its own
      control step, so they come robot after robot).
    * Received messages: an engine that hands a step's deliveries to its robots as one
      `packed_messages.PackedMessages` exposes them (`Simulation.step_deliveries`), and the
      recorder copies those columns. For an engine that calls each robot's `receive` /
      `receive_all` itself (asynchronous stepping, or an older engine), `hook_receive` puts
      capturing versions of those two on the robot instance; they append to the
      `ReceivedColumns` in `received` (the key given to the hook: the recorder's robot index).
    """

    def __init__(self) -> None:
        #: the world host calls of this step; None: not capturing
        self.calls: CallLog | None = None
        #: (robot id, payload, distance, azimuth, elevation) from hooked receives this step
        self.received = ReceivedColumns()

    def start(self) -> None:
        self.calls = CallLog()
        self.received = ReceivedColumns()

    def stop(self) -> None:
        self.calls = None
        self.received = ReceivedColumns()

    def take(self) -> tuple[CallLog, ReceivedColumns]:
        """This step's host calls and hooked receives, and start the next step's. Empty ones
        are kept for the next step (a new pair per step was ~5 us of a recorder's step), so a
        caller that keeps them past the next step keeps them only when not empty."""
        calls, received = self.calls, self.received
        if calls is None:
            calls = CallLog()
        elif calls.robots:  # an empty log (a step without host calls) is kept for the next
            self.calls = CallLog()
        if received.robots:  # an empty one is kept for the next step (see above)
            self.received = ReceivedColumns()
        return calls, received

    def tap(self, key: int, name: str, function: Callable[[Any], None],
            live: list[bool] | None = None, latched: int | None = None
            ) -> Callable[[Any], None]:
        """`function` (a world host function of robot `key`) noting its calls while capturing
        and, when `live` is given, while `live[0]` (False while the robot boots: a boot's host
        calls are not inputs of a step).

        `latched`: the argument count of a latched host function (`host.LatchedHostFunction`,
        e.g. a Kilobot's `led`), which a compiled swarm step runs without Python on its happy
        path (exactly that many int arguments): the tap never sees those calls, so it notes
        none on the happy path, whichever way the call came; by the latch's contract such a
        call's only effect on the VM is `ret0`, which `ReplayHostFunctions` repeats for any
        happy-path call of that function without a record. (Making the function an ordinary
        tapped one instead sent every such call back to Python: +80 % on a Kilobot swarm.)"""
        capture = self
        live = [True] if live is None else live
        encoded = _length_prefixed(name)

        def tapped(call: Any) -> None:
            log = capture.calls
            if log is None or not live[0] or (latched is not None
                                               and latch_happy_path(call, latched)):
                function(call)
                return
            count_at = log.begin(key, encoded)
            if type(call) is HostCall:
                call._log = log  # type: ignore[attr-defined]
                call._count_at = count_at  # type: ignore[attr-defined]
                call.__class__ = _CapturingHostCall
                try:
                    function(call)
                finally:
                    call.__class__ = HostCall
            else:
                function(_CapturingCall(call, log, count_at))

        return tapped

    def hook_receive(self, robot: Any, key: int) -> None:
        """Capture `robot`'s receives through instance attributes (see the class doc). Not
        needed, and not done, when the engine exposes `step_deliveries`."""
        cls = type(robot)
        receive = cls.receive.__get__(robot)
        receive_all = getattr(cls, "receive_all", None)
        rows = self
        bulk = [False]  # inside receive_all, which may call receive for each message

        def capturing_receive(message: bytes, distance: float = 0.0, azimuth: float = 0.0,
                              elevation: float = 0.0) -> None:
            if rows.calls is not None and not bulk[0]:
                rows.received.add(key, [(None, message, distance, azimuth, elevation)])
            receive(message, distance, azimuth, elevation)

        robot.receive = capturing_receive
        if receive_all is None:
            return
        receive_all = receive_all.__get__(robot)

        def capturing_receive_all(deliveries: Sequence[tuple[Any, bytes, float, float, float]]
                                  ) -> None:
            if rows.calls is not None:
                rows.received.add(key, deliveries)
            bulk[0] = True
            try:
                receive_all(deliveries)
            finally:
                bulk[0] = False

        robot.receive_all = capturing_receive_all


#: The engine's robot factory: (program, profile, robot_id, host functions) -> firmware loop.
Factory = Callable[[Any, Any, int, Mapping[str, Callable[[Any], None]]], Any]


# ---- replay ------------------------------------------------------------------------------------
class ReplayHostFunctions:
    """Host functions for a rebuilt robot: each call repeats the next recorded call's effects.

    Before `load` (e.g. while the rebuilt robot boots, before its snapshot is restored) a call
    only returns 0 (its effects are overwritten by the restore).
    """

    def __init__(self, names: Sequence[str], latched: Mapping[str, int] | None = None) -> None:
        self.names = list(names)
        #: name -> argument count of the latched host functions (their happy-path calls
        #: were not recorded: see `SwarmCapture.tap`; recordings of format 3)
        self.latched = dict(latched or {})
        self._pending: list[HostCallRecord] | None = None

    def load(self, calls: list[HostCallRecord]) -> None:
        self._pending = list(reversed(calls))

    def leftover(self) -> int:
        return len(self._pending or [])

    def functions(self) -> dict[str, Callable[[Any], None]]:
        return {name: self._replayer(name) for name in self.names}

    def _replayer(self, name: str) -> Callable[[Any], None]:
        latched = self.latched.get(name)

        def replay(call: Any) -> None:
            pending = self._pending
            if pending is None:
                call.ret(0)
                return
            if latched is not None and latch_happy_path(call, latched):
                return  # not recorded; its only effect on the VM is ret0 (HostCall.finish)
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


def replay_step(robot: Any, inputs: StepInputs, host: ReplayHostFunctions) -> list[bytes]:
    """Apply one recorded control step to `robot` (restored to the state before that step);
    the payloads it sent in that step (what the live inspector saw leave its out-queue)."""
    replay_receive(robot, inputs)
    return replay_control_step(robot, inputs, host)


def replay_receive(robot: Any, inputs: StepInputs) -> None:
    """The messages `robot` received in a recorded step, handed to it again (the engine
    delivers every robot's messages before any robot's turn)."""
    s = inputs.situation
    receive_all = getattr(robot, "receive_all", None)
    if receive_all is not None and inputs.payloads:  # the engine's way, when the robot has it
        receive_all([(None, message, s[3 * k], s[3 * k + 1], s[3 * k + 2])
                     for k, message in enumerate(inputs.payloads)])
    else:
        for k, message in enumerate(inputs.payloads):
            robot.receive(message, s[3 * k], s[3 * k + 1], s[3 * k + 2])


def replay_control_step(robot: Any, inputs: StepInputs, host: ReplayHostFunctions
                        ) -> list[bytes]:
    """`robot`'s turn of a recorded step (after `replay_receive`), its host calls answered
    as recorded; the payloads it sent."""
    sent: list[bytes] = []
    if inputs.stepped:
        host.load(inputs.host_calls)
        try:
            sent = list(robot.control_step() or [])
        finally:
            left = host.leftover()
            host._pending = None
        if left:
            raise ReplayDivergence(f"the replayed step made {left} host call(s) fewer than "
                                   "the recorded one")
    return sent


# ---- bytes -------------------------------------------------------------------------------------
# Layout of one step (all little-endian), `LAYOUT_COMPACT` (recording format 4 on):
#   u16 robot records (r)
#   u8 step flags: 1 = the lengths column is there, 2 = the bearing columns are there (else
#     every azimuth and elevation is +0.0)
#   without a lengths column: u8 the length of every payload of the step (0 when none)
#   r headers: u16 robot index, u8 flags (1 = stepped), u16 messages, u16 host calls
#   the messages of all records, in record order (M in all), as columns:
#     [u16 length[M]], the M payloads back to back, f64 distance[M],
#     [f64 azimuth[M], f64 elevation[M]]
#   the host calls of all records, in record order:
#     host call: u8 name length, name (UTF-8), u8 effects
#       effect: b"E" u8 n | b"F" u8 length, kind | b"R" value
#       value:  b"N" | b"I" i64 | b"D" f64 | b"T" u8 entries, (u8 length, key, value)*
# `LAYOUT_FULL` (formats 2 and 3, still read) has no step flags byte, always the lengths, and
# f64 situation[3M] (distance, azimuth, elevation of each message, interleaved) instead of the
# distance and bearing columns. A Kilobot swarm's ~150 messages a step all have 8-byte
# payloads and no bearings: the compact layout is 16 instead of 34 bytes a message (5.5 ->
# 2.6 KB a step), and its payloads are one strided copy of the engine's payload table (cutting
# each row to its own length with a mask was ~10 us of the recorder's ~180 a step).
# Step-wide columns copied from the captured ones, not one packed struct per message: an M300
# swarm receives ~300 messages a step, and ~300 `pack` calls were one of the recorder's
# largest costs; like values side by side also compress better.
#: The input layouts (`decode_step(layout=...)`; `recording.layout.input_layout` says which a
#: recording format uses).
LAYOUT_FULL = 1
LAYOUT_COMPACT = 2
#: Step flags of `LAYOUT_COMPACT` (the full layout has both columns always).
_LENGTHS = 1
_BEARINGS = 2


def _step_head(flags: int, length: int) -> bytes:
    """A compact step's flags byte, and the length of all its payloads (no lengths column)."""
    return bytes((flags,)) if flags & _LENGTHS else bytes((flags, length))
_U16 = struct.Struct("<H")
_HEAD = struct.Struct("<HBHH")
_I64 = struct.Struct("<q")
_F64 = struct.Struct("<d")
_STEPPED = 1
#: `array` writes the machine's byte order; the layout is little-endian.
_SWAP = sys.byteorder != "little"


class InputLogError(ValueError):
    """Bytes that are not an input log (a corrupt recording)."""


def _encode_ret(value: Any, out: bytearray) -> None:
    """A ``ret`` effect: ``R`` and the value; an int (the usual answer) without the type
    dispatch of `_encode_value` (the same bytes)."""
    if type(value) is int:
        out += b"RI"
        out += _I64.pack(value)
    else:
        out += b"R"
        _encode_value(value, out)


def _encode_value(value: Any, out: bytearray) -> None:
    kind = type(value)  # exact types first: a host call returns ints, floats and small tables
    if kind is int:
        out += b"I"
        out += _I64.pack(value)
    elif kind is float:
        out += b"D"
        out += _F64.pack(value)
    elif value is None:
        out += b"N"
    elif isinstance(value, bool | int):
        out += b"I"
        out += _I64.pack(int(value))
    elif isinstance(value, float):
        out += b"D"
        out += _F64.pack(value)
    elif isinstance(value, dict):
        out += b"T"
        out.append(len(value))
        for key, item in value.items():
            # Only str keys are cached: True == 1 as dict keys, but not as text.
            name = _KEYS.get(key) if type(key) is str else None
            if name is None:
                name = _length_prefixed(str(key))
                if type(key) is str and len(_KEYS) < _MAX_KEYS:
                    _KEYS[key] = name
            out += name
            if type(item) is int:  # the usual entry (an M300 `position`: x, y, z, cell)
                out += b"I"
                out += _I64.pack(item)
            else:
                _encode_value(item, out)
    else:
        out += b"N"  # HostCall.ret turns anything else into nil too


#: Encoded table keys of host-call answers ("x", "y", ...: the same few every step), at most
#: 1,024 of them (a world that made up new keys every call cannot grow this without bound).
_KEYS: dict[Any, bytes] = {}
_MAX_KEYS = 1024


def encode_step(records: Sequence[tuple[int, StepInputs]], layout: int = LAYOUT_COMPACT
                ) -> bytes:
    """The inputs of the robots of one step (robots with none may be left out)."""
    payloads = list(chain.from_iterable(inputs.payloads for _, inputs in records))
    lengths = array("H", map(len, payloads))
    situation = array("d")
    for _, inputs in records:
        situation += inputs.situation
    out = bytearray(_U16.pack(len(records)))
    flags = _LENGTHS | _BEARINGS
    if layout == LAYOUT_COMPACT:
        flags = ((_LENGTHS if len(set(lengths)) > 1 else 0)
                 | (_BEARINGS if any(situation[1::3].tobytes() + situation[2::3].tobytes())
                    else 0))  # any bit set: -0.0 is kept as it is
        out += _step_head(flags, lengths[0] if lengths else 0)
    for index, inputs in records:
        out += _HEAD.pack(index, _STEPPED if inputs.stepped else 0, len(inputs.payloads),
                          len(inputs.host_calls))
    if payloads:
        if _SWAP:
            lengths.byteswap()
            situation.byteswap()
        if flags & _LENGTHS:
            out += lengths.tobytes()
        out += b"".join(payloads)
        if layout == LAYOUT_COMPACT:
            out += situation[0::3].tobytes()
            if flags & _BEARINGS:
                out += situation[1::3].tobytes() + situation[2::3].tobytes()
        else:
            out += situation.tobytes()
    _encode_calls(chain.from_iterable(inputs.host_calls for _, inputs in records), out)
    return bytes(out)


#: A record header (`_HEAD`) as a numpy row, so the steps' headers are one array.
_HEAD_ROW = np.dtype([("index", "<u2"), ("flags", "u1"), ("messages", "<u2"), ("calls", "<u2")])


def encode_columns(stepped: np.ndarray, deliveries: PackedMessages | ReceivedColumns | None,
                   calls: tuple[Sequence[int], bytes], layout: int = LAYOUT_COMPACT) -> bytes:
    """`encode_steps` of one step."""
    return encode_steps([stepped], [deliveries], [calls], layout)[0]


def encode_steps(stepped: Sequence[np.ndarray],
                 deliveries: Sequence[PackedMessages | ReceivedColumns | None],
                 calls: Sequence[tuple[Sequence[int], bytes]],
                 layout: int = LAYOUT_COMPACT) -> list[bytes]:
    """`encode_steps_joined`, as one bytes object per step."""
    data, ends = encode_steps_joined(stepped, deliveries, calls, layout)
    return [data[a:b] for a, b in zip([0, *ends], ends, strict=False)]


def encode_steps_joined(stepped: Sequence[np.ndarray],
                        deliveries: Sequence[PackedMessages | ReceivedColumns | None],
                        calls: Sequence[tuple[Sequence[int], bytes]],
                        layout: int = LAYOUT_COMPACT) -> tuple[bytes, list[int]]:
    """`encode_step`'s bytes for each of several steps of a whole swarm, given as columns
    (what a recorder keeps per step until it flushes: the engine's `step_deliveries` and
    the encoded host calls, instead of per-robot records).

    Per step: `stepped[k][i]`: robot i ran its control step; `deliveries[k]`: the messages
    the robots received, rows sorted by receiver (None: none), as `PackedMessages` or as
    `ReceivedColumns` keyed by robot index; `calls[k]`: (robot index of each host call, the
    calls' bytes), robots in index order (`CallLog.ordered`). A robot gets a record when it
    stepped, received or called. Payloads are cut to what a VM reads (`PAYLOAD_SIZE`), as
    `receive` does. Batched: the packed deliveries of all the steps are concatenated and
    encoded by a few numpy operations, then each step's bytes are slices of those columns
    (one step at a time, this was ~25 numpy calls per step with cold caches after each
    simulation step). Returned back to back, with the offset where each step's bytes end (a
    recorder hands them to Arrow as they are: one bytes object per step, then copied into an
    Arrow array, was ~5 us a Kilobot step)."""
    steps = len(stepped)
    if steps == 0:
        return b"", []
    count = len(stepped[0])
    ran = np.array(stepped, dtype=bool).reshape(steps, count)
    received = np.zeros(steps * count, dtype=np.int64)
    # per step: its flags and common payload length (compact layout), its message columns
    columns: list[tuple[bytes, ...]] = [()] * steps
    flag_bytes = [_step_head(0, 0) if layout == LAYOUT_COMPACT else b""] * steps
    packed = [k for k, d in enumerate(deliveries)
              if isinstance(d, PackedMessages) and len(d.robots)]
    if packed:
        parts = [deliveries[k] for k in packed]
        sizes = np.array([len(d.robots) for d in parts], dtype=np.int64)
        robots = np.concatenate([d.robots for d in parts])
        received += np.bincount(np.repeat(np.array(packed) * count, sizes) + robots,
                                minlength=steps * count)
        bounds = np.concatenate([[0], np.cumsum(sizes)])
        _packed_columns(parts, bounds, packed, layout, columns, flag_bytes)
    for k, d in enumerate(deliveries):
        if isinstance(d, ReceivedColumns) and len(d):
            robots, lengths, payload_bytes, situation = _message_columns(d)
            received[k * count:(k + 1) * count] += np.bincount(robots, minlength=count)
            flags, columns[k] = _step_columns(lengths, payload_bytes, situation, layout)
            if layout == LAYOUT_COMPACT:
                flag_bytes[k] = _step_head(flags, int(lengths[0]))
    called = np.zeros(steps * count, dtype=np.int64)
    call_rows = [(k, indexes) for k, (indexes, _) in enumerate(calls) if len(indexes)]
    if call_rows:
        called += np.bincount(np.concatenate([np.asarray(indexes, dtype=np.int64) + k * count
                                              for k, indexes in call_rows]),
                              minlength=steps * count)
    flat = ran.reshape(-1)
    present = np.flatnonzero(flat | (received > 0) | (called > 0))
    heads = np.zeros(len(present), _HEAD_ROW)
    heads["index"] = present % count
    heads["flags"] = flat[present] * _STEPPED
    heads["messages"] = received[present]
    heads["calls"] = called[present]
    head_bytes = heads.tobytes()
    per_step = np.bincount(present // count, minlength=steps)
    firsts = np.concatenate([[0], np.cumsum(per_step)]).tolist()
    records = per_step.tolist()
    size = _HEAD.size
    pack = _U16.pack
    chunks: list[bytes] = []
    last_chunk = []  # per step: the index of its last chunk
    for k in range(steps):
        chunks += (pack(records[k]), flag_bytes[k],
                   head_bytes[size * firsts[k]:size * firsts[k + 1]], *columns[k], calls[k][1])
        last_chunk.append(len(chunks) - 1)
    ends = np.cumsum(np.fromiter(map(len, chunks), dtype=np.int64, count=len(chunks)))
    return b"".join(chunks), ends[last_chunk].tolist()


def _packed_columns(parts: list[PackedMessages], bounds: np.ndarray, steps: list[int],
                    layout: int, columns: list[tuple[bytes, ...]], flag_bytes: list[bytes]
                    ) -> None:
    """The message columns (and compact step heads) of the steps `steps`, whose deliveries
    are `parts` (rows `bounds[j]:bounds[j + 1]` once concatenated), written into `columns`
    and `flag_bytes` at those steps: each column is encoded once for all the steps, and each
    step's bytes are slices of it."""
    lengths = np.minimum(np.concatenate([d.lengths for d in parts]), PAYLOAD_SIZE)
    payloads = np.concatenate([d.payloads for d in parts])
    low, high = int(lengths.min()), int(lengths.max())
    rows = bounds.tolist()
    if low == high:  # the usual case: every payload as long (8 bytes for a Kilobot)
        payload_bytes = payloads[:, :low].tobytes()
        bytes_at = (low * bounds).tolist()
    else:
        payload_bytes = payloads[np.arange(PAYLOAD_SIZE) < lengths[:, None]].tobytes()
        bytes_at = np.concatenate([[0], np.cumsum(lengths)])[bounds].tolist()
    if layout == LAYOUT_FULL:
        length_bytes = lengths.astype("<u2").tobytes()
        situation_bytes = np.column_stack([np.concatenate([getattr(d, name) for d in parts])
                                           for name in ("distances", "azimuths", "elevations")]
                                          ).astype("<f8").tobytes()
        for j, k in enumerate(steps):
            r0, r1 = rows[j], rows[j + 1]
            columns[k] = (length_bytes[2 * r0:2 * r1], payload_bytes[bytes_at[j]:bytes_at[j + 1]],
                          situation_bytes[24 * r0:24 * r1])
        return
    distance_bytes = np.concatenate([d.distances for d in parts]).astype("<f8", copy=False
                                                                         ).tobytes()
    azimuths = np.concatenate([d.azimuths for d in parts])
    elevations = np.concatenate([d.elevations for d in parts])
    # A step's bearing columns are written when any of its bearings has a bit set (-0.0 too)
    bearing = azimuths.view(np.uint64) | elevations.view(np.uint64)
    with_bearings: set[int] = set()
    if bearing.any():
        at = np.concatenate([[0], np.cumsum(bearing != 0)])[bounds]
        with_bearings = set(np.flatnonzero(np.diff(at)).tolist())
        azimuth_bytes = azimuths.astype("<f8", copy=False).tobytes()
        elevation_bytes = elevations.astype("<f8", copy=False).tobytes()
    common = [low] * len(steps)  # each step's payload length, -1: several (a lengths column)
    if low != high:
        starts = bounds[:-1]  # every step in `steps` has messages
        lows = np.minimum.reduceat(lengths, starts)
        common = np.where(lows == np.maximum.reduceat(lengths, starts), lows, -1).tolist()
        length_bytes = lengths.astype("<u2").tobytes()
    heads = {}
    for j, k in enumerate(steps):
        r0, r1 = rows[j], rows[j + 1]
        step = [payload_bytes[bytes_at[j]:bytes_at[j + 1]], distance_bytes[8 * r0:8 * r1]]
        flags = 0
        if common[j] < 0:
            flags = _LENGTHS
            step.insert(0, length_bytes[2 * r0:2 * r1])
        if j in with_bearings:
            flags |= _BEARINGS
            step += (azimuth_bytes[8 * r0:8 * r1], elevation_bytes[8 * r0:8 * r1])
        columns[k] = tuple(step)
        head = heads.get((flags, common[j]))
        if head is None:
            head = heads[flags, common[j]] = _step_head(flags, common[j])
        flag_bytes[k] = head


def _step_columns(lengths: np.ndarray, payload_bytes: bytes, situation: np.ndarray,
                  layout: int) -> tuple[int, tuple[bytes, ...]]:
    """One step's message columns in `layout` (and its compact flags) from the messages'
    lengths (already cut to PAYLOAD_SIZE), payloads back to back and (M, 3) situated data."""
    length_bytes = lengths.astype("<u2").tobytes()
    if layout == LAYOUT_FULL:
        return 0, (length_bytes, payload_bytes, situation.astype("<f8").tobytes())
    flags = ((_LENGTHS if int(lengths.min()) != int(lengths.max()) else 0)
             | (_BEARINGS if bool(situation[:, 1:].view(np.uint64).any()) else 0))
    step = [payload_bytes, situation[:, 0].astype("<f8").tobytes()]
    if flags & _LENGTHS:
        step.insert(0, length_bytes)
    if flags & _BEARINGS:
        step += (situation[:, 1].astype("<f8").tobytes(), situation[:, 2].astype("<f8").tobytes())
    return flags, tuple(step)


def encode_calls(records: Iterable[HostCallRecord]) -> bytes:
    """Host calls in the layout `CallLog` writes them (for records built by hand)."""
    out = bytearray()
    _encode_calls(records, out)
    return bytes(out)


def _message_columns(deliveries: ReceivedColumns
                     ) -> tuple[np.ndarray, np.ndarray, bytes, np.ndarray]:
    """Hooked receives as receivers, payload lengths, payloads back to back and (M, 3)
    situated data (distance, azimuth, elevation of each message)."""
    columns = deliveries.sorted()
    return (np.array(columns.robots, dtype=np.int64),
            np.fromiter(map(len, columns.payloads), dtype=np.int64, count=len(columns.payloads)),
            b"".join(columns.payloads),
            np.frombuffer(columns.situation, dtype=np.float64).reshape(-1, 3))


def _encode_calls(calls: Iterable[HostCallRecord], out: bytearray) -> None:
    names = _NAMES
    for call in calls:
        name = names.get(call.name)
        if name is None:
            name = names[call.name] = _length_prefixed(call.name)
        out += name
        out.append(len(call.effects))
        for effect in call.effects:
            kind = effect[0]
            if kind == "ret":
                _encode_ret(effect[1], out)
            elif kind == "expect":
                out += _EXPECT[effect[1] & 0xFF]
            else:
                out += b"F" + _length_prefixed(effect[1])


def _length_prefixed(text: str) -> bytes:
    data = text.encode()
    return bytes([len(data)]) + data


#: Encoded host-function names (a swarm calls the same few names every step).
_NAMES: dict[str, bytes] = {}
_EXPECT = [b"E" + bytes([n]) for n in range(256)]


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


def _skip_calls(reader: _Reader, calls: int) -> None:
    """Step over one robot's host calls without building them (a seek needs one robot of 25)."""
    data, at = reader.data, reader.at
    try:
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


def _read_calls(reader: _Reader, calls: int) -> list[HostCallRecord]:
    records = []
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
        records.append(record)
    return records


def _read_messages(reader: _Reader, total: int, first: int, count: int, flags: int,
                   common: int, layout: int) -> tuple[list[bytes], array]:
    """Payloads and situated data of messages `first`..`first + count` of the step's `total`
    (the whole block is stepped over; only those are built); `common`: the length of every
    payload when there is no lengths column."""
    if flags & _LENGTHS:
        lengths = array("H")
        lengths.frombytes(reader.take(2 * total))
        if _SWAP:
            lengths.byteswap()
        payload_bytes = sum(lengths)
        at = sum(lengths[:first])
        sizes: Iterable[int] = lengths[first:first + count]
    else:  # every payload `common` bytes
        payload_bytes, at, sizes = common * total, common * first, [common] * count
    block = reader.take(payload_bytes + (24 if flags & _BEARINGS else 8) * total)
    payloads = []
    for length in sizes:
        payloads.append(block[at:at + length])
        at += length
    if layout == LAYOUT_FULL:  # (distance, azimuth, elevation) interleaved
        start = payload_bytes + 24 * first
        situation = array("d", block[start:start + 24 * count])
    else:  # a distance column, then (if there) an azimuth and an elevation column
        situation = array("d", bytes(24 * count))  # bearings +0.0 unless written
        for column in range(3 if flags & _BEARINGS else 1):
            start = payload_bytes + 8 * (column * total + first)
            situation[column::3] = array("d", block[start:start + 8 * count])
    if _SWAP:
        situation.byteswap()
    return payloads, situation


def decode_step(data: bytes, only: int | None = None, layout: int = LAYOUT_COMPACT
                ) -> dict[int, StepInputs]:
    """`encode_step`'s bytes in `layout` back: robot index -> its inputs (with `only`, just
    that robot's: the other records are stepped over, not built)."""
    reader = _Reader(data)
    records = reader.unpack(_U16)[0]
    step_flags = reader.byte() if layout == LAYOUT_COMPACT else _LENGTHS | _BEARINGS
    if step_flags & ~(_LENGTHS | _BEARINGS):
        raise InputLogError(f"unknown step flags {step_flags:#x} in input log")
    common = 0 if step_flags & _LENGTHS else reader.byte()
    # The record headers as one numpy view (a seek decodes a step of 25 robots per step it
    # re-executes: 25 struct unpacks were a third of that)
    heads = np.frombuffer(reader.take(_HEAD.size * records), _HEAD_ROW)
    indexes, flags = heads["index"].tolist(), heads["flags"].tolist()
    counts, calls = heads["messages"].tolist(), heads["calls"].tolist()
    total = sum(counts)
    firsts = list(accumulate(counts, initial=0))
    result: dict[int, StepInputs] = {}
    if only is not None:  # one robot's slice of the columns (if it has a record)
        mine = indexes.index(only) if only in indexes else None
        first, count = (0, 0) if mine is None else (firsts[mine], counts[mine])
        payloads, situation = (
            _read_messages(reader, total, first, count, step_flags, common, layout) if total
            else ([], array("d")))
        if mine is None:
            _skip_calls(reader, sum(calls))
        else:
            _skip_calls(reader, sum(calls[:mine]))
            result[only] = StepInputs(payloads, situation, stepped=bool(flags[mine] & _STEPPED),
                                      host_calls=_read_calls(reader, calls[mine]))
            _skip_calls(reader, sum(calls[mine + 1:]))
    else:  # everything: one pass over the columns
        payloads, situation = (
            _read_messages(reader, total, 0, total, step_flags, common, layout) if total
            else ([], array("d")))
        for i, index in enumerate(indexes):
            a, b = firsts[i], firsts[i + 1]
            result[index] = StepInputs(payloads[a:b], situation[3 * a:3 * b],
                                       stepped=bool(flags[i] & _STEPPED),
                                       host_calls=_read_calls(reader, calls[i]))
    if reader.at != len(data):
        raise InputLogError(f"{len(data) - reader.at} stray bytes after the input log")
    return result
