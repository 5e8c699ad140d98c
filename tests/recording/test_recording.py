"""Recording and reading back a swarm on the real engine and Kilobot world (toy firmware).

The firmware is `doubles.ToyRobot`, whose state depends on every outside input (messages with
situated data, host-function results and failures), so these tests pin the recorder's
mechanics: what a replay shows equals the live run, the rebuilt robot equals the live one
byte for byte, and damaged, foreign or existing files are handled as the issue asks.
"""

from __future__ import annotations

import os
import random
import signal
import subprocess
import sys
import textwrap
from collections.abc import Callable
from pathlib import Path
from typing import TypeVar

import numpy as np
import pytest

from bbzide.recording.reader import read_recording, rrd_frames
from bbzide.recording.rebuild import RobotRebuilder
from bbzide.recording.recorder import MissionRecorder, Recordable, RecordingError
from bbzide.worlds.commands import load_script
from bbzide.worlds.engine import Simulation
from bbzide.worlds.registry import WORLDS
from tests.recording.doubles import ToyRobot

T = TypeVar("T")

REPO = Path(__file__).resolve().parents[2]
ROBOTS = 12
STEPS = 120


def toy_swarm(seed: int = 3) -> tuple[Simulation, Recordable]:
    spec = WORLDS["kilobot"]
    program = load_script(REPO / "examples/kilobot/gradient.bzz", spec.host_names, [])
    recordable = Recordable(build=ToyRobot)
    sim = Simulation("kilobot", program, robots=ROBOTS, seed=seed,
                     robot_factory=recordable.factory, watch=())
    return sim, recordable


def record_steps(sim: Simulation, recorder: MissionRecorder, steps: int,
                 note: Callable[[], T]) -> dict[int, T]:
    """Step and record the swarm `steps` times; what `note()` returns after each step, by the
    step it saw (the live side a rebuilt recording is compared with)."""
    live = {}
    for _ in range(steps):
        sim.step()
        recorder.record_step()
        live[sim.step_count] = note()
    return live


@pytest.fixture(scope="module")
def recorded(tmp_path_factory: pytest.TempPathFactory) -> dict:
    """A recorded run (started at step 4) and the live figures at every step."""
    sim, recordable = toy_swarm()
    sim.run(4)
    path = tmp_path_factory.mktemp("rec") / "mission.rrd"
    live: dict[int, dict] = {}

    def note() -> None:
        live[sim.step_count] = {
            "positions": sim.positions.copy(), "leds": sim.leds.copy(),
            "snapshots": [s.robot.snapshot() for s in sim.robots],
            "rop": [s.robot.vm.heap.rtobj for s in sim.robots],
            "gc": [s.robot.vm.heap.gc_runs for s in sim.robots],
            "sent": sim.stats.sent.copy(), "links": list(sim.links),
        }

    with MissionRecorder(path, sim, recordable, keyframe_every=10, flush_every=16) as recorder:
        note()
        for step in range(STEPS):
            if step == 50:
                sim.load_program(sim.robots[0].program, keep_state=True)  # reboot mid-run
                note()
            sim.step()
            recorder.record_step()
            note()
    return {"path": path, "live": live, "recording": read_recording(path)}


def test_replay_shows_the_live_poses_leds_heap_and_traffic(recorded: dict) -> None:
    recording, live = recorded["recording"], recorded["live"]
    assert (recording.first_step, recording.last_step) == (4, 4 + STEPS)
    assert not recording.truncated
    for step in range(recording.first_step, recording.last_step + 1, 7):
        row = recording.row(step)
        np.testing.assert_allclose(recording.positions[row], live[step]["positions"], atol=1e-6)
        np.testing.assert_array_equal(recording.leds[row] / 255.0, live[step]["leds"])
        assert recording.heap["rop"][row].tolist() == live[step]["rop"]
        assert recording.heap["gc_runs"][row].tolist() == live[step]["gc"]
        assert recording.messages["sent"][row].tolist() == live[step]["sent"].tolist()
        assert sorted(map(tuple, recording.links[row].tolist())) == sorted(live[step]["links"])


def test_rebuilt_robot_is_byte_identical_at_random_steps(recorded: dict) -> None:
    recording, live = recorded["recording"], recorded["live"]
    rebuilder = RobotRebuilder(recording, build=ToyRobot)
    rng = random.Random(7)
    steps = rng.sample(range(recording.first_step, recording.last_step + 1), 25)
    for step in sorted(steps) + steps:  # forwards (reusing the cache) and in random order
        index = rng.randrange(ROBOTS)
        robot = rebuilder.robot_at(index, step)
        assert robot.snapshot() == live[step]["snapshots"][index], (index, step)


def test_keyframes_cover_start_period_and_reboot(recorded: dict) -> None:
    keyframes = [k.step for k in recorded["recording"].keyframes[0]]
    assert keyframes[0] == 4 and 14 in keyframes and 54 in keyframes   # reboot at step 54
    kinds = [e.kind for e in recorded["recording"].events]
    assert kinds.count("program") == 2  # recording start and the reload
    errors = [e for e in recorded["recording"].events if e.kind == "error"]
    assert len(errors) == 1 and errors[0].robot == 7 and "MEM" in errors[0].text
    row = recorded["recording"].row(errors[0].step)
    assert recorded["recording"].failed[row].tolist() == [i == 7 for i in range(ROBOTS)]
    assert not recorded["recording"].failed[row - 1].any()


def test_existing_file_needs_force(recorded: dict, tmp_path: Path) -> None:
    path = tmp_path / "taken.rrd"
    path.write_bytes(b"precious")
    sim, recordable = toy_swarm()
    with pytest.raises(RecordingError, match="--force"):
        MissionRecorder(path, sim, recordable)
    assert path.read_bytes() == b"precious"
    with MissionRecorder(path, sim, recordable, force=True) as recorder:
        sim.step()
        recorder.record_step()
    assert read_recording(path).last_step == 1


def test_foreign_and_corrupt_files_are_user_errors(recorded: dict, tmp_path: Path) -> None:
    foreign = tmp_path / "notes.rrd"
    foreign.write_text("these are my notes, not a recording\n")
    with pytest.raises(RecordingError, match="not a Rerun recording"):
        read_recording(foreign)
    with pytest.raises(RecordingError, match="no such recording"):
        read_recording(tmp_path / "missing.rrd")
    other = tmp_path / "other.rrd"
    import rerun as rr

    stream = rr.RecordingStream("someone-else")
    stream.save(str(other))
    stream.log("points", rr.Points3D([[0, 0, 0]]))
    stream.flush()
    stream.disconnect()
    with pytest.raises(RecordingError, match="not one of bbzide's"):
        read_recording(other)
    data = recorded["path"].read_bytes()
    header_only = tmp_path / "header.rrd"
    header_only.write_bytes(data[:30])
    with pytest.raises(RecordingError, match="no complete"):
        read_recording(header_only)


def test_torn_tail_reads_up_to_the_last_complete_step(recorded: dict, tmp_path: Path) -> None:
    data = recorded["path"].read_bytes()
    complete, ended = rrd_frames(data)
    assert ended
    previous_last = None
    for fraction in (0.9, 0.6, 0.35):
        cut = tmp_path / f"cut{fraction}.rrd"
        cut.write_bytes(data[: int(complete * fraction)])
        recording = read_recording(cut)
        assert recording.truncated
        assert recording.first_step == 4 and recording.last_step < 4 + STEPS
        if previous_last is not None:
            assert recording.last_step <= previous_last
        previous_last = recording.last_step
        live = recorded["live"][recording.last_step]
        np.testing.assert_allclose(recording.positions[-1], live["positions"], atol=1e-6)
        robot = RobotRebuilder(recording, build=ToyRobot).robot_at(5, recording.last_step)
        assert robot.snapshot() == live["snapshots"][5]


def test_killed_writer_leaves_a_readable_file(tmp_path: Path) -> None:
    """SIGKILL a recording process mid-run; the file reads up to its last flushed step."""
    path = tmp_path / "killed.rrd"
    script = textwrap.dedent(f"""
        import sys, time
        sys.path.insert(0, {str(REPO)!r})
        from tests.recording.test_recording import toy_swarm
        from bbzide.recording.recorder import MissionRecorder
        sim, recordable = toy_swarm()
        recorder = MissionRecorder({str(path)!r}, sim, recordable, flush_every=10)
        for step in range(100000):
            sim.step()
            recorder.record_step()
            if step == 35:
                print("flushed", flush=True)
    """)
    env = dict(os.environ, PYTHONPATH=str(REPO))
    process = subprocess.Popen([sys.executable, "-c", script], stdout=subprocess.PIPE, env=env)
    try:
        assert process.stdout is not None
        assert process.stdout.readline().strip() == b"flushed"
    finally:
        process.send_signal(signal.SIGKILL)
        process.wait()
    recording = read_recording(path)
    assert recording.truncated
    assert recording.last_step >= 30
    RobotRebuilder(recording, build=ToyRobot).robot_at(2, recording.last_step)


def test_crafted_keyframe_is_refused_not_unpickled() -> None:
    import pickle

    from bbzide.recording.rebuild import check_snapshot
    from bbzide.vm.profiles import PROFILES
    from bbzide.vm.vm import VM

    class Payload:
        def __reduce__(self) -> tuple:
            return (os.system, ("echo crafted",))

    check_snapshot(VM(PROFILES["kilobot"], 3).snapshot(), "a real VM snapshot")  # accepted
    vm = VM(PROFILES["kilobot"], 3)
    check_snapshot(vm.pickled_snapshot(), "a pickled VM snapshot")  # formats 2 and 3
    for crafted in (pickle.dumps(Payload()), pickle.dumps((1, [pickle.dumps(Payload())]))):
        with pytest.raises(RecordingError, match="not a VM snapshot"):
            check_snapshot(crafted, "keyframe")
    flat = vm.snapshot()  # the flat layout: damaged bytes are refused before any restore
    with pytest.raises(RecordingError, match="damaged"):
        check_snapshot(flat[:-3], "keyframe")


def test_a_recording_of_another_format_version_is_refused(tmp_path: Path,
                                                          monkeypatch: pytest.MonkeyPatch) -> None:
    """Format 1 (packed messages, XOR deltas, zlib) cannot be rebuilt by this reader."""
    from bbzide.recording import layout

    for version, word in ((layout.OLDEST_READABLE - 1, "older"),
                          (layout.FORMAT_VERSION + 1, "newer")):
        path = tmp_path / f"v{version}.rrd"
        sim, recordable = toy_swarm()
        with monkeypatch.context() as patched:
            patched.setattr(layout, "FORMAT_VERSION", version)
            with MissionRecorder(path, sim, recordable) as recorder:
                sim.step()
                recorder.record_step()
        with pytest.raises(RecordingError, match=f"written by an {word}|written by a {word}"):
            read_recording(path)


def test_passive_bodies_are_recorded_without_a_vm(tmp_path: Path) -> None:
    """A swarm with passive bodies (a group without a program: no firmware loop) records:
    their heap figures are zero and marked as having no VM, the programmed robots rebuild
    exactly, and a passive body has nothing to rebuild."""
    from bbzide.worlds.engine import RobotGroup

    spec = WORLDS["kilobot"]
    program = load_script(REPO / "examples/kilobot/gradient.bzz", spec.host_names, [])
    recordable = Recordable(build=ToyRobot)
    sim = Simulation("kilobot", seed=4, robot_factory=recordable.factory, watch=(),
                     groups=[RobotGroup(4, program), RobotGroup(2, None)])
    path = tmp_path / "passive.rrd"
    with MissionRecorder(path, sim, recordable, keyframe_every=7) as recorder:
        live = record_steps(sim, recorder, 30,
                            lambda: [s.robot.snapshot() for s in sim.robots[:4]])
    recording = read_recording(path)
    assert recording.heap["rop"][:, 4:].max() == 0 and recording.heap["rop"][:, :4].min() > 0
    rebuilder = RobotRebuilder(recording, build=ToyRobot)
    assert not rebuilder.has_vm(5)
    for index in range(4):
        for step in (9, 23, 30):
            assert rebuilder.robot_at(index, step).snapshot() == live[step][index]


def test_a_format_2_recording_still_opens_and_rebuilds(tmp_path: Path,
                                                       monkeypatch: pytest.MonkeyPatch) -> None:
    """Format 3 only added the latched host functions (none in this toy swarm), so a file
    that says version 2 reads and rebuilds as before."""
    from bbzide.recording import layout

    path = tmp_path / "v2.rrd"
    sim, recordable = toy_swarm()
    with monkeypatch.context() as patched:
        patched.setattr(layout, "FORMAT_VERSION", 2)
        with MissionRecorder(path, sim, recordable, keyframe_every=5) as recorder:
            live = record_steps(sim, recorder, 8, lambda: sim.robots[2].robot.snapshot())
    recording = read_recording(path)
    assert recording.meta["version"] == 2
    assert RobotRebuilder(recording, build=ToyRobot).robot_at(2, 8).snapshot() == live[8]


def test_overlays_looked_at_less_often_while_unchanged_and_at_the_last_step(
        tmp_path: Path) -> None:
    """Unchanged overlays are looked at after 10, 20, 40, then 80 steps; a change is recorded
    at the next look (and brings back every 10 steps), and closing looks at the last step."""
    from bbzide.recording.recorder import OVERLAY_EVERY, OVERLAY_EVERY_MAX

    sim, recordable = toy_swarm()
    looks: list[int] = []

    def overlays() -> dict:
        looks.append(sim.step_count)
        level = 0 if sim.step_count < 200 else 1 if sim.step_count < 333 else 2
        return {"light": {"bounds": [0, 0, 1, 1], "values": [[level]]}}

    sim.world.overlays = overlays  # type: ignore[method-assign]
    path = tmp_path / "overlays.rrd"
    with MissionRecorder(path, sim, recordable) as recorder:
        for _ in range(337):
            sim.step()
            recorder.record_step()
    recording = read_recording(path)
    gaps = np.diff(looks[:6]).tolist()
    assert looks[0] == 0 and gaps == [10, 20, 40, 80, 80]  # a replay starts with overlays
    changes = [(step, o["light"]["values"][0][0]) for step, o in recording.overlays]
    assert changes[0] == (0, 0) and recording.overlays_at(0)["light"]["values"] == [[0]]
    # changed at step 200: seen at the next look, at most OVERLAY_EVERY_MAX steps late
    assert changes[1][1] == 1 and 200 <= changes[1][0] < 200 + OVERLAY_EVERY_MAX
    assert looks[looks.index(changes[1][0]) + 1] == changes[1][0] + OVERLAY_EVERY
    assert changes[-1] == (337, 2)  # changed at step 333, between looks: the last step's
    assert recording.overlays_at(recording.last_step)["light"]["values"] == [[2]]


def test_a_flush_of_inputs_opens_into_steps_and_a_damaged_one_is_refused() -> None:
    """Format 4 stores a flush's input blobs as one zstd frame with the steps and where each
    step's bytes end; the reader turns it back into one blob per step, and a frame that does
    not decompress, or whose ends do not fit it, is a corrupt recording."""
    import pyarrow as pa

    from bbzide.recording import layout
    from bbzide.recording.compression import INPUT_LEVEL, Compressor
    from bbzide.recording.reader import _input_steps

    blobs = [b"", b"first step", b"", b"the third"]
    frame = Compressor(INPUT_LEVEL).compress(b"".join(blobs))
    ends = np.cumsum([len(b) for b in blobs]).tolist()

    def columns(frame: bytes, ends: list[int]) -> dict:
        row = np.array([40])  # the flush's first step
        return {(layout.INPUTS, "inputs"): [(row, pa.array([[frame]]))],
                (layout.INPUTS, "input_steps"): [(row, pa.array([[40, 41, 42, 43]]))],
                (layout.INPUTS, "input_ends"): [(row, pa.array([ends]))]}

    (steps, opened), = _input_steps(columns(frame, ends), Path("x.rrd"))
    assert steps.tolist() == [40, 41, 42, 43] and opened == blobs
    for damaged in (columns(frame[:-2], ends), columns(frame, [*ends[:-1], ends[-1] + 1]),
                    columns(frame, ends[:-1]), columns(frame, [0, 12, 10, ends[-1]])):
        with pytest.raises(RecordingError, match="corrupt"):
            _input_steps(damaged, Path("x.rrd"))


def test_a_flush_window_that_grows_keeps_every_step(tmp_path: Path,
                                                    monkeypatch: pytest.MonkeyPatch) -> None:
    """A window whose arrays start shorter than the steps it buffers (a `flush_every` above
    `WINDOW_ROWS`) doubles them and keeps what was written: every step reads back."""
    from bbzide.recording import recorder as recorder_module

    monkeypatch.setattr(recorder_module, "WINDOW_ROWS", 3)
    sim, recordable = toy_swarm(seed=5)
    path = tmp_path / "grown.rrd"
    with MissionRecorder(path, sim, recordable, flush_every=16) as recorder:
        live = record_steps(sim, recorder, 40, lambda: (
            sim.positions.copy(), sim.headings.copy(), [s.robot.vm.heap.rtobj for s in sim.robots]
        ))
    recording = read_recording(path)
    assert recording.last_step == 40
    for step, (positions, headings, rop) in live.items():
        row = recording.row(step)
        np.testing.assert_allclose(recording.positions[row], positions, atol=1e-6)
        np.testing.assert_allclose(recording.headings[row], headings, atol=1e-6)
        assert recording.heap["rop"][row].tolist() == rop
