"""The swarm step-time meter reads the VM's exact counters and `bbzide run --steptime` prints
the per-platform estimate."""

from __future__ import annotations

from pathlib import Path

from bbzide.cli import main
from bbzide.vm.profiles import get_profile
from bbzide.vm.robot import Robot
from bbzide.worlds.commands import load_script
from bbzide.worlds.engine import Simulation
from bbzide.worlds.registry import WORLDS
from bbzide.worlds.steptime import StepTimeMeter, summary_rows

REPO = Path(__file__).resolve().parents[2]
GRADIENT = REPO / "examples" / "kilobot" / "gradient.bzz"


def test_meter_counts_match_a_lone_robot_on_its_first_step() -> None:
    program = load_script(GRADIENT, WORLDS["kilobot"].host_names, [])
    sim = Simulation("kilobot", program, robots=3, seed=1, watch=())
    meter = StepTimeMeter(sim)
    meter.run(3)
    assert len(meter.counts) == 9
    lone = Robot(program, get_profile("kilobot"), 0, host_functions={"led": lambda call: None})
    lone.boot()
    before = (lone.vm.instructions_executed, lone.vm.heap.gc_runs)
    lone.control_step()
    first = meter.counts[0]     # robot 0, step 0: no message yet, same code path
    assert first.instructions == lone.vm.instructions_executed - before[0]
    assert first.gc_runs == lone.vm.heap.gc_runs - before[1]
    assert first.messages == 0
    assert any(c.messages > 0 for c in meter.counts[3:])   # later steps hear the others


def test_summary_has_both_platforms_and_the_kilobot_is_slower() -> None:
    program = load_script(GRADIENT, WORLDS["kilobot"].host_names, [])
    meter = StepTimeMeter(Simulation("kilobot", program, robots=2, seed=0, watch=()))
    meter.run(4)
    rows = {row["platform"]: row for row in summary_rows(meter)}
    assert set(rows) == {"kilobot", "crazyflie"}
    for row in rows.values():
        assert 0 < row["min"] <= row["mean"] <= row["max"]
    assert rows["kilobot"]["mean"] > rows["crazyflie"]["mean"]


def test_run_steptime_prints_the_estimate(capsys) -> None:  # noqa: ANN001
    status = main(["run", str(GRADIENT), "--world", "kilobot", "--robots", "3", "--steps", "3",
                   "--steptime"])
    out = capsys.readouterr().out
    assert status == 0
    assert "estimated step time per platform" in out
    assert "kilobot" in out and "crazyflie" in out
    assert "this world's control period:" in out
