"""The per-step input log's bytes: every kind of input survives encode -> decode, and decoding
one robot's record (what a seek does) gives exactly that robot's inputs."""

from __future__ import annotations

import pytest

from bbzide.vm.input_log import (
    HostCallRecord,
    InputLogError,
    StepInputs,
    decode_step,
    encode_step,
)


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


def test_every_input_round_trips_and_one_robot_decodes_alone() -> None:
    records = [(index, inputs_of(index)) for index in (0, 1, 2, 4, 7, 11)]
    data = encode_step(records)
    assert decode_step(data) == dict(records)
    for index, inputs in records:
        assert decode_step(data, only=index) == {index: inputs}
    assert decode_step(data, only=3) == {}  # a robot with no record this step


def test_a_torn_record_is_an_error_even_when_skipped() -> None:
    data = encode_step([(0, inputs_of(1)), (1, inputs_of(2))])
    with pytest.raises(InputLogError):
        decode_step(data[:-3], only=1)
    with pytest.raises(InputLogError):
        decode_step(data[:20], only=1)  # cut inside robot 0's record, which is stepped over


def test_a_negative_zero_bearing_keeps_its_sign() -> None:
    """Situated data is stored as its exact bits: a bbzfloat conversion keeps the sign of
    -0.0, so it must come back as -0.0."""
    import math

    inputs = StepInputs.of([(b"\x00\x01\x00", 2.0, -0.0, 0.0)], stepped=True)
    (message, distance, azimuth, elevation), = decode_step(encode_step([(5, inputs)]))[5].received
    assert (message, distance, elevation) == (b"\x00\x01\x00", 2.0, 0.0)
    assert math.copysign(1.0, azimuth) == -1.0


class _Inner:
    """A firmware loop that notes how its messages arrived."""

    def __init__(self, bulk: bool) -> None:
        self.got: list[tuple] = []
        if bulk:
            self.receive_all = lambda deliveries: self.got.append(("all", list(deliveries)))

    def receive(self, message: bytes, distance: float, azimuth: float, elevation: float) -> None:
        self.got.append(("one", message, distance, azimuth, elevation))


def test_bulk_deliveries_are_noted_and_reach_the_robot_its_way() -> None:
    """The engine hands a step's messages over in one `receive_all` call when the robot has
    one: the capture must note them (forwarding the call unnoted would make every rebuild
    diverge) and pass them on as the robot takes them."""
    from bbzide.vm.input_log import CapturingRobot, HostCallTap

    deliveries = [(7, b"\x00\x07\x00\x01", 1.5, -0.25, 0.0), (9, b"\x01\x09", 3.0, 0.5, 0.125)]
    for bulk in (True, False):
        inner = _Inner(bulk)
        robot = CapturingRobot(inner, HostCallTap())
        robot.capturing = True
        robot.receive_all(deliveries)
        assert robot.take_inputs().received == [d[1:] for d in deliveries]
        assert inner.got == ([("all", deliveries)] if bulk
                             else [("one", *d[1:]) for d in deliveries])
