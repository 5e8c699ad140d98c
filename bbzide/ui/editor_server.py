"""A small HTTP server for the Buzz editor page and its JSON API.

viser 1.1.1 has no code-editor widget (its multiline text input is a plain textarea without
line numbers, highlighting or markers) and its HTTP handler serves only its own client bundle.
So the editor is our own page (`static/editor.html|css|js`), served here on 127.0.0.1 and shown
inside the viser panel in an <iframe>. It talks to `ProgramSession` through four JSON routes
(see the top of `static/editor.js`). Only the one `.bzz` file of the session can be written, and
only through `ProgramSession.edit_from_browser` (atomic save).
"""

from __future__ import annotations

import json
import threading
from http import HTTPStatus
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from pathlib import Path
from typing import Any

from bbzide.ui.program_session import ProgramSession

STATIC_DIR = Path(__file__).resolve().parent / "static"
STATIC_FILES = {
    "/": ("editor.html", "text/html; charset=utf-8"),
    "/editor.html": ("editor.html", "text/html; charset=utf-8"),
    "/editor.css": ("editor.css", "text/css; charset=utf-8"),
    "/editor.js": ("editor.js", "application/javascript; charset=utf-8"),
}
#: Largest request body accepted: a generous bound for a Buzz script (the Kilobot flash is 32 KB).
MAX_BODY_BYTES = 2 * 1024 * 1024


class EditorServer:
    """Serves the editor on `host:port` (port 0 = any free port) from a daemon thread."""

    def __init__(self, session: ProgramSession, host: str = "127.0.0.1", port: int = 0) -> None:
        self.session = session
        handler = _make_handler(session)
        self._httpd = ThreadingHTTPServer((host, port), handler)
        self._httpd.daemon_threads = True
        self.host = host
        self.port = self._httpd.server_address[1]
        self._thread = threading.Thread(
            target=self._httpd.serve_forever, name="bbzide-editor", daemon=True
        )

    def start(self) -> EditorServer:
        self._thread.start()
        return self

    def url(self, browser_host: str | None = None) -> str:
        return f"http://{browser_host or self.host}:{self.port}/"

    def stop(self) -> None:
        self._httpd.shutdown()
        self._httpd.server_close()
        self._thread.join(timeout=5)


def _make_handler(session: ProgramSession) -> type[BaseHTTPRequestHandler]:
    class EditorRequestHandler(BaseHTTPRequestHandler):
        server_version = "bbzide-editor"

        def log_message(self, format: str, *args: Any) -> None:  # noqa: A002 - stdlib signature
            return  # keep the terminal for the IDE's own messages

        def do_GET(self) -> None:  # noqa: N802 - stdlib naming
            path = self.path.partition("?")[0]
            if path in STATIC_FILES:
                name, mime = STATIC_FILES[path]
                self._send(HTTPStatus.OK, (STATIC_DIR / name).read_bytes(), mime)
            elif path == "/api/state":
                self._send_json(session.state())
            elif path == "/api/source":
                self._send_json(session.source())
            else:
                self._send(HTTPStatus.NOT_FOUND, b"not found", "text/plain")

        def do_POST(self) -> None:  # noqa: N802 - stdlib naming
            length = int(self.headers.get("Content-Length") or 0)
            if length > MAX_BODY_BYTES:
                self._send(HTTPStatus.REQUEST_ENTITY_TOO_LARGE, b"too large", "text/plain")
                return
            try:
                body = json.loads(self.rfile.read(length) or b"{}")
            except json.JSONDecodeError:
                self._send(HTTPStatus.BAD_REQUEST, b"bad json", "text/plain")
                return
            path = self.path.partition("?")[0]
            if path == "/api/source" and isinstance(body.get("text"), str):
                try:
                    session.edit_from_browser(body["text"])
                except OSError as error:
                    self._send_json({**session.state(), "save_error": str(error)})
                    return
                self._send_json(session.state())
            elif path == "/api/compile":
                session.compile_now()
                self._send_json(session.state())
            else:
                self._send(HTTPStatus.NOT_FOUND, b"not found", "text/plain")

        def _send_json(self, payload: dict[str, Any]) -> None:
            self._send(HTTPStatus.OK, json.dumps(payload).encode(), "application/json")

        def _send(self, status: HTTPStatus, body: bytes, mime: str) -> None:
            self.send_response(status)
            self.send_header("Content-Type", mime)
            self.send_header("Content-Length", str(len(body)))
            self.send_header("Cache-Control", "no-store")
            self.end_headers()
            self.wfile.write(body)

    return EditorRequestHandler
