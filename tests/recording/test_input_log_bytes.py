"""The per-step input log's bytes: every kind of input survives encode -> decode, and decoding
one robot's record (what a seek does) gives exactly that robot's inputs."""

from __future__ import annotations

import numpy as np
import pytest

from bbzide.recording.input_log import (
    LAYOUT_COMPACT,
    LAYOUT_FULL,
    HostCallRecord,
    InputLogError,
    StepInputs,
    decode_step,
    encode_step,
)

#: Both input layouts: the compact one (format 4 on) and the full one (formats 2 and 3).
LAYOUTS = pytest.mark.parametrize("layout", [LAYOUT_COMPACT, LAYOUT_FULL],
                                  ids=["compact", "full"])


def inputs_of(robot: int) -> StepInputs:
    """Robot-dependent inputs using every layout: bearings present or not, each effect kind,
    every value tag (nil, int, float, nested table)."""
    received = [
        (bytes([0, robot, 0, 7, 0, 1, 2, 3]), 12.5 + robot, 0.0, 0.0),
        (bytes([1, 2, 0, 9, 0, 4, 5, 6, robot]), 3.0, -1.25, 0.0),
        (bytes([0, 3, 0]), 7.0, 0.0, 2.5),
        (bytes([2, 1, 0, 4, 0, 9, 9, 9, 1]), 0.5, 1.0, -0.75),
    ][: 1 + robot % 4]
    calls = [
        HostCallRecord("position", [("expect", 0), ("ret", {"x": robot, "y": 2.5, "z": None})]),
        HostCallRecord("goto", [("expect", 2), ("fail", "TYPE")]),
        HostCallRecord("rand", [("ret", -robot * 1000)]),
        HostCallRecord("nested", [("ret", {"a": {"b": 1.0}, "c": 3})]),
    ][: robot % 5]
    return StepInputs.of(received, stepped=robot % 3 != 0, host_calls=calls)


@LAYOUTS
def test_every_input_round_trips_and_one_robot_decodes_alone(layout: int) -> None:
    records = [(index, inputs_of(index)) for index in (0, 1, 2, 4, 7, 11)]
    data = encode_step(records, layout)
    assert decode_step(data, layout=layout) == dict(records)
    for index, inputs in records:
        assert decode_step(data, only=index, layout=layout) == {index: inputs}
    assert decode_step(data, only=3, layout=layout) == {}  # a robot with no record this step


@LAYOUTS
def test_a_torn_record_is_an_error_even_when_skipped(layout: int) -> None:
    data = encode_step([(0, inputs_of(1)), (1, inputs_of(2))], layout)
    with pytest.raises(InputLogError):
        decode_step(data[:-3], only=1, layout=layout)
    with pytest.raises(InputLogError):
        # cut inside robot 0's record, which is stepped over
        decode_step(data[:20], only=1, layout=layout)


@LAYOUTS
def test_a_negative_zero_bearing_keeps_its_sign(layout: int) -> None:
    """Situated data is stored as its exact bits: a bbzfloat conversion keeps the sign of
    -0.0, so it must come back as -0.0 (the compact layout writes the bearings then)."""
    import math

    inputs = StepInputs.of([(b"\x00\x01\x00", 2.0, -0.0, 0.0)], stepped=True)
    (message, distance, azimuth, elevation), = decode_step(
        encode_step([(5, inputs)], layout), layout=layout)[5].received
    assert (message, distance, elevation) == (b"\x00\x01\x00", 2.0, 0.0)
    assert math.copysign(1.0, azimuth) == -1.0


def test_the_compact_layout_leaves_out_equal_lengths_and_zero_bearings() -> None:
    """A Kilobot-like step (every payload 8 bytes, no bearings) is 18 bytes a message smaller
    in the compact layout: no u16 length and no f64 azimuth and elevation per message, for 2
    bytes of step head; one bearing or one other length brings its column back, whole."""
    received = [(bytes([k] * 8), 10.0 + k, 0.0, 0.0) for k in range(6)]
    records = [(k, StepInputs.of(received[2 * k:2 * k + 2], stepped=True)) for k in range(3)]
    full, compact = (encode_step(records, layout) for layout in (LAYOUT_FULL, LAYOUT_COMPACT))
    assert len(full) - len(compact) == 18 * 6 - 2
    assert compact[2:4] == b"\x00\x08"  # flags: no columns; every payload 8 bytes
    bearing = [*received[:5], (bytes(8), 1.0, 0.0, 0.5)]
    short = [*received[:5], (bytes(5), 1.0, 0.0, 0.0)]
    for changed, flags, grown in ((bearing, 2, 16 * 6), (short, 1, 2 * 6 - 1 - 3)):
        records = [(k, StepInputs.of(changed[2 * k:2 * k + 2], stepped=True)) for k in range(3)]
        data = encode_step(records, LAYOUT_COMPACT)
        assert data[2] == flags and len(data) - len(compact) == grown
        assert decode_step(data, layout=LAYOUT_COMPACT) == dict(records)


class _Inner:
    """A firmware loop that notes how its messages arrived (one by one)."""

    def __init__(self) -> None:
        self.got: list[tuple] = []

    def receive(self, message: bytes, distance: float, azimuth: float, elevation: float) -> None:
        self.got.append(("one", message, distance, azimuth, elevation))


class _BulkInner(_Inner):
    """...and one that also takes a step's deliveries in one call, which calls `receive` for
    each, as `Robot.receive_all` does outside its compiled path."""

    def receive_all(self, deliveries: list[tuple]) -> None:
        self.got.append(("all", list(deliveries)))
        for _, *message in deliveries:
            self.receive(*message)


def test_hooked_receives_are_noted_and_reach_the_robot_its_way() -> None:
    """An engine without `step_deliveries` calls each robot's `receive` or `receive_all`: the
    hooks must note both (forwarding `receive_all` unnoted would make every rebuild
    diverge) and pass the messages on as the robot takes them."""
    from bbzide.recording.input_log import SwarmCapture

    deliveries = [(7, b"\x00\x07\x00\x01", 1.5, -0.25, 0.0), (9, b"\x01\x09", 3.0, 0.5, 0.125)]
    for inner in (_BulkInner(), _Inner()):
        capture = SwarmCapture()
        capture.hook_receive(inner, 3)
        inner.receive_all(deliveries) if isinstance(inner, _BulkInner) else [
            inner.receive(*d[1:]) for d in deliveries]
        assert len(capture.take()[1]) == 0  # not capturing yet: passed on, not noted
        capture.start()
        inner.got.clear()
        inner.receive_all(deliveries) if isinstance(inner, _BulkInner) else [
            inner.receive(*d[1:]) for d in deliveries]
        got = capture.take()[1]  # each message once
        assert got.robots == [3, 3] and got.payloads == [d[1] for d in deliveries]
        assert list(got.situation) == [x for d in deliveries for x in d[2:]]
        ones = [("one", *d[1:]) for d in deliveries]
        assert inner.got == ([("all", deliveries), *ones] if isinstance(inner, _BulkInner)
                             else ones)
        assert type(inner) in (_Inner, _BulkInner)  # the robot itself is not wrapped


@LAYOUTS
def test_columns_encode_to_the_same_bytes_as_per_robot_records(layout: int) -> None:
    """`encode_steps` (several steps' deliveries as numpy columns and their host calls as
    bytes, the recorder's way at each flush) writes exactly `encode_step`'s layout for each
    step, so `decode_step` and every recording stay as they were; payloads longer than a VM
    reads are cut as `receive` cuts them; packed, hooked and missing deliveries mix."""
    from bbzide.recording.input_log import (
        HostCallRecord,
        ReceivedColumns,
        StepInputs,
        encode_calls,
        encode_columns,
        encode_steps,
    )
    from bbzide.vm.swarm_batch import PackedMessages

    long = bytes(range(1, 13))  # 12 bytes on the wire, 9 read
    rows = [(0, 4, b"\x00\x04\x00\x01\x00\x05", 1.5, -0.25, 0.0),
            (0, 2, long, 2.0, 0.5, 0.25), (3, 0, b"\x02", 0.75, 3.0, -1.0)]
    calls = [(0, HostCallRecord("rand", [("expect", 0), ("ret", 17)])),
             (2, HostCallRecord("gps", [("ret", {"x": 1.5, "y": -2})])),
             (2, HostCallRecord("led", [("expect", 1), ("fail", "TYPE")]))]
    encoded_calls = ([c[0] for c in calls], encode_calls(c[1] for c in calls))
    stepped = np.array([True, False, True, False, False])
    packed = encode_columns(stepped, PackedMessages.from_rows(rows), encoded_calls, layout)
    records = [
        (0, StepInputs.of([(r[2][:9], *r[3:]) for r in rows[:2]], True, [calls[0][1]])),
        (2, StepInputs.of([], True, [c[1] for c in calls[1:]])),
        (3, StepInputs.of([(rows[2][2], *rows[2][3:])], False)),
    ]
    assert packed == encode_step(records, layout)
    decoded = decode_step(packed, layout=layout)
    assert decoded[0].received[1][0] == long[:9]
    assert decoded[2].host_calls[0].effects == [("ret", {"x": 1.5, "y": -2})]
    hooked = ReceivedColumns()  # the hooked receives' form, in another receiver order
    hooked.add(3, [(None, *rows[2][2:])])
    hooked.add(0, [(None, *r[2:]) for r in rows[:2]])
    nine = [(1, 0, bytes(range(9)), 4.0, 0.0, 0.0), (4, 1, bytes(range(9, 18)), 5.0, 1.0, 2.0)]
    several = encode_steps(
        [stepped, np.zeros(5, bool), stepped, np.ones(5, bool)],
        [PackedMessages.from_rows(rows), None, hooked, PackedMessages.from_rows(nine)],
        [encoded_calls, ([], b""), encoded_calls, ([], b"")], layout)
    assert several[:3] == [packed, encode_step([], layout), packed]
    assert several[3] == encode_step([
        (i, StepInputs.of([(r[2], *r[3:]) for r in nine if r[0] == i], True))
        for i in range(5)], layout)


def test_host_calls_are_written_as_they_happen_in_the_layout() -> None:
    """The capture writes each tapped host call's effects straight into the step's bytes
    (`CallLog`): the same bytes as the records would encode to, robots put in index order
    when an engine steps them out of order, and nothing noted while not capturing or while
    the robot boots."""
    from bbzide.recording.input_log import HostCallRecord, SwarmCapture, encode_calls

    class Call:  # the parts of HostCall a world host function uses
        def __init__(self, args: int) -> None:
            self.args = args

        def expect_args(self, n: int) -> bool:
            return self.args == n

        def ret(self, value: object = None) -> None:
            pass

        def fail(self, kind: str) -> None:
            pass

    def position(call: Call) -> None:
        if call.expect_args(0):
            call.ret({"x": 1.25, "y": -3})

    def led(call: Call) -> None:
        if not call.expect_args(1):
            call.fail("LNUM")

    capture = SwarmCapture()
    live = [False]
    tapped = {(key, name): capture.tap(key, name, fn, live if key == 9 else None)
              for key in (5, 7, 9) for name, fn in (("position", position), ("led", led))}
    tapped[(5, "position")](Call(0))  # not capturing: passed on only
    capture.start()
    tapped[(9, "led")](Call(1))  # robot 9 is still booting
    tapped[(7, "position")](Call(0))
    tapped[(7, "led")](Call(2))
    tapped[(5, "led")](Call(1))
    indexes, data = capture.take()[0].ordered({5: 0, 7: 1, 9: 2})
    assert indexes == [0, 1, 1]
    assert data == encode_calls([
        HostCallRecord("led", [("expect", 1)]),
        HostCallRecord("position", [("expect", 0), ("ret", {"x": 1.25, "y": -3})]),
        HostCallRecord("led", [("expect", 1), ("fail", "LNUM")])])
    live[0] = True
    tapped[(9, "position")](Call(0))
    assert capture.take()[0].ordered({9: 2})[0] == [2]
