"""`bbzide run ... --record FILE.rrd`: no overwriting, needs a world, writes a replayable file."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import pytest

from bbzide.cli import main
from bbzide.recording.reader import read_recording

REPO = Path(__file__).resolve().parents[2]
EXAMPLE = str(REPO / "examples/kilobot/gradient.bzz")
HAS_ROBOT = importlib.util.find_spec("bbzide.vm.robot") is not None


def test_existing_file_is_kept_without_force(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    path = tmp_path / "mission.rrd"
    path.write_bytes(b"keep me")
    code = main(["run", EXAMPLE, "--world", "kilobot", "--steps", "3", "--record", str(path)])
    assert code == 1
    assert "--force" in capsys.readouterr().err
    assert path.read_bytes() == b"keep me"


def test_record_needs_a_world_and_an_rrd_name(tmp_path: Path,
                                              capsys: pytest.CaptureFixture) -> None:
    assert main(["run", EXAMPLE, "--record", str(tmp_path / "m.rrd")]) == 1
    assert "--world" in capsys.readouterr().err
    assert main(["run", EXAMPLE, "--world", "kilobot", "--record", str(tmp_path / "m.txt")]) == 1
    assert ".rrd" in capsys.readouterr().err


@pytest.mark.skipif(not HAS_ROBOT, reason="bbzide/vm/robot.py (vm-runtime) not merged yet")
def test_recorded_run_replays(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    path = tmp_path / "mission.rrd"
    path.write_bytes(b"old")
    code = main(["run", EXAMPLE, "--world", "kilobot", "--robots", "9", "--steps", "30",
                 "--record", str(path), "--force"])
    out = capsys.readouterr().out
    assert code == 0, out
    assert "recording:" in out
    recording = read_recording(path)
    assert (recording.first_step, recording.last_step, recording.robot_count) == (0, 30, 9)
    assert recording.programs[0]["source"] == Path(EXAMPLE).read_text()


@pytest.mark.parametrize("extra, words", [
    (["--seed", "-1"], "--seed must be >= 0"),       # was numpy's ValueError (internal error)
    (["--budget", "0"], "--budget must be >= 1"),
    (["--dump"], "--dump is for one robot"),
])
def test_recorded_run_refuses_what_run_world_refuses(extra: list[str], words: str, tmp_path: Path,
                                                     capsys: pytest.CaptureFixture) -> None:
    path = tmp_path / "s.rrd"
    code = main(["run", EXAMPLE, "--world", "kilobot", "--robots", "3", "--steps", "2",
                 "--record", str(path), *extra])
    err = capsys.readouterr().err
    assert code == 1, err
    assert words in err and "internal error" not in err
    assert not path.exists()


LOOP_1000 = ("function init() {}\nfunction step() {\n  var i = 0\n"
             "  while (i < 1000) { i = i + 1 }\n}\n")
RETURNS = "function init() {}\nfunction step() {\n  return 1\n}\n"


@pytest.mark.skipif(not HAS_ROBOT, reason="bbzide/vm/robot.py (vm-runtime) not merged yet")
def test_recorded_run_applies_budget_and_loop(tmp_path: Path,
                                              capsys: pytest.CaptureFixture) -> None:
    """As `run --world` does: every robot gets --budget and --loop, and the recording keeps
    them (its rebuilt robots must run under the same ones)."""
    busy = tmp_path / "busy.bzz"
    busy.write_text(LOOP_1000)
    path = tmp_path / "busy.rrd"
    assert main(["run", str(busy), "--world", "kilobot", "--robots", "2", "--steps", "3",
                 "--budget", "500", "--record", str(path)]) == 0
    assert "BUDGET at" in capsys.readouterr().out
    assert read_recording(path).meta["instruction_budget"] == 500
    returns = tmp_path / "returns.bzz"
    returns.write_text(RETURNS)
    path = tmp_path / "returns.rrd"
    assert main(["run", str(returns), "--world", "kilobot", "--robots", "1", "--steps", "300",
                 "--loop", "robot", "--record", str(path)]) == 0
    assert "STACK" in capsys.readouterr().out  # the firmware keeps step's return value
    assert read_recording(path).meta["loop"] == "robot"


@pytest.mark.skipif(not HAS_ROBOT, reason="needs the VM room's Robot")
def test_a_scenario_run_can_be_recorded_with_its_script_source(tmp_path: Path,
                                                              capsys: pytest.CaptureFixture
                                                              ) -> None:
    scenario = REPO / "examples/kilobot/leader.toml"
    path = tmp_path / "leader.rrd"
    assert main(["run", str(scenario), "--steps", "4", "--record", str(path)]) == 0
    assert "6 robots, 4 steps" in capsys.readouterr().out
    recording = read_recording(path)
    assert recording.robot_count == 6 and recording.last_step == 4
    assert recording.meta["watch"] == ["leader"] and recording.meta["seed"] == 2
    sources = [program["source"] for program in recording.programs.values()]
    assert sources == [(REPO / "examples/kilobot/leader.bzz").read_text()]


@pytest.mark.skipif(not HAS_ROBOT, reason="needs the VM room's Robot")
def test_a_replay_has_the_world_overlays_from_its_first_step(tmp_path: Path) -> None:
    """The belief map, targets and rendezvous of an M300 field at the first recorded step
    (they were missing until the first look, ten steps in)."""
    path = tmp_path / "field.rrd"
    flocking = str(REPO / "examples/m300/flocking.bzz")
    assert main(["run", flocking, "--world", "m300", "--robots", "3", "--steps", "4",
                 "--record", str(path)]) == 0
    recording = read_recording(path)
    first = recording.overlays_at(recording.first_step)
    assert {"belief_map", "targets", "rendezvous"} <= set(first)
    assert len(first["targets"]) == 3
