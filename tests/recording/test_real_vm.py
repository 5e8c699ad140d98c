"""Recording real Buzz swarms (the VM's Robot in the worlds): replay equals the live run.

A Kilobot swarm runs the shipped examples on the real compiler, VM and world while being
recorded; the recording must show the live poses and heap figures at sampled steps, and a robot
rebuilt at random steps (keyframe + re-executed inputs) must equal the live robot byte for byte:
its `snapshot()`, its heap bytes, ROP, LSP, stack and pc.
"""

from __future__ import annotations

import gc
import random
import zlib
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from bbzide.recording import layout
from bbzide.recording.reader import read_recording
from bbzide.recording.rebuild import RobotRebuilder
from bbzide.recording.recorder import MissionRecorder, Recordable
from bbzide.vm.robot import Robot
from bbzide.worlds.commands import load_script
from bbzide.worlds.engine import Simulation
from bbzide.worlds.registry import WORLDS
from tests.recording.test_recording import record_steps

REPO = Path(__file__).resolve().parents[2]
ROBOTS = 9
STEPS = 60


def vm_state(robot: object) -> tuple:
    vm = robot.vm  # type: ignore[attr-defined]
    heap = vm.heap
    return (bytes(heap.data), heap.rtobj, heap.ltseg, vm.pc, vm.stackptr,
            list(vm.stack[: vm.stackptr + 1]),
            Robot.comparable(robot.snapshot()))  # type: ignore[attr-defined]


#: (script, asynchronous, format): the lockstep engine hands the recorder a step's deliveries
#: as columns (`step_deliveries`); the asynchronous one calls each robot's `receive`, which the
#: recorder then hooks. Format 3 (the full input layout, zstd blobs) is written as an older
#: bbzide wrote it, and must still rebuild exactly.
CASES = [("gradient.bzz", False, layout.FORMAT_VERSION), ("firefly.bzz", False,
                                                          layout.FORMAT_VERSION),
         ("gradient.bzz", True, layout.FORMAT_VERSION), ("gradient.bzz", False, 3)]


@pytest.fixture(scope="module", params=CASES,
                ids=["gradient", "firefly", "gradient-async", "gradient-format-3"])
def recorded(request: pytest.FixtureRequest, tmp_path_factory: pytest.TempPathFactory) -> dict:
    spec = WORLDS["kilobot"]
    script, asynchronous, version = request.param
    program = load_script(REPO / "examples/kilobot" / script, spec.host_names, [])
    recordable = Recordable()
    sim = Simulation("kilobot", program, robots=ROBOTS, seed=5,
                     robot_factory=recordable.factory, asynchronous=asynchronous)
    path = tmp_path_factory.mktemp("real") / "mission.rrd"
    live: dict[int, dict] = {}

    def note() -> None:
        live[sim.step_count] = {
            "positions": sim.positions.copy(),
            "used": [s.robot.vm.heap.used_bytes() for s in sim.robots],
            "states": [vm_state(s.robot) for s in sim.robots],
        }

    newest, flat = layout.FORMAT_VERSION, Robot.snapshot
    layout.FORMAT_VERSION = version  # (module-scoped: no monkeypatch) what the recorder writes
    if version < 4:  # and the keyframes as formats 2 and 3 held them: pickled
        Robot.snapshot = Robot.pickled_snapshot  # type: ignore[method-assign]
    try:
        with MissionRecorder(path, sim, recordable, keyframe_every=10) as recorder:
            note()
            for _ in range(STEPS):
                sim.step()
                recorder.record_step()
                note()
    finally:
        layout.FORMAT_VERSION, Robot.snapshot = newest, flat  # type: ignore[method-assign]
    assert not sim.failures, [str(s.failure) for s in sim.failures]
    return {"recording": read_recording(path), "live": live}


def decoded_inputs(recording: Any) -> list[dict[int, Any]]:
    """Every step's decoded inputs, read the way the recording's format says."""
    from bbzide.recording.compression import decompress
    from bbzide.recording.input_log import decode_step

    version = recording.meta["version"]
    return [decode_step(decompress(blob) if layout.inputs_compressed(version) else blob,
                        layout=layout.input_layout(version)) if blob else {}
            for blob in recording.inputs]


def test_replay_shows_live_poses_and_heap_use(recorded: dict) -> None:
    recording, live = recorded["recording"], recorded["live"]
    for step in range(0, STEPS + 1, 9):
        row = recording.row(step)
        np.testing.assert_allclose(recording.positions[row], live[step]["positions"], atol=1e-6)
        assert recording.heap["used"][row].tolist() == live[step]["used"]


def test_rebuilt_vm_is_byte_identical_at_random_steps(recorded: dict) -> None:
    recording, live = recorded["recording"], recorded["live"]
    rebuilder = RobotRebuilder(recording)
    rng = random.Random(11)
    for _ in range(20):
        step = rng.randint(0, STEPS)
        index = rng.randrange(ROBOTS)
        rebuilt = vm_state(rebuilder.robot_at(index, step))
        expected = live[step]["states"][index]
        assert rebuilt[:6] == expected[:6], (index, step)
        assert zlib.crc32(rebuilt[6]) == zlib.crc32(expected[6]), (index, step)


#: A stigmergy created in `step` (after boot) on a host answer: its C closures are registered
#: in the live VM at that moment, so a robot rebuilt from a later keyframe must get them too.
LATE_STIGMERGY = """
var s = nil
function init() { }
function step() {
  if (s == nil) {
    if (rand() > 100) { s = stigmergy.create(1) }
  }
  if (s != nil) { n = s.size() + rand() }
}
"""


def test_closures_created_after_boot_survive_a_rebuild(tmp_path: Path) -> None:
    from bbzide import compiler

    spec = WORLDS["kilobot"]
    script = tmp_path / "late.bzz"
    script.write_text(LATE_STIGMERGY)
    program = compiler.compile_file(
        str(script), string_table=compiler.bittybuzz_string_table(list(spec.host_names))
    ).to_bbo()
    recordable = Recordable()
    sim = Simulation("kilobot", program, robots=6, seed=2, robot_factory=recordable.factory)
    path = tmp_path / "late.rrd"
    with MissionRecorder(path, sim, recordable, keyframe_every=5) as recorder:
        live = record_steps(sim, recorder, 24, lambda: [vm_state(s.robot) for s in sim.robots])
    assert not sim.failures
    rebuilder = RobotRebuilder(read_recording(path))
    for index in range(6):
        for step in (12, 24):
            assert vm_state(rebuilder.robot_at(index, step))[:6] == live[step][index][:6]


#: A top level and an `init` that call host functions: a reboot's calls must not be taken
#: for inputs of the next step (the rebuilt robot starts from the boot keyframe).
BOOT_CALLS = """
var seen = rand()
function init() { seen = seen + rand() }
function step() { seen = seen + rand() }
"""


def test_a_program_reload_mid_recording_keyframes_the_rebooted_robots(tmp_path: Path) -> None:
    """The robots stay plain Robots; their `on_phase` hook tells the recorder when a reboot
    ends, so it keyframes the fresh state, and the host calls the boot makes are not
    recorded as a step's inputs: robots rebuilt after the reload equal the live ones. The
    watched global `seen` exists only in the second program: its label is recorded from the
    reload on (the recorder looks at which programs can have it whenever robots reboot)."""
    from bbzide import compiler

    spec = WORLDS["kilobot"]
    first = load_script(REPO / "examples/kilobot/gradient.bzz", spec.host_names, [])
    script = tmp_path / "boot.bzz"
    script.write_text(BOOT_CALLS)
    second = compiler.compile_file(
        str(script), string_table=compiler.bittybuzz_string_table(list(spec.host_names))
    ).to_bbo()
    recordable = Recordable()
    sim = Simulation("kilobot", first, robots=5, seed=3, robot_factory=recordable.factory,
                     watch=("seen",))
    assert all(type(s.robot) is Robot for s in sim.robots)
    path = tmp_path / "reload.rrd"
    live = {}
    seen = {}
    with MissionRecorder(path, sim, recordable, keyframe_every=50) as recorder:
        for _ in range(30):
            if sim.step_count == 12:
                sim.load_program(second, keep_state=True)
            sim.step()
            recorder.record_step()
            live[sim.step_count] = [vm_state(s.robot) for s in sim.robots]
            seen[sim.step_count] = [str(s.global_value("seen")) for s in sim.robots]
    assert not sim.failures
    recording = read_recording(path)
    assert recording.labels["seen"][recording.row(10)].tolist() == [""] * 5
    assert recording.labels["seen"][recording.row(30)].tolist() == seen[30] != ["None"] * 5
    assert [k.step for k in recording.keyframes[0]] == [0, 12]
    assert any(e.kind == "program" and e.step == 12 for e in recording.events)
    rebuilder = RobotRebuilder(recording)
    for index in range(5):
        for step in (10, 13, 30):
            assert vm_state(rebuilder.robot_at(index, step))[:6] == live[step][index][:6], (
                index, step)


def test_latched_led_stays_latched_and_out_of_the_input_log(recorded: dict) -> None:
    """A Kilobot's `led` is a latched host function: in a recorded swarm it stays one (the
    compiled swarm step keeps running it), so its happy-path calls are not in the input log
    (format 3), the meta says so, and the rebuilds above still match the live robots."""
    recording = recorded["recording"]
    assert all(dict(pairs) == {"led": 1} for pairs in recording.meta["latched"])
    names = {call.name for step in decoded_inputs(recording) for inputs in step.values()
             for call in inputs.host_calls}
    assert "led" not in names


def test_kilobot_inputs_are_written_compact_and_older_formats_as_they_were(
        recorded: dict) -> None:
    """Format 4 writes a Kilobot step's messages without a lengths column (every payload is
    as long) and without bearing columns (a Kilobot senses no bearing), a flush's blobs as one
    zstd frame that the reader opens (so each step's blob comes back raw), and flat
    keyframes; a format 3 recording holds a zstd frame per step in the full layout and pickled
    keyframes. Either decodes to the same kind of messages: 8-byte payloads, zero bearings."""
    recording = recorded["recording"]
    blobs = [blob for blob in recording.inputs if blob]
    zstd_magic = b"\x28\xb5\x2f\xfd"
    snapshot = RobotRebuilder(recording).snapshot(1, recording.keyframes[1][-1])
    assert snapshot.startswith(b"BZR" if recording.meta["version"] >= 4 else b"\x80")
    if recording.meta["version"] >= 4:
        assert not any(blob.startswith(zstd_magic) for blob in blobs)
        assert {blob[2:4] for blob in blobs} <= {b"\x00\x08", b"\x00\x00"}  # flags, length
    else:
        assert all(blob.startswith(zstd_magic) for blob in blobs)
    received = [inputs for step in decoded_inputs(recording) for inputs in step.values()
                if inputs.payloads]
    assert {len(p) for inputs in received for p in inputs.payloads} == {8}
    assert all(inputs.situation[1::3].tolist() == [0.0] * len(inputs.payloads)
               for inputs in received)
    assert len(received) > STEPS


def test_a_reload_whose_boot_fails_is_keyframed_failed(tmp_path: Path) -> None:
    """A program whose top level fails (a VM error during boot) loaded mid-recording: no hook
    says the boot ended well, so the recorder keyframes those robots at its next step; the
    error is an event, and robots rebuilt after it equal the live failed ones."""
    from bbzide import compiler

    spec = WORLDS["kilobot"]
    first = load_script(REPO / "examples/kilobot/gradient.bzz", spec.host_names, [])
    script = tmp_path / "broken.bzz"
    script.write_text("x = rand() / 0\nfunction init() { }\nfunction step() { }\n")
    broken = compiler.compile_file(
        str(script), string_table=compiler.bittybuzz_string_table(list(spec.host_names))
    ).to_bbo()
    recordable = Recordable()
    sim = Simulation("kilobot", first, robots=3, seed=3, robot_factory=recordable.factory)
    path = tmp_path / "broken.rrd"
    live = {}
    with MissionRecorder(path, sim, recordable, keyframe_every=50) as recorder:
        for _ in range(12):
            if sim.step_count == 6:
                sim.load_program(broken, keep_state=True)
            sim.step()
            recorder.record_step()
            live[sim.step_count] = [Robot.comparable(s.robot.snapshot()) for s in sim.robots]
    assert len(sim.failures) == 3
    recording = read_recording(path)
    assert [k.step for k in recording.keyframes[0]] == [0, 7]
    assert sum(e.kind == "error" for e in recording.events) == 3
    rebuilder = RobotRebuilder(recording)
    for index in range(3):
        for step in (5, 7, 12):
            assert Robot.comparable(rebuilder.robot_at(index, step).snapshot()) == \
                live[step][index], (index, step)


def test_a_warmed_up_replay_rebuilds_every_robot_exactly(recorded: dict) -> None:
    """The replay's warm-up (every robot booted and re-executed over its first keyframe span,
    before any click) leaves each rebuild robot where the next seek starts from: seeks before,
    inside and after that span still give the live VM byte for byte."""
    from bbzide.ui.replay_session import ReplaySession

    recording, live = recorded["recording"], recorded["live"]
    session = ReplaySession(recording)
    session.warm_up()
    gc.unfreeze()  # warm_up moves what lives now out of the collector's passes: undo it here
    rebuilder = session.rebuilder
    for index in range(ROBOTS):
        frames = recording.keyframes[index]
        # each robot booted, and cached at the step before its second keyframe
        assert rebuilder._cache[index][0] == frames[1].step - 1
        for step in (frames[0].step, frames[1].step - 1, frames[1].step + 3, STEPS):
            rebuilt = vm_state(rebuilder.robot_at(index, step))
            assert rebuilt[:6] == live[step]["states"][index][:6], (index, step)


def test_warm_up_of_one_robot_then_the_rest(recorded: dict) -> None:
    """What the replay app does: one robot before it serves the page, the rest afterwards."""
    from bbzide.ui.replay_session import ReplaySession

    session = ReplaySession(recorded["recording"])
    session.warm_up(count=1)
    assert {index for index, _ in session.rebuilder._booted} == {0}
    session.warm_up()
    gc.unfreeze()
    assert {index for index, _ in session.rebuilder._booted} == set(range(ROBOTS))


def test_a_recording_of_pickled_snapshots_still_rebuilds_exactly(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """Recordings of formats 2 and 3 hold pickled keyframes (the layout before the flat one,
    vm/snapshot_layout.py): recorded that way, robots still rebuild to the live state."""
    spec = WORLDS["kilobot"]
    program = load_script(REPO / "examples/kilobot/gradient.bzz", spec.host_names, [])
    recordable = Recordable()
    sim = Simulation("kilobot", program, robots=4, seed=7, robot_factory=recordable.factory)
    path = tmp_path / "old.rrd"
    with monkeypatch.context() as patch:
        patch.setattr(Robot, "snapshot", Robot.pickled_snapshot)
        with MissionRecorder(path, sim, recordable, keyframe_every=10) as recorder:
            live = record_steps(sim, recorder, 25, lambda: [
                Robot.comparable(s.robot.snapshot()) for s in sim.robots])
    recording = read_recording(path)
    rebuilder = RobotRebuilder(recording)
    assert rebuilder.snapshot(1, recording.keyframes[1][-1]).startswith(b"\x80")
    for index, step in ((0, 3), (1, 12), (2, 20), (3, 25)):
        rebuilt = rebuilder.robot_at(index, step)
        assert rebuilt.snapshot().startswith(b"BZR")  # written flat again once restored
        assert Robot.comparable(rebuilt.snapshot()) == live[step][index], (index, step)
