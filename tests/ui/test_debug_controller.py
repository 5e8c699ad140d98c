"""The run controller's debugger side on the real compiler, VM and Kilobot world: pause on error,
watches read after every step, and the stigmergy view."""

from __future__ import annotations

import math
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest
from browser import wait_until

from bbzide.ui.inspection import PausedAt
from bbzide.ui.run_controller import RunController, RunSettings
from bbzide.ui.watches import BadWatch, Watch, WatchBook, chart_data
from bbzide.ui.world_adapter import WorldsBackend

BACKEND = WorldsBackend()

#: How long the simulation thread may take to apply a command on a loaded machine (liveness).
WAIT_S = 60.0

FAILING = """\
var count = 0
function init() {}
function step() {
  count = count + 1
  if (id == 2 and count == 3) {
    nosuchfunction(count)
  }
}
"""
FAILING_LINE = 6

STIGMERGY = """\
var s
var count = 0
function init() {
  s = stigmergy.create(1)
  if (id == 0) { s.put("goal", 42) }
}
function step() {
  count = count + id
}
"""


def controller_for(text: str, tmp_path: Path, robots: int = 4) -> RunController:
    path = tmp_path / "script.bzz"
    path.write_text(text)
    _compiled, program = BACKEND.compile(text, path, "kilobot")
    controller = RunController(BACKEND, RunSettings("kilobot", robots, 1, 0.0)).start()
    controller.load_program(program)
    wait_until(lambda: controller.last_frame is not None, WAIT_S, message="the first frame")
    return controller


@pytest.fixture
def failing(tmp_path: Path) -> Iterator[RunController]:
    controller = controller_for(FAILING, tmp_path)
    try:
        yield controller
    finally:
        controller.stop()


def test_a_robot_entering_an_error_pauses_the_run_at_its_line(failing: RunController) -> None:
    failing.play()
    wait_until(lambda: failing.status.paused_at is not None, WAIT_S, message="the error stop")
    paused = failing.status.paused_at
    assert paused is not None
    assert (paused.reason, paused.robot_id, paused.line) == ("error", 2, FAILING_LINE)
    assert "nosuchfunction" in (paused.message or "")
    assert not failing.status.running and failing.status.step == 3
    assert failing.flush(WAIT_S) and failing.status.step == 3  # it stays paused
    failing.play()  # continue: no new failure, so it runs on
    wait_until(lambda: failing.status.step >= 8, WAIT_S, message="running on")
    assert failing.status.paused_at is None


def test_without_pause_on_error_the_run_goes_on(failing: RunController) -> None:
    failing.pause_on_error = False
    failing.play()
    wait_until(lambda: failing.status.step >= 6, WAIT_S, message="steps past the error")
    failing.pause()
    assert failing.flush(WAIT_S)  # the pause draws the last step: its error count too
    assert failing.status.paused_at is None and failing.status.robots_in_error == 1


def test_watches_read_every_robot_after_every_step(tmp_path: Path) -> None:
    controller = controller_for(STIGMERGY, tmp_path)
    book = WatchBook()
    count, heap = Watch("expression", "count"), Watch("heap", aggregate=True)
    book.add(count)
    book.add(heap)
    with pytest.raises(BadWatch):
        book.add(Watch("expression", "  "))

    def sample(sim: object) -> None:
        book.sample(sim.step_count, sim.watch_values)  # type: ignore[attr-defined]

    try:
        controller.add_step_listener(sample)
        for _ in range(5):
            controller.single_step()
        wait_until(lambda: controller.status.step == 5, WAIT_S, message="five steps")
        steps, table = book.series(count)
        assert steps.tolist() == [1, 2, 3, 4, 5]
        ids = controller.last_frame.robot_ids  # type: ignore[union-attr]
        # count grows by the robot's id each step
        assert table[-1].tolist() == [5 * robot_id for robot_id in ids]
        _steps, heaps = book.series(heap)
        assert np.all(heaps > 0) and np.all(np.isfinite(heaps))
        data, series = chart_data(heap, *book.series(heap), ids)
        assert [s["label"] for s in series] == ["step", "min", "mean", "max"]
        assert data[1].tolist() == heaps.min(axis=1).tolist()
        with controller.locked() as sim:
            versions = sim.stigmergy_versions(64)  # type: ignore[union-attr]
            goal = sim.watch_values(Watch("stigmergy", "goal"))  # type: ignore[union-attr]
        key, _stamp, writer, value, holders = versions[0]
        assert (key, writer, value) == ("goal", ids[0], "42")
        assert holders[0] == ids[0]
        assert goal[0] == 42.0 and all(math.isnan(v) or v == 42.0 for v in goal)
        controller.remove_step_listener(sample)
        controller.single_step()
        wait_until(lambda: controller.status.step == 6, WAIT_S, message="one more step")
        assert book.series(count)[0].tolist() == [1, 2, 3, 4, 5]  # no listener, no sample
    finally:
        controller.stop()


#: A listener lambda (line 4) and a `step` with a host call (line 8) and a local (line 9).
LISTENING = """\
var heard = 255
function init() {
  neighbors.listen("g", function(vid, value, rid) {
    heard = value
  })
}
function step() {
  neighbors.broadcast("g", id)
  var x = id + 1
  led(x % 7 + 1)
}
"""


def robot_bytes(controller: RunController, robot_id: int) -> bytes:
    """Robot `robot_id`'s whole state (heap, stack, pc) as comparable bytes."""
    with controller.locked() as sim:
        state = sim.sim.state_of(robot_id)  # type: ignore[union-attr]
        return state.robot.comparable(state.robot.snapshot())  # type: ignore[no-any-return]


def test_breakpoint_steps_and_back_through_the_controller(tmp_path: Path) -> None:
    from bbzide.ui.breakpoints import LineBreakpoint

    controller = controller_for(LISTENING, tmp_path)

    def command(name: str) -> tuple[int, int | None, str]:
        stops = controller.status.stops
        controller.debug(name)
        wait_until(lambda: controller.status.stops > stops or controller.status.debug_note,
                   WAIT_S, message=name)
        paused = controller.status.paused_at
        assert paused is not None, controller.status.debug_note
        return paused.robot_id, paused.line, paused.reason

    try:
        controller.set_breakpoints([LineBreakpoint(9, robot=1)])
        controller.play()
        wait_until(lambda: controller.status.paused_at is not None, WAIT_S, message="the hit")
        paused = controller.status.paused_at
        assert paused is not None and not controller.status.running
        assert (paused.robot_id, paused.line, paused.reason, paused.step) == (1, 9,
                                                                            "breakpoint", 0)
        assert paused.mid_step and paused.frames[0].function == "step"
        at_nine = robot_bytes(controller, 1)
        assert command("step_over") == (1, 10, "step")
        assert controller.status.paused_at.frames[0].locals == {"x": "2"}  # type: ignore
        # over the end of `step`: the robot's next line is the listener's, next control step
        assert command("step_over") == (1, 4, "step")
        assert controller.status.paused_at.frames[0].function == "lambda at line 3"  # type: ignore
        # out of the lambda: its calls for the other messages run through, then `step` starts
        assert command("step_out") == (1, 8, "step")
        assert command("step_back_control_step")[1] == 8
        assert command("step_over")[:2] == (1, 9)  # (a breakpoint's line: reason "breakpoint")
        assert robot_bytes(controller, 1) == at_nine  # the same state, byte for byte
        controller.set_breakpoints([])
        controller.play()  # finishes the held step through the debugger, then runs plain
        wait_until(lambda: controller.status.step >= 4, WAIT_S, message="running on")
    finally:
        controller.stop()


def back_line(controller: RunController) -> PausedAt:
    """Step back one line of robot 2 (the robot the error scripts fail) and wait for it."""
    stops = controller.status.stops
    controller.debug("step_back_line", 2)
    wait_until(lambda: controller.status.stops > stops or controller.status.debug_note,
               WAIT_S, message="the step back")
    paused = controller.status.paused_at
    assert paused is not None, controller.status.debug_note
    return paused


def test_step_back_from_a_pause_the_debugger_did_not_make(tmp_path: Path) -> None:
    """Plain steps (no breakpoint) then Pause: Back goes to robot 2's last line of the step
    before, inside that step; the same from the pause on an error at the end of a plain step,
    where it lands on the failing line."""
    controller = controller_for(FAILING, tmp_path)
    try:
        for _ in range(2):
            controller.single_step()
        wait_until(lambda: controller.status.step == 2, WAIT_S, message="two plain steps")
        controller.pause()
        assert controller.flush(WAIT_S) and controller.status.paused_at is None
        paused = back_line(controller)
        # the last line robot 2 ran in step 1 (its count was 2: the `if` is false)
        assert (paused.robot_id, paused.line, paused.reason, paused.step) == (2, 5, "step", 1)
        assert paused.mid_step
        controller.play()  # on to the error, which pauses the run at the end of its step
        wait_until(lambda: controller.status.paused_at is not None
                   and controller.status.paused_at.reason == "error", WAIT_S,
                   message="the error pause")
        error = controller.status.paused_at
        assert error is not None and (error.robot_id, error.line) == (2, FAILING_LINE)
        paused = back_line(controller)
        assert (paused.robot_id, paused.line, paused.reason) == (2, FAILING_LINE, "step")
        assert paused.step == error.step - 1  # inside the step that failed (an error pause
        back_again = back_line(controller)  # after a plain step names the step count after it)
        assert (back_again.line, back_again.step) == (5, error.step - 1)  # the `if` before
    finally:
        controller.stop()
