"""Malformed requests to a running IDE get a 4xx and a short reason, never a traceback.

Two layers: the HTTP requests the IDE's port cannot take (another method than GET, a body, a
bad Content-Length, an oversized head, bytes that are not UTF-8), and the editor websocket's
messages (not JSON, not an object, wrong types, missing fields, binary, too large). The server
runs in this process, so `capfd` holds everything its threads print to the terminal, and
`caplog` every log record (pytest's own log handler takes them, where a user's terminal would
get Python's last-resort handler printing the record and its traceback).
"""

from __future__ import annotations

import json
import socket
from collections.abc import Iterator
from pathlib import Path

import pytest
import websockets.exceptions
import websockets.sync.client
from browser import UI_WAIT_S, free_port
from doubles import FakeBackend

from bbzide.ui.app import IdeApp
from bbzide.ui.editor_server import MAX_MESSAGE_BYTES
from bbzide.ui.run_controller import RunSettings

SCRIPT = "function init() {\n  x = 1\n}\n\nfunction step() {\n  x = x + 1\n}\n"


@pytest.fixture
def app(tmp_path: Path) -> Iterator[IdeApp]:
    script = tmp_path / "main.bzz"
    script.write_text(SCRIPT)
    started = IdeApp(script, FakeBackend(), RunSettings("fake-table", 3, 1, 30.0),
                     port=free_port()).start(run=False)
    try:
        yield started
    finally:
        started.stop()


def answer_to(port: int, request: bytes) -> tuple[int, str]:
    """Send raw bytes; (status, body) of the answer, (0, "") if the server closed silently."""
    with socket.create_connection(("127.0.0.1", port), timeout=UI_WAIT_S) as connection:
        connection.sendall(request)
        received = b""
        while chunk := connection.recv(65536):
            received += chunk
    head, _, body = received.partition(b"\r\n\r\n")
    if not head:
        return 0, ""
    return int(head.split()[1]), body.decode("utf-8", "replace")


def assert_terminal_clean(capfd: pytest.CaptureFixture[str],
                          caplog: pytest.LogCaptureFixture) -> None:
    out, err = capfd.readouterr()
    assert "Traceback" not in out + err, out + err
    for record in caplog.records:
        assert record.exc_info is None and "\n" not in record.getMessage(), record.getMessage()


def test_http_requests_the_port_cannot_take_get_a_4xx(
    app: IdeApp, capfd: pytest.CaptureFixture[str], caplog: pytest.LogCaptureFixture
) -> None:
    port = app.server.get_port()
    host = f"Host: 127.0.0.1:{port}\r\n".encode()
    token = app.token.encode()
    cases = {
        "websocket handshake with a bad key": (
            b"GET /editor/socket?token=" + token + b" HTTP/1.1\r\n" + host +
            b"Upgrade: websocket\r\nConnection: Upgrade\r\nSec-WebSocket-Key: bad\r\n"
            b"Sec-WebSocket-Version: 13\r\n\r\n", 400),
        "POST of a JSON array": (b"POST /editor/socket HTTP/1.1\r\n" + host +
                                 b"Content-Length: 6\r\n\r\n[1, 2]", 405),
        "POST without Content-Length": (b"POST /editor/socket HTTP/1.1\r\n" + host +
                                        b"\r\n", 405),
        "bad Content-Length": (b"GET / HTTP/1.1\r\n" + host +
                               b"Content-Length: twelve\r\n\r\n", 400),
        "huge declared body": (b"GET / HTTP/1.1\r\n" + host +
                               b"Content-Length: 10000000000\r\n\r\n", 400),
        "chunked body": (b"GET / HTTP/1.1\r\n" + host +
                         b"Transfer-Encoding: chunked\r\n\r\n5\r\nhello\r\n0\r\n\r\n", 400),
        "huge head": (b"GET / HTTP/1.1\r\n" + host + b"X-Pad: " + b"a" * 100_000, 431),
        "not UTF-8 in the path": (b"GET /editor/\xff\xfe?token=" + token + b" HTTP/1.1\r\n" +
                                  host + b"\r\n", 404),
        "not UTF-8 in a header": (b"GET /?token=" + token + b" HTTP/1.1\r\n" + host +
                                  b"Origin: http://\xff\r\n\r\n", 403),
        "no request line": (b"\r\n\r\n", 400),
        "HTTP/1.0": (b"GET / HTTP/1.0\r\n\r\n", 505),
    }
    # A head cut off by the client: nothing to answer, and the server must not print a
    # traceback about it either. The server's closing of the connection is the sign it is done.
    with socket.create_connection(("127.0.0.1", port), timeout=UI_WAIT_S) as cut_off:
        cut_off.sendall(b"GET / HTTP/1.1\r\n" + host)
        cut_off.shutdown(socket.SHUT_WR)
        assert cut_off.recv(100) == b""
    for name, (request, status) in cases.items():
        got, body = answer_to(port, request)
        assert got == status, (name, got, body)
        assert 0 < len(body) < 200 and "Traceback" not in body, (name, body)
    assert_terminal_clean(capfd, caplog)
    assert app.session.text == SCRIPT and Path(app.session.path).read_text() == SCRIPT


def test_malformed_editor_messages_get_a_4xx_answer(
    app: IdeApp, capfd: pytest.CaptureFixture[str], caplog: pytest.LogCaptureFixture
) -> None:
    port = app.server.get_port()
    messages: list[tuple[str | bytes, int]] = [
        ("[1, 2, 3]", 400),
        ('"just a string"', 400),
        ("{not json", 400),
        ("[" * 100_000, 400),  # nested too deep for the parser
        (b"\x00\x01 binary", 400),
        ('{"id": 1, "op": "save", "text": 5, "base_revision": 0}', 400),
        ('{"id": 2, "op": "save", "text": "x = 1"}', 400),
        ('{"id": 3, "op": "save", "text": "x = 1", "base_revision": "0"}', 400),
        ('{"id": 4, "op": "save", "text": "x = 1", "base_revision": true}', 400),
        ('{"id": 5, "op": "delete"}', 400),
        ('{"id": 6}', 400),
        ('{"id": 7, "op": "save", "text": "x = 1", "base_revision": 99}', 409),
        ('{"id": 8, "op": "source"}', 200),
    ]
    with websockets.sync.client.connect(
        f"ws://127.0.0.1:{port}/editor/socket",
        additional_headers={"Authorization": f"token {app.token}"}, max_size=None,
    ) as connection:
        for message, code in messages:
            connection.send(message)
            reply = json.loads(connection.recv(timeout=UI_WAIT_S))
            assert reply["code"] == code, (message[:40], reply)
            if code >= 400 and code != 409:
                assert 0 < len(reply["error"]) < 120, reply
        connection.send("x" * (MAX_MESSAGE_BYTES + 1))
        with pytest.raises(websockets.exceptions.ConnectionClosed) as closed:
            connection.recv(timeout=UI_WAIT_S)
        assert closed.value.rcvd is not None and closed.value.rcvd.code == 1009  # too big
    assert_terminal_clean(capfd, caplog)
    assert app.session.text == SCRIPT and Path(app.session.path).read_text() == SCRIPT
