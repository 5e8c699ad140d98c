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


def test_a_script_that_is_not_utf8_is_refused_with_its_position(tmp_path: Path) -> None:
    script = tmp_path / "latin1.bzz"
    script.write_bytes(b"x = 1\ns = \"caf\xe9\"\n")
    with pytest.raises(IdeError, match=r"latin1.bzz:2:8: .*not UTF-8"):
        resolve_script(script, None)
    assert script.read_bytes() == b"x = 1\ns = \"caf\xe9\"\n"


def test_a_folder_is_named_as_a_folder(tmp_path: Path) -> None:
    with pytest.raises(IdeError, match="is a folder"):
        resolve_script(tmp_path, None)


@pytest.mark.parametrize("command, extra, words", [
    ("ide", ["--seed", "-1"], "--seed must be >= 0"),
    ("ide", ["--robots", "5000"], "--robots must be 1..1000"),
    ("ide", ["--threads", "0"], "--threads must be >= 1"),
    ("ide", ["--port", "70000"], "--port must be 0..65535"),
    ("ide", ["--host", "999.1.1.1"], "cannot listen on 999.1.1.1"),
    ("replay", ["--port", "-2"], "--port must be 0..65535"),
    ("replay", ["--host", "999.1.1.1"], "cannot listen on 999.1.1.1"),
])
def test_bad_server_arguments_fail_before_any_server_starts(command, extra, words, tmp_path,
                                                            monkeypatch, capsys) -> None:
    from bbzide.cli import main
    from bbzide.ui import commands

    def no_serving(app, open_browser):  # a server that started is itself the failure
        app.stop()
        return 99

    monkeypatch.setattr(commands, "serve_until_interrupted", no_serving)
    target = tmp_path / ("s.bzz" if command == "ide" else "s.rrd")
    target.write_text("function step() {}\n")
    assert main([command, str(target), "--no-browser", *extra]) == 1
    err = capsys.readouterr().err
    assert words in err and "Traceback" not in err


@pytest.mark.parametrize("name, words", [
    ("g.bbo", "bytecode, not Buzz source"), ("g.bo", "bytecode, not Buzz source"),
    ("g.bdb", "bytecode, not Buzz source"), ("m.rrd", "bbzide replay"),
])
def test_bytecode_and_recordings_are_not_opened_as_source(name, words, tmp_path: Path) -> None:
    path = tmp_path / name
    path.write_bytes(b"\x00\x01abc")       # valid UTF-8: the editor would have taken it
    with pytest.raises(IdeError, match=words):
        resolve_script(path, None)
    assert path.read_bytes() == b"\x00\x01abc"
