"""The inspector's runtime rows on real Kilobot VMs: neighbors, swarm memberships, pitfalls.

A script joins swarm 3 and broadcasts a table every step. The inspector must list each robot's
neighbors as its VM holds them (ids of the robots within IR range, distances in mm as the
world measured them), its swarm membership (not the `swarm` library table), and warn that a
table goes out as its type only (BittyBuzz's 9-byte payload carries one 3-byte value).
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np

from bbzide.ui.world_adapter import WorldsBackend

REPO = Path(__file__).resolve().parents[2]

BACKEND = WorldsBackend()

SCRIPT = """
got = 0
function init() {
  s = swarm.create(3)
  s.join()
  neighbors.listen("t", function(vid, value, rid) { got = got + 1 })
}
function step() {
  neighbors.broadcast("t", TABLE)
}
"""


def run(tmp_path: Path, value: str, robots: int = 4) -> object:
    path = tmp_path / "probe.bzz"
    text = SCRIPT.replace("TABLE", value)
    path.write_text(text)
    _, program = BACKEND.compile(text, path, "kilobot")
    sim = BACKEND.create("kilobot", program, robots, 1)
    for _ in range(3):
        sim.step()
    return sim


def test_neighbors_swarms_and_the_table_warning(tmp_path: Path) -> None:
    sim = run(tmp_path, "{.a = 1}")
    view = sim.inspect(0)
    frame = sim.frame()
    distances = np.linalg.norm(frame.positions - frame.positions[0], axis=1)
    comm_range = sim.geometry().comm_range
    in_range = {frame.robot_ids[k] for k in range(1, frame.count) if distances[k] < comm_range}
    listed = {int(name.split()[1]): value for name, value in view.neighbors}
    assert set(listed) == in_range and in_range
    for robot, value in listed.items():
        measured = int(value.split(",")[0].split()[1])
        assert abs(measured - 1000 * distances[frame.robot_ids.index(robot)]) < 5
    assert view.swarms == ["member of: 3 (bits 00001000)"]
    assert any("a table is being sent" in w for w in view.warnings)


def test_a_lone_robot_sending_a_table_is_warned(tmp_path: Path) -> None:
    """Nothing received, nothing queued at the end of a step: the warning comes from what the
    robot sent in its last step (the engine's step_outbox)."""
    sim = run(tmp_path, "{.a = 1}", robots=1)
    view = sim.inspect(0)
    assert view.in_queue == [] and view.out_queue == []
    assert any("a table is being sent" in w for w in view.warnings)


def test_no_table_no_warning(tmp_path: Path) -> None:
    view = run(tmp_path, "7").inspect(0)
    assert not any("table" in w for w in view.warnings)


def test_frame_links_are_the_engine_links_as_indexes(tmp_path: Path) -> None:
    sim = run(tmp_path, "7")
    frame = sim.frame()
    engine = sim.sim
    by_id = [(frame.robot_ids[a], frame.robot_ids[b]) for a, b in frame.links.tolist()]
    assert by_id == engine.links and len(by_id) > 0


def test_an_undefined_call_is_explained_at_its_line(tmp_path: Path) -> None:
    """The inspector and the editor's runtime markers name the call at its own line."""
    assert BACKEND is not None
    path = tmp_path / "student.bzz"
    text = "function init() {}\nfunction step() {\n  led(1)\n  nosuchfunction(id)\n}\n"
    path.write_text(text)
    _, program = BACKEND.compile(text, path, "kilobot")
    sim = BACKEND.create("kilobot", program, 3, 1)
    sim.step()
    view = sim.inspect(1)
    assert view.last_error == (
        "TYPE: `nosuchfunction` is nil here: it is not defined, and no host function of the "
        f"Kilobot has that name at {path.resolve()}:4:2")
    assert view.last_error_line is not None and "nosuchfunction(id)" in view.last_error_line
    assert view.pc_line == 4  # the header's "pc N (line 4)": the call's line, not the `}`
    [(where, message, robots)] = sim.runtime_errors()
    assert (where.line, where.col, robots) == (4, 2, 3)
    assert message.startswith("TYPE: `nosuchfunction` is nil here")


def test_problem_messages_keep_their_inline_code(tmp_path: Path) -> None:
    """Warnings are sentences with `code` in them: shown as text (not one code span, which
    glued "`not x` gives" into "not xgives"), emphasis characters escaped outside the code."""
    from bbzide.ui.inspection import RobotInspection
    from bbzide.ui.inspector_panel import _problems_markdown

    view = RobotInspection(0, 0, 1, "error", 0, 1088, 0, 1088, 0, [], 0, 1088, None, None, None,
                           last_error="TYPE: `my_func` is nil here",
                           warnings=["11:4: BittyBuzz `not x` gives the truth value of x: "
                                     "write `x == 0`", "a_b * c"])
    text = _problems_markdown(view)
    assert "**Last error:** TYPE: `my_func` is nil here" in text
    assert "- 11:4: BittyBuzz `not x` gives the truth value of x: write `x == 0`" in text
    assert "- a\\_b \\* c" in text


def test_an_int16_overflow_is_warned_once_at_the_literal(tmp_path: Path) -> None:
    """`var big = 40000`: the pitfall at 1:10, not also bo2bbo's warning naming a .bo offset."""
    from bbzide.ui.pitfalls import find_pitfalls
    from bbzide.ui.program_session import _warnings_of

    assert BACKEND is not None
    path = tmp_path / "big.bzz"
    text = "var big = 40000\nfunction step() {}\n"
    path.write_text(text)
    compiled, program = BACKEND.compile(text, path, "kilobot")
    assert any("16 bit integer range" in w for w in program.warnings)  # bo2bbo still says it
    shown = _warnings_of(compiled, program) + find_pitfalls(text)
    assert [(d.line, d.col) for d in shown] == [(1, 10)]
    assert "int16" in shown[0].message


def test_switching_world_then_opening_its_example(tmp_path: Path) -> None:
    """After the World dropdown changes, one click puts that world's example in the editor
    (saved and compiled for the new world), instead of the old world's script."""
    from browser import free_port

    from bbzide.ui.app import IdeApp
    from bbzide.ui.run_controller import RunSettings

    assert BACKEND is not None
    script = tmp_path / "mine.bzz"
    script.write_text((REPO / "examples/kilobot/gradient.bzz").read_text())
    app = IdeApp(script, BACKEND, RunSettings("kilobot", 4, 0), port=free_port()).start(run=False)
    try:
        app.controls.world.value = "crazyflie"
        app._change_world("crazyflie")  # what choosing it in the World dropdown does
        assert app.load_world_example()
        example = BACKEND.example_path("crazyflie")
        assert example is not None
        assert script.read_text() == example.read_text() == app.session.text
        assert app.session.outcome is not None and app.session.outcome.ok
    finally:
        app.stop()


STUDENT = "function init() {}\nfunction step() {\n  led(1)\n  nosuchfunction(id)\n}\n"


def test_the_error_line_is_the_compiled_one_not_the_file_on_disk(tmp_path: Path) -> None:
    """The file changed after the robots got their program: the inspector shows the line the
    robots run, live and in a replay of a recording."""
    from bbzide.cli import main
    from bbzide.recording.reader import read_recording
    from bbzide.recording.rebuild import RobotRebuilder
    from bbzide.ui.replay_session import ReplaySession

    assert BACKEND is not None
    path = tmp_path / "student.bzz"
    path.write_text(STUDENT)
    _, program = BACKEND.compile(STUDENT, path, "kilobot")
    sim = BACKEND.create("kilobot", program, 2, 1)
    sim.step()
    recording_path = tmp_path / "student.rrd"
    assert main(["run", str(path), "--world", "kilobot", "--robots", "2", "--steps", "3",
                 "--record", str(recording_path)]) == 0
    path.write_text("# rewritten\n" * 10)  # the file on disk moves on
    assert sim.inspect(0).last_error_line == "  nosuchfunction(id)"
    recording = read_recording(recording_path)
    session = ReplaySession(recording, RobotRebuilder(recording))
    view = session.inspect(0, recording.last_step)
    assert view.last_error is not None and "`nosuchfunction` is nil here" in view.last_error
    assert view.last_error_line == "  nosuchfunction(id)"


def test_the_replay_program_tab_numbers_the_lines() -> None:
    from bbzide.ui.replay_app import numbered_source_html

    text = numbered_source_html("var a = 1\n\nfunction step() { a = a < 2 }\n")
    rows = [re.sub(r"<[^>]+>", "", row) for row in text.split("\n")]
    assert rows == ["1 │ var a = 1", "2 │ ", "3 │ function step() { a = a &lt; 2 }"]
    assert numbered_source_html(None) == "(the recording has no source text)"


def test_a_replayed_step_shows_the_live_warnings(tmp_path: Path) -> None:
    """The "table being sent" warning reads the payloads a robot sent in its last step: a
    replay re-executes that step, so the inspector at a recorded step warns as it did live."""
    from bbzide.cli import main
    from bbzide.recording.reader import read_recording
    from bbzide.recording.rebuild import RobotRebuilder
    from bbzide.ui.replay_session import ReplaySession

    path = tmp_path / "probe.bzz"
    path.write_text(SCRIPT.replace("TABLE", "{.a = 1}"))
    recording_path = tmp_path / "probe.rrd"
    assert main(["run", str(path), "--world", "kilobot", "--robots", "4", "--steps", "7",
                 "--record", str(recording_path)]) == 0
    _, program = BACKEND.compile(path.read_text(), path, "kilobot")
    live = BACKEND.create("kilobot", program, 4, 0)
    recording = read_recording(recording_path)
    session = ReplaySession(recording, RobotRebuilder(recording))
    for _ in range(recording.last_step):
        live.step()
    assert live.step_count == recording.last_step
    shown = live.inspect(0).warnings
    assert any("a table is being sent" in warning for warning in shown)
    assert session.inspect(0, recording.last_step).warnings == shown


def test_a_replay_warns_as_live_at_every_step_keyframe_steps_included(tmp_path: Path) -> None:
    """At a keyframe's own step the rebuild re-executes the step from the keyframe before, so
    the "table being sent" warning is there too, as it was live, at every recorded step."""
    from bbzide.cli import main
    from bbzide.recording.reader import read_recording
    from bbzide.recording.rebuild import RobotRebuilder
    from bbzide.ui.replay_session import ReplaySession

    path = tmp_path / "probe.bzz"
    path.write_text(SCRIPT.replace("TABLE", "{.a = 1}"))
    recording_path = tmp_path / "probe.rrd"
    assert main(["run", str(path), "--world", "kilobot", "--robots", "3", "--steps", "9",
                 "--record", str(recording_path), "--keyframe-every", "3"]) == 0
    _, program = BACKEND.compile(path.read_text(), path, "kilobot")
    live = BACKEND.create("kilobot", program, 3, 0)
    recording = read_recording(recording_path)
    keyframe_steps = {k.step for k in recording.keyframes[0]}
    assert {3, 6} <= keyframe_steps  # the steps this test is about
    session = ReplaySession(recording, RobotRebuilder(recording))
    for step in range(1, recording.last_step + 1):
        live.step()
        shown = live.inspect(0).warnings
        assert any("a table is being sent" in warning for warning in shown)
        assert session.inspect(0, step).warnings == shown, step
