"""Breakpoints in a replay: "seek to the next hit" re-executes the recorded steps with the
debugger's tracer and lands on the step in which the robot ran the line (real compiler, VM,
Kilobot world and recording)."""

from __future__ import annotations

from pathlib import Path

import pytest

from bbzide.cli import main
from bbzide.recording.reader import read_recording
from bbzide.recording.rebuild import RobotRebuilder
from bbzide.ui.replay_session import ReplaySession

#: Robot 1 runs line 5 only in its 4th control step; every robot runs line 3 every step.
SCRIPT = """\
var count = 0
function step() {
  count = count + 1
  if (id == 1 and count == 4) {
    log("four")
  }
}
"""


@pytest.fixture(scope="module")
def session(tmp_path_factory: pytest.TempPathFactory) -> ReplaySession:
    folder = tmp_path_factory.mktemp("replay-break")
    script = folder / "count.bzz"
    script.write_text(SCRIPT)
    path = folder / "count.rrd"
    assert main(["run", str(script), "--world", "kilobot", "--robots", "3", "--steps", "12",
                 "--record", str(path)]) == 0
    recording = read_recording(path)
    return ReplaySession(recording, RobotRebuilder(recording))


def test_the_next_hit_is_the_step_that_ran_the_line(session: ReplaySession) -> None:
    ids = [int(i) for i in session.recording.meta["robot_ids"]]
    hit = session.next_hit(5, session.first_step - 1)
    assert hit is not None
    step, index = hit
    assert ids[index] == 1
    count = dict(session.inspect(index, step).globals)["count"]
    assert count == "4"
    assert session.next_hit(5, step) is None  # it runs once
    # a line every robot runs: the very next step, the first robot in turn
    assert session.next_hit(3, step) == (step + 1, 0)
    # only robot 2: never line 5
    assert session.next_hit(5, session.first_step - 1, robots=[ids.index(2)]) is None


#: Robot 1 runs line 6 + 3 * (n - 3) only in the control step where its count is n (3..9).
ONCE_EACH = "var count = 0\nvar last = 0\nfunction step() {\n  count = count + 1\n" + "".join(
    f"  if (id == 1 and count == {n}) {{\n    last = {n}\n  }}\n" for n in range(3, 10)
) + "}\n"


def test_a_hit_in_a_keyframe_s_own_step_is_found(tmp_path: Path) -> None:
    """Keyframes every 3 steps: the line robot 1 first runs in the step of one of its
    keyframes is found there (that step is re-executed from the keyframe before)."""
    from bbzide.recording.recorder import MissionRecorder
    from bbzide.ui.world_adapter import WorldsBackend

    backend = WorldsBackend()
    script = tmp_path / "once.bzz"
    script.write_text(ONCE_EACH)
    _compiled, program = backend.compile(ONCE_EACH, script, "kilobot")
    handle = backend.create("kilobot", program, 3, 1)
    recorder = MissionRecorder(tmp_path / "once.rrd", handle.sim, handle.recordable,
                               keyframe_every=3, source_of=lambda _program: ONCE_EACH)
    for _ in range(12):
        handle.sim.step()
        recorder.record_step()
    recorder.close()
    recording = read_recording(recorder.path)
    session = ReplaySession(recording, RobotRebuilder(recording))
    ids = [int(i) for i in recording.meta["robot_ids"]]
    robot = ids.index(1)
    keyframe_steps = [k.step for k in recording.keyframes[robot]]
    counts = {step: int(dict(session.inspect(robot, step).globals)["count"])
              for step in range(recording.first_step, recording.last_step + 1)}
    # a keyframe step (not the first) in which robot 1's count is one of 3..9
    step = next(s for s in keyframe_steps[1:] if 3 <= counts[s] <= 9)
    line = 6 + 3 * (counts[step] - 3)
    assert session.next_hit(line, recording.first_step - 1, [robot]) == (step, robot)
    assert session.next_hit(line, recording.first_step - 1) == (step, robot)
    assert session.next_hit(line, step) is None  # it runs once
