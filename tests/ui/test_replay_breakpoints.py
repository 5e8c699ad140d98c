"""Breakpoints in a replay: "seek to the next hit" re-executes the recorded steps with the
debugger's tracer and lands on the step in which the robot ran the line (real compiler, VM,
Kilobot world and recording)."""

from __future__ import annotations

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
