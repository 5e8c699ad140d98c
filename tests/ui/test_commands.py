"""`bbzide ide`: arguments, the scratch copy of the example, clear errors without tracebacks."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from bbzide.cli import build_parser
from bbzide.ui.commands import IdeError, resolve_script

REPO = Path(__file__).resolve().parents[2]


def test_ide_arguments_and_defaults() -> None:
    args = build_parser().parse_args(
        ["ide", "x.bzz", "--robots", "7", "--port", "9000", "--no-browser"]
    )
    assert (args.script, args.robots, args.port, args.no_browser) == (Path("x.bzz"), 7, 9000, True)
    defaults = build_parser().parse_args(["ide"])
    assert defaults.host == "127.0.0.1" and defaults.port == 8080 and defaults.script is None


def test_example_is_copied_once_to_a_scratch_file(tmp_path: Path, monkeypatch) -> None:
    monkeypatch.setenv("XDG_DATA_HOME", str(tmp_path / "data"))
    example = tmp_path / "flock.bzz"
    example.write_text("x = 1\n")
    scratch = resolve_script(None, example)
    assert scratch == tmp_path / "data" / "bbzide" / "scratch" / "flock.bzz"
    scratch.write_text("x = 2\n")  # the user's edits survive a restart
    assert resolve_script(None, example).read_text() == "x = 2\n"
    assert example.read_text() == "x = 1\n"  # the shipped example is untouched


def test_missing_script_is_a_user_error(tmp_path: Path) -> None:
    with pytest.raises(IdeError, match="no such Buzz script"):
        resolve_script(tmp_path / "nope.bzz", None)


def test_cli_prints_one_line_and_exits_1(tmp_path: Path) -> None:
    result = subprocess.run(
        [sys.executable, "-m", "bbzide", "ide", str(tmp_path / "nope.bzz"), "--no-browser"],
        capture_output=True,
        text=True,
        cwd=REPO,
        env={"PYTHONPATH": str(REPO)},
        timeout=60,
    )
    assert result.returncode == 1
    assert "Traceback" not in result.stderr and result.stderr.startswith("error:")
