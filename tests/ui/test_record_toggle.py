"""The IDE's Record toggle: RunController records the running swarm into a new .rrd.

The swarm is the real engine and Kilobot table with toy firmware (tests/recording/doubles.py)
behind the real `WorldsSimulation` adapter, so the path from the toggle to the file is the one
the IDE uses; only the Buzz VM is replaced.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from browser import wait_until

from bbzide.recording.reader import read_recording
from bbzide.ui.app import new_recording_path
from bbzide.ui.run_controller import RunController, RunSettings
from bbzide.ui.world_adapter import WorldsSimulation
from tests.recording.test_recording import toy_swarm


class ToyBackend:
    def __init__(self) -> None:
        self.created: list[WorldsSimulation] = []

    def create(self, world: str, program: Any, robots: int, seed: int) -> WorldsSimulation:
        sim, recordable = toy_swarm(seed)
        handle = WorldsSimulation(sim, program, sim.robots[0].profile, recordable)
        self.created.append(handle)
        return handle


def test_toggle_records_from_the_current_step_until_switched_off(tmp_path: Path) -> None:
    backend = ToyBackend()
    controller = RunController(backend, RunSettings("kilobot", 12, 3, 0.0)).start()  # type: ignore[arg-type]
    try:
        controller.load_program("program")
        wait_until(lambda: controller.last_frame is not None, 10, message="first frame")
        for _ in range(5):
            controller.single_step()
        wait_until(lambda: controller.status.step == 5, 10, message="five steps")
        path = new_recording_path(tmp_path / "demo.bzz")
        assert path.parent == tmp_path / "recordings" and path.suffix == ".rrd"
        controller.set_recording(path, "# the source\n")
        wait_until(lambda: controller.status.recording == str(path), 10, message="recording")
        controller.play()
        wait_until(lambda: controller.status.step > 40, 20, message="running")
        controller.pause()
        assert controller.flush(10)
        controller.set_recording(None)
        wait_until(lambda: controller.status.recording is None, 10, message="stopped")
        stopped_at = controller.status.step
        recording = read_recording(path)
        assert not recording.truncated
        assert recording.first_step == 5
        assert recording.last_step == stopped_at
        assert recording.programs[0]["source"] == "# the source\n"
        assert new_recording_path(tmp_path / "demo.bzz") != path  # never the same file twice
    finally:
        controller.stop()


def test_reset_stops_the_recording(tmp_path: Path) -> None:
    backend = ToyBackend()
    controller = RunController(backend, RunSettings("kilobot", 12, 3, 0.0)).start()  # type: ignore[arg-type]
    try:
        controller.load_program("program")
        wait_until(lambda: controller.last_frame is not None, 10, message="first frame")
        path = tmp_path / "run.rrd"
        controller.set_recording(path)
        wait_until(lambda: controller.status.recording == str(path), 10, message="recording")
        controller.single_step()
        controller.single_step()
        wait_until(lambda: controller.status.step == 2, 10, message="two steps")
        controller.reset()
        wait_until(lambda: controller.status.recording is None, 10, message="reset stops it")
        assert read_recording(path).last_step == 2
    finally:
        controller.stop()
