"""`bbzide ide --token` / $BBZIDE_TOKEN: the printed address carries the token, the server answers
nothing without it, and a bad token is refused before any server starts.

The launch test runs the real command in a child process, as a user's terminal would, and reads
what it prints: the address line on stdout, and stderr, which must hold no traceback after the
requests (one of them malformed) and Ctrl-C.
"""

from __future__ import annotations

import http.client
import os
import re
import select
import signal
import subprocess
import sys
from pathlib import Path

import pytest
from browser import UI_WAIT_S

from bbzide.cli import main
from bbzide.ui import commands

REPO = Path(__file__).resolve().parents[2]
SCRIPT = "function init() {\n  x = 1\n}\n\nfunction step() {\n  x = x + 1\n}\n"


@pytest.mark.parametrize("command", ["ide", "replay"])
@pytest.mark.parametrize("option, environment", [
    (["--token", "short"], {}),
    (["--token", "has space in it"], {}),
    ([], {"BBZIDE_TOKEN": "a;b=c;d-e-f"}),
])
def test_a_bad_token_fails_before_any_server_starts(command: str, option: list[str],
                                                    environment: dict[str, str], tmp_path: Path,
                                                    monkeypatch: pytest.MonkeyPatch,
                                                    capsys: pytest.CaptureFixture[str]) -> None:
    def no_serving(app: object, open_browser: bool) -> int:  # a started server is the failure
        app.stop()  # type: ignore[attr-defined]
        return 99

    monkeypatch.setattr(commands, "serve_until_interrupted", no_serving)
    for name, value in environment.items():
        monkeypatch.setenv(name, value)
    target = tmp_path / ("s.bzz" if command == "ide" else "s.rrd")
    target.write_text(SCRIPT)
    assert main([command, str(target), "--no-browser", *option]) == 1
    err = capsys.readouterr().err
    assert "token" in err.lower() and "at least 8 characters" in err and "Traceback" not in err


def read_line(process: subprocess.Popen[str]) -> str:
    """The next line the process prints, waiting at most UI_WAIT_S for it."""
    assert process.stdout is not None
    ready, _, _ = select.select([process.stdout], [], [], UI_WAIT_S)
    assert ready, "the IDE printed nothing"
    return process.stdout.readline()


def get(port: int, path: str, method: str = "GET") -> int:
    connection = http.client.HTTPConnection("127.0.0.1", port, timeout=UI_WAIT_S)
    try:
        connection.request(method, path, body=b'{"text": "pwned"}' if method == "POST" else None)
        response = connection.getresponse()
        response.read()
        return response.status
    finally:
        connection.close()


@pytest.mark.parametrize("how", ["option", "environment"])
def test_the_printed_address_carries_the_fixed_token(how: str, tmp_path: Path) -> None:
    script = tmp_path / "main.bzz"
    script.write_text(SCRIPT)
    token = "scripted-token-42"
    environment = {k: v for k, v in os.environ.items() if k != "BBZIDE_TOKEN"}
    environment["PYTHONPATH"] = str(REPO)
    arguments = [sys.executable, "-m", "bbzide", "ide", str(script), "--no-browser", "--paused",
                 "--port", "0"]
    if how == "option":
        arguments += ["--token", token]
    else:
        environment["BBZIDE_TOKEN"] = token
    # Ctrl-C as a terminal sends it: a run started in the background by a non-interactive
    # shell (as CI may start this one) inherits SIGINT ignored, which no user's IDE has
    process = subprocess.Popen(arguments, cwd=REPO, env=environment, text=True,
                               stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                               preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    try:
        line = read_line(process)
        match = re.search(r"http://127\.0\.0\.1:(\d+)/\?token=(\S+)", line)
        assert match, line
        port = int(match.group(1))
        assert match.group(2) == token
        assert get(port, "/") == 403
        assert get(port, "/editor/") == 403
        assert get(port, "/editor/socket", method="POST") == 405
        assert get(port, f"/?token={token}") == 200
        assert get(port, f"/editor/?token={token}") == 200
    finally:
        process.send_signal(signal.SIGINT)
        # the IDE exits after its run thread's current work: on a fresh clone that can be
        # numba compiling a kernel for the first time (a minute or more on a loaded machine)
        _, err = process.communicate(timeout=4 * UI_WAIT_S)
    assert process.returncode == 0, err
    assert "Traceback" not in err, err
    assert script.read_text() == SCRIPT
