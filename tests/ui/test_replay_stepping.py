"""Stepping in a replay: a debugger on the swarm rebuilt at a recorded step stops where the
live debugger stops from the same step of the same run (robot, control step, line, frames,
heap bytes), forward and back, and leaves the recording's own rebuilds alone (real compiler,
VM, Kilobot world and recorder)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest

from bbzide.debugger import Breakpoint, SwarmDebugger
from bbzide.recording.reader import read_recording
from bbzide.recording.recorder import MissionRecorder, RecordingError
from bbzide.ui.replay_session import ReplaySession
from bbzide.ui.world_adapter import WorldsBackend
from bbzide.vm.robot import Robot
from tests.debugger.swarms import ROBOTS, STEPPING_SCRIPT, TABLE

BACKEND = WorldsBackend()

RECORDED_STEPS = 8
#: The step the replay and the live run start stepping from (every robot hears the others).
START = 3


def live_swarm(script: Path, program: Any) -> Any:
    return BACKEND.create("kilobot", program, ROBOTS, 1, world_options=TABLE)


@pytest.fixture(scope="module")
def run(tmp_path_factory: pytest.TempPathFactory) -> tuple[ReplaySession, Path, Any]:
    folder = tmp_path_factory.mktemp("replay-stepping")
    script = folder / "swarm.bzz"
    script.write_text(STEPPING_SCRIPT)
    _compiled, program = BACKEND.compile(STEPPING_SCRIPT, script, "kilobot")
    handle = live_swarm(script, program)
    recorder = MissionRecorder(folder / "swarm.rrd", handle.sim, handle.recordable,
                               keyframe_every=3, source_of=lambda _program: STEPPING_SCRIPT)
    for _ in range(RECORDED_STEPS):
        handle.sim.step()
        recorder.record_step()
    recorder.close()
    return ReplaySession(read_recording(recorder.path)), script, program


def where(debugger: SwarmDebugger, stop: Any) -> tuple[Any, ...]:
    """What a user sees of a stop, and the stopped robot's exact state."""
    if stop is None:
        return (None,)
    robot = debugger.simulation.state_of(stop.robot).robot
    return (stop.robot, stop.step, stop.line, stop.reason, stop.frames,
            Robot.comparable(robot.snapshot()), bytes(robot.vm.heap.data))


def test_stepping_in_replay_stops_where_the_live_debugger_stops(
        run: tuple[ReplaySession, Path, Any]) -> None:
    session, script, program = run
    handle = live_swarm(script, program)
    for _ in range(START):
        handle.sim.step()
    live = SwarmDebugger(handle.sim)
    replay = session.debugger_at(START)
    commands = [
        ("breakpoints", [Breakpoint(9, robot=2)]),  # in the listener lambda
        ("run", 5), ("step_out", 2), ("breakpoints", []), ("step_into", 2),
        ("step_over", 2), ("step_into", 2), ("step_into", 2), ("step_out", 2),
        ("step_instruction", 2), ("step_over", 2), ("step_back", 2, "line"),
        ("step_back", 2, "line"), ("step_back", 2, "control_step"),
        ("breakpoints", [Breakpoint(15)]), ("run", 3), ("run", 3),
        ("run_back_to_previous_hit",), ("run", 3),
    ]
    stops = 0
    for command, *arguments in commands:
        if command == "breakpoints":
            live.breakpoints = replay.breakpoints = arguments[0]
            continue
        mine = where(replay, getattr(replay, command)(*arguments))
        theirs = where(live, getattr(live, command)(*arguments))
        assert mine == theirs, command
        stops += mine != (None,)
    assert stops >= 10
    # every robot, not only the stepped one, is where the live one is
    assert [Robot.comparable(s.robot.snapshot()) for s in replay.simulation.robots] == \
        [Robot.comparable(s.robot.snapshot()) for s in live.simulation.robots]


def test_stepping_leaves_the_recording_alone(run: tuple[ReplaySession, Path, Any]) -> None:
    session = run[0]
    before = [session.rebuilder.robot_at(i, START).snapshot() for i in range(ROBOTS)]
    replay = session.debugger_at(START)
    replay.breakpoints = [Breakpoint(15)]
    assert replay.run(2) is not None
    replay.breakpoints = []
    replay.run(2)
    assert [session.rebuilder.robot_at(i, START).snapshot() for i in range(ROBOTS)] == before


def test_stepping_past_the_recording_s_end_is_one_line(
        run: tuple[ReplaySession, Path, Any]) -> None:
    session = run[0]
    replay = session.debugger_at(session.last_step)
    with pytest.raises(RecordingError, match=f"ends at step {session.last_step}"):
        replay.run(1)
