"""RunController: commands applied between steps on its own thread; a stuck step blocks nobody."""

from __future__ import annotations

import threading

from browser import wait_until
from doubles import FakeBackend, FakeProgram

from bbzide.ui.run_controller import RunController, RunSettings


def make_controller(speed: float = 0.0) -> tuple[RunController, FakeBackend]:
    backend = FakeBackend()
    controller = RunController(backend, RunSettings("fake-table", 5, 3, speed)).start()
    controller.load_program(FakeProgram("step", b"x"))
    wait_until(lambda: controller.last_frame is not None, 5, message="first frame")
    return controller, backend


def test_play_pause_step_reset() -> None:
    controller, backend = make_controller()
    try:
        assert controller.status.step == 0
        controller.single_step()
        assert controller.flush(5)
        assert controller.status.step == 1 and not controller.status.running
        assert controller.flush(5)  # another turn of the simulation thread: still one step
        assert controller.status.step == 1  # paused after a single step
        controller.play()
        wait_until(lambda: controller.status.step > 20, 5, message="running")
        controller.pause()
        assert controller.flush(5)
        paused_at = controller.status.step
        assert controller.flush(5)
        assert controller.status.step == paused_at
        controller.reset()
        wait_until(lambda: controller.status.step == 0, 5, message="reset")
        assert len(backend.created) == 2
    finally:
        controller.stop()



def test_a_paused_scene_shows_the_current_step() -> None:
    """At full speed most frames are skipped (30 Hz limit); a pause still draws the last step."""
    controller, _backend = make_controller()
    try:
        for _round in range(5):
            controller.play()
            start = controller.status.step
            wait_until(
                lambda start=start: controller.status.step > start + 50, 5, message="running"
            )
            controller.pause()
            wait_until(
                lambda: controller.last_frame.step == controller.status.step,
                5,
                message="the paused frame to be the current step",
            )
            with controller.locked() as sim:
                assert controller.last_frame.step == sim.step_count
    finally:
        controller.stop()

def test_new_program_keeps_or_resets_the_world() -> None:
    controller, backend = make_controller()
    try:
        controller.single_step()
        controller.single_step()
        wait_until(lambda: controller.status.step == 2, 5, message="two steps")
        controller.load_program(FakeProgram("red", b"y"))
        wait_until(lambda: controller.status.program_generation == 2, 5, message="reload")
        assert len(backend.created) == 1 and backend.created[0].program.text == "red"
        assert controller.status.step == 2  # world kept
        controller.update_settings(keep_state_on_reload=False)
        controller.load_program(FakeProgram("blue", b"z"))
        wait_until(lambda: len(backend.created) == 2, 5, message="rebuild")
        wait_until(lambda: controller.status.step == 0, 5, message="step 0")
    finally:
        controller.stop()


def test_settings_rebuild_with_new_robot_count() -> None:
    controller, backend = make_controller()
    try:
        controller.update_settings(robots=12)
        wait_until(
            lambda: controller.last_frame is not None and controller.last_frame.count == 12,
            5,
            message="12 robots",
        )
    finally:
        controller.stop()


def test_a_stuck_step_leaves_commands_and_status_working() -> None:
    controller, backend = make_controller()
    release = threading.Event()
    try:
        controller.load_program(FakeProgram("while(1){}", b"loop", release=release))
        controller.play()
        wait_until(lambda: controller.status.step_started_at is not None, 5, message="step begins")
        controller.pause()  # returns at once: only queued
        controller.load_program(FakeProgram("step", b"ok"))
        # both calls returned while the step is still stuck (it ends only when released)
        assert not release.is_set() and controller.status.step_started_at is not None
        assert controller.status.program_generation == 2
        release.set()
        wait_until(
            lambda: controller.status.program_generation == 3, 5, message="reloaded after the step"
        )
        assert not controller.status.running
    finally:
        controller.stop()


def test_a_new_world_waits_for_the_program_compiled_for_it() -> None:
    # A program is compiled for one world's string table (its host-function ids): switching
    # worlds must not run the old world's bytecode in the new world, even for a step; the app
    # compiles for the new world and sends that program (or nothing, if the text has errors).
    controller, backend = make_controller()
    try:
        controller.play()
        controller.update_settings(world="fake-lab")
        assert controller.flush(5)
        assert controller.settings.world == "fake-lab"
        assert controller.flush(5)  # another turn: the old program still does not run
        assert all(sim.world != "fake-lab" for sim in backend.created)
        assert not controller.has_program
        controller.load_program(FakeProgram("lab", b"l"))
        wait_until(lambda: backend.created[-1].world == "fake-lab", 5, message="lab world")
        assert backend.created[-1].program.text == "lab"
        wait_until(lambda: controller.status.step > 0, 5, message="lab runs")
    finally:
        controller.stop()


def test_a_world_that_refuses_the_settings_shows_the_users_message() -> None:
    from doubles import FakeBackend as Base

    from bbzide.diagnostics import UserError

    class Refusing(Base):
        def create(self, world, program, robots, seed):  # noqa: ANN001, ANN202
            if robots > 100:
                raise UserError(f"{robots} robots do not fit in the {world} world")
            return super().create(world, program, robots, seed)

    backend = Refusing()
    controller = RunController(backend, RunSettings("fake-table", 5, 3, 0.0)).start()
    try:
        controller.load_program(FakeProgram("step", b"x"))
        wait_until(lambda: controller.last_frame is not None, 5, message="first frame")
        controller.update_settings(robots=900)
        wait_until(lambda: controller.status.error is not None, 5, message="refused")
        assert controller.status.error == "900 robots do not fit in the fake-table world"
        assert controller.last_frame.count == 5          # the old world stays
    finally:
        controller.stop()
