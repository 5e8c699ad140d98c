"""The keyframe budget counts a robot's CPU time, not wall-clock time: a robot whose control
steps burn CPU is keyframed once they add up to the budget, one that only waits (as a robot
does on a loaded machine, when its thread waits for a core) is keyframed by the step bound
alone. Each swarm records for `STEPS` steps with a step bound far beyond them."""

from __future__ import annotations

import time
from pathlib import Path

from bbzide.recording.reader import read_recording
from bbzide.recording.recorder import KEYFRAME_BUDGET_SECONDS, MissionRecorder, Recordable
from bbzide.worlds.commands import load_script
from bbzide.worlds.engine import Simulation
from bbzide.worlds.registry import WORLDS
from tests.recording.doubles import ToyRobot

REPO = Path(__file__).resolve().parents[2]
#: Each control step burns or sleeps this long: the budget (25 ms) is reached after ~7 steps.
STEP_SECONDS = 0.004
STEPS = 30


class BurningRobot(ToyRobot):
    def control_step(self) -> list[bytes]:
        started = time.thread_time()
        while time.thread_time() - started < STEP_SECONDS:
            pass
        return super().control_step()


class WaitingRobot(ToyRobot):
    def control_step(self) -> list[bytes]:
        time.sleep(STEP_SECONDS)
        return super().control_step()


def keyframe_steps(robot_class: type, path: Path) -> list[int]:
    spec = WORLDS["kilobot"]
    program = load_script(REPO / "examples/kilobot/gradient.bzz", spec.host_names, [])
    recordable = Recordable(build=robot_class)
    sim = Simulation("kilobot", program, robots=2, seed=1, robot_factory=recordable.factory,
                     watch=())
    with MissionRecorder(path, sim, recordable, keyframe_every=1000) as recorder:
        for _ in range(STEPS):
            sim.step()
            recorder.record_step()
    return [k.step for k in read_recording(path).keyframes[0]]


def test_cpu_time_spends_the_budget_waiting_does_not(tmp_path: Path) -> None:
    burning = keyframe_steps(BurningRobot, tmp_path / "burning.rrd")
    # 30 steps x 4 ms of CPU = 120 ms: 4 keyframes after the first (one every ~7 steps). The
    # CPU time is estimated (wall time x the thread's CPU share), so on a loaded machine the
    # count may be off by a few; never one every 3 steps or less (~8 ms a step, twice the real).
    expected = int(STEPS * STEP_SECONDS / KEYFRAME_BUDGET_SECONDS)
    assert burning[0] == 0 and expected - 1 <= len(burning) - 1 <= STEPS // 4, burning
    waiting = keyframe_steps(WaitingRobot, tmp_path / "waiting.rrd")
    assert waiting == [0]  # 120 ms of wall time, a few ms of CPU: only the first keyframe
