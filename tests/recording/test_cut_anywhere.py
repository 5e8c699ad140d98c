"""A recording cut at any byte (a killed writer) opens up to its last complete step, or is refused.

A recording cut off by killing the process mid-run must be readable up to its last flushed
step. The writer can die anywhere: inside a data message, inside Rerun's end-of-stream message
(which carries the footer's index) or inside the footer itself. We cut one finished recording at
every few per cent and around every message boundary, and each cut must either open marked
truncated, with the full file's frames and rebuilt robots at every step it holds, or (only when
nothing complete survived) be refused with a `RecordingError` that says so.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from bbzide.recording.reader import FILE_HEADER_BYTES, MESSAGE_HEADER, read_recording
from bbzide.recording.rebuild import RobotRebuilder
from bbzide.recording.recorder import MissionRecorder, RecordingError
from tests.recording.doubles import ToyRobot
from tests.recording.test_recording import toy_swarm

#: Enough steps for several flushes (every 8 steps) and two keyframe periods (every 20).
STEPS = 40
#: A reload mid-run, so that a flush also holds an event.
RELOAD_AT = 13
#: Robots whose rebuilt VM state is compared at each cut (rebuilding all 12 at ~150 cuts is slow).
CHECKED_ROBOTS = (0, 7)


def message_boundaries(data: bytes) -> list[int]:
    """Offsets where each message starts, plus the end of the last one (and of the file)."""
    starts = [FILE_HEADER_BYTES]
    at = FILE_HEADER_BYTES
    while at + MESSAGE_HEADER.size <= len(data):
        kind, length = MESSAGE_HEADER.unpack_from(data, at)
        at += MESSAGE_HEADER.size + length
        starts.append(at)
        if kind == 0:  # end of stream: Rerun's footer follows
            break
    return [*starts, len(data)]


@pytest.fixture(scope="module")
def full(tmp_path_factory: pytest.TempPathFactory) -> dict:
    sim, recordable = toy_swarm()
    path = tmp_path_factory.mktemp("cut") / "mission.rrd"
    with MissionRecorder(path, sim, recordable, keyframe_every=20, flush_every=8) as recorder:
        for step in range(STEPS):
            if step == RELOAD_AT:  # an event: its text and its kind are two chunks of a flush
                sim.load_program(sim.robots[0].program, keep_state=True)
            sim.step()
            recorder.record_step()
    recording = read_recording(path)
    rebuilder = RobotRebuilder(recording, build=ToyRobot)
    snapshots = {(index, step): rebuilder.robot_at(index, step).snapshot()
                 for index in CHECKED_ROBOTS for step in recording.steps.tolist()}
    return {"data": path.read_bytes(), "recording": recording, "snapshots": snapshots}


def cut_points(data: bytes) -> list[int]:
    size = len(data)
    points = {size * percent // 100 for percent in range(0, 100, 3)}
    for boundary in message_boundaries(data):
        points.update((boundary - 1, boundary, boundary + 1, boundary + MESSAGE_HEADER.size + 3))
    points.update((size - 33, size - 32, size - 31, size - 8, size - 1))  # inside the footer
    return sorted(p for p in points if 0 < p < size)


def test_every_cut_opens_up_to_its_last_step_or_is_refused_clearly(full: dict,
                                                                  tmp_path: Path) -> None:
    data, whole = full["data"], full["recording"]
    opened: list[int] = []
    refused: list[int] = []
    for offset in cut_points(data):
        cut = tmp_path / f"cut{offset}.rrd"
        cut.write_bytes(data[:offset])
        try:
            recording = read_recording(cut)
        except RecordingError as error:
            assert "no complete" in str(error) or "not a Rerun recording" in str(error), \
                (offset, str(error))
            refused.append(offset)
            continue
        opened.append(offset)
        assert recording.truncated, offset
        assert recording.first_step == whole.first_step, offset
        assert recording.last_step <= whole.last_step, offset
        rows = len(recording.steps)
        np.testing.assert_array_equal(recording.positions, whole.positions[:rows])
        np.testing.assert_array_equal(recording.leds, whole.leds[:rows])
        assert recording.inputs == whole.inputs[:rows], offset
        assert recording.events == whole.events[:len(recording.events)], offset
        rebuilder = RobotRebuilder(recording, build=ToyRobot)
        for index in CHECKED_ROBOTS:
            step = recording.last_step
            assert rebuilder.robot_at(index, step).snapshot() == full["snapshots"][index, step], \
                (offset, index, step)
    assert opened, "no cut opened at all"
    assert not refused or max(refused) < min(opened), "a longer cut was refused"
    # A cut inside the end-of-stream message or the footer still holds every step.
    assert read_recording_last(tmp_path, data[: len(data) - 1]) == whole.last_step


def read_recording_last(folder: Path, data: bytes) -> int:
    path = folder / "tail.rrd"
    path.write_bytes(data)
    return read_recording(path).last_step
