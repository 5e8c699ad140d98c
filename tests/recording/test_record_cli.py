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
