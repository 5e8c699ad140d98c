"""The `bbzide` router: what reaches a user when a command goes wrong.

A `UserError` is one message and exit 1 (tests/test_diagnostics.py); a bug (any other exception)
must not show a Python traceback either: one line naming the bug and the file that holds the
traceback, exit 70. A bytecode file of the reference VM (.bo) given to `run` is named as such.
"""

from __future__ import annotations

import argparse
import tempfile
from pathlib import Path

import pytest

from bbzide import cli
from bbzide.cli import main

REPO = Path(__file__).resolve().parents[1]


def _parser_whose_command_crashes() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="bbzide")
    commands = parser.add_subparsers(dest="command")

    def crash(args: argparse.Namespace) -> int:
        return {}["missing key"]

    commands.add_parser("crash").set_defaults(handler=crash)
    return parser


def test_a_bug_prints_one_line_and_keeps_the_traceback_in_a_file(monkeypatch, tmp_path, capsys):
    monkeypatch.setattr(cli, "build_parser", _parser_whose_command_crashes)
    monkeypatch.setattr(tempfile, "tempdir", str(tmp_path))
    monkeypatch.delenv("BBZIDE_TRACEBACK", raising=False)
    assert main(["crash"]) == cli.EXIT_BUG
    err = capsys.readouterr().err
    assert "Traceback" not in err
    assert "internal error (a bug in bbzide): KeyError: 'missing key'" in err
    saved = [p for p in tmp_path.rglob("*.txt")]
    assert len(saved) == 1 and str(saved[0]) in err
    assert "Traceback" in saved[0].read_text() and "crash" in saved[0].read_text()


def test_bbzide_traceback_shows_the_bug_to_its_developers(monkeypatch):
    monkeypatch.setattr(cli, "build_parser", _parser_whose_command_crashes)
    monkeypatch.setenv("BBZIDE_TRACEBACK", "1")
    with pytest.raises(KeyError):
        main(["crash"])


@pytest.mark.parametrize("extra", [[], ["--world", "kilobot", "--steps", "1"]])
def test_running_a_bo_names_the_bbo_to_run_instead(extra, tmp_path, capsys):
    script = tmp_path / "g.bzz"
    script.write_text((REPO / "examples" / "kilobot" / "gradient.bzz").read_text())
    assert main(["compile", str(script), "--platform", "kilobot"]) == 0
    capsys.readouterr()
    assert main(["run", str(script.with_suffix(".bo")), *extra]) == 1
    err = capsys.readouterr().err
    assert "bbzide bo2bbo" in err and "Syntax error" not in err
