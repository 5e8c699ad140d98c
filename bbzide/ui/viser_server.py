"""The viser server both apps stand on (the live IDE and the replay), set up one way and guarded.

Both pages look alike on purpose — a user who records in the IDE and replays the file finds
the same panels in the same places — so the theme, the docked control panel and the page
address live here, once. The server binds where the caller says (127.0.0.1 unless the user
passed ``--host``; viser's own default, 0.0.0.0, is never used implicitly).

**One port, one gate.** viser serves its page and its websocket from one `websockets` server
(``websockets.asyncio.server.serve``), whose ``process_request`` hook sees every HTTP request
and every websocket handshake before anything is answered. viser 1.1.1 offers no way to pass
our own hook, so `open_server` wraps that one ``serve`` call while viser starts it: our
``process_request`` runs first on every request (`bbzide.ui.access.check_request`: host,
origin, token) and hands what it admits to viser's own; our connection handler routes the
websocket paths listed in `Routes.sockets` to their handlers and every other one to viser's.
The same hook serves the few static pages of `Routes.pages` (the editor), so the whole IDE is
one address: the editor's iframe is a relative URL that works however the page was reached
(``--host 0.0.0.0`` from another machine too). `websockets` answers only GET (it is a
websocket server), which is why the editor talks to the IDE over its own websocket rather than
POST requests. The wrap is installed before the server listens and removed when it is up; if
viser ever starts its server another way, `open_server` refuses to run it unguarded
(`UnguardedServer`).

`websockets` drops requests it cannot take (another method than GET, a body, a head too large)
by closing the connection without a word, and its logger then prints a traceback. The same wrap
passes `serve` our connection class (`AnsweringConnection`, through `serve`'s own
``create_connection`` parameter), which reads the request head first and answers those with a
4xx and a one-line reason (`head_problem`); `quiet_handshake_errors` keeps `websockets`' log to
one line. viser's start-up banner, which shows the address without the token (an address that
answers 403), is not printed: the IDE prints its own. Nor is viser's warning about an update
queued for a tab that has just closed (`quiet_closed_tab_updates`): the panels of that tab may
be mid-refresh when it goes, and dropping the update is exactly what should happen.
"""

from __future__ import annotations

import contextlib
import io
import logging
import sys
import threading
import warnings
from collections.abc import Awaitable, Callable, Iterator, Mapping
from dataclasses import dataclass, field
from http import HTTPStatus

import viser
import websockets.asyncio.server
import websockets.exceptions
from websockets.asyncio.server import ServerConnection
from websockets.datastructures import Headers
from websockets.http11 import Request, Response

from bbzide.ui.access import AccessPolicy, Verdict, check_request

#: A websocket route: runs for the whole life of one connection.
SocketHandler = Callable[[ServerConnection], Awaitable[None]]
#: viser's hook and handler, as `websockets.serve` receives them.
ProcessRequest = Callable[[ServerConnection, Request], Response | None]
#: The headers `check_request` reads; each may appear once.
CHECKED_HEADERS = ("Host", "Origin", "Sec-Fetch-Site", "Sec-Fetch-Mode", "Sec-Fetch-Dest",
                   "Cookie", "Authorization")
#: Sent with every page: no other site may show the IDE in a frame (clickjacking).
FRAME_POLICY = "frame-ancestors 'self'"


@dataclass(frozen=True)
class Page:
    """A static file served beside viser's client (GET only)."""

    body: bytes
    content_type: str


@dataclass(frozen=True)
class Routes:
    """What the IDE serves on viser's port besides viser itself: path -> page or socket."""

    pages: Mapping[str, Page] = field(default_factory=dict)
    sockets: Mapping[str, SocketHandler] = field(default_factory=dict)
    #: Called with the query string of every admitted request for the page itself ("/"), on
    #: the server's event loop: it must return at once (the IDE opens `?scenario=` links).
    on_visit: Callable[[str], None] | None = None


class UnguardedServer(RuntimeError):
    """viser started its server without the call `open_server` guards (a viser upgrade)."""


#: The ambient light that stands in for viser's default environment map (see `open_server`):
#: of 1.0-4.0, 3.5 drew the 25-robot Kilobot gradient closest to the mapped picture.
AMBIENT_INTENSITY = 3.5

#: Only one server is being started at a time: the wrap of `serve` is process-wide.
_STARTING = threading.Lock()


def open_server(
    host: str, port: int, token: str, routes: Routes | None = None
) -> viser.ViserServer:
    """A viser server with the bbzide theme, the control panel docked on the right, and every
    request checked against `token` (see the module docstring)."""
    gate = Gate(AccessPolicy.for_bind(token, host), routes or Routes())
    quiet_handshake_errors()
    quiet_closed_tab_updates()
    with _STARTING, _serve_through(gate), contextlib.redirect_stdout(io.StringIO()):
        server = viser.ViserServer(host=host, port=port, verbose=False)
    if not gate.installed:
        server.stop()
        raise UnguardedServer("viser did not start its server through websockets.serve: "
                              "bbzide cannot check who connects, so it does not serve")
    server.gui.configure_theme(control_width="large", show_share_button=False, dark_mode=False)
    # Docked, not floating: the 3D view then spans only the free area between the panels, so
    # the camera's centre (where the swarm is framed) is visible, not behind the controls.
    server.gui.main_panel.dock_right()
    # No shadows: nothing bbzide draws casts one (robots, rings and overlays are added with
    # cast_shadow=False; grids, lines and points never cast), yet the default lights' shadow
    # pass was a third of each frame in software WebGL (a 25-robot IDE in headless Chromium
    # without a GPU: ~69 -> ~47 ms of CPU a frame at 1400 x 900). The picture is the same.
    server.scene.configure_default_lights(cast_shadow=False)
    # No environment map: a flat ambient light of the same strength instead. The map lights
    # every robot from an HDR photograph, which the page first filters into mipmaps on the
    # GPU: without one (software WebGL) that kept a new page from drawing its first frame for
    # ~2.7 s (open to first frame, 5.5-6.0 -> 2.9-3.0 s, 25 Kilobots). The robots' colours are
    # matched, not guessed: AMBIENT_INTENSITY is the intensity whose Kilobot picture differs
    # least from the mapped one (mean signed difference ~0 over the robots' pixels).
    server.scene.configure_environment_map(hdri=None)
    server.scene.add_light_ambient("/ambient_light", intensity=AMBIENT_INTENSITY)
    return server


def page_url(server: viser.ViserServer, token: str) -> str:
    """The address to open in a browser (a wildcard bind is reached through 127.0.0.1)."""
    host = server.get_host()
    return f"http://{'127.0.0.1' if host in ('0.0.0.0', '') else host}:{server.get_port()}/" \
        f"?token={token}"


class Gate:
    """Our `process_request` and connection handler, wrapped around viser's."""

    def __init__(self, policy: AccessPolicy, routes: Routes) -> None:
        self.policy = policy
        self.routes = routes
        self.installed = False

    def wrap(
        self, handler: SocketHandler, process_request: ProcessRequest | None
    ) -> tuple[SocketHandler, ProcessRequest]:
        self.installed = True

        async def route(connection: ServerConnection) -> None:
            path = connection.request.path.partition("?")[0] if connection.request else ""
            await self.routes.sockets.get(path, handler)(connection)

        def admit(connection: ServerConnection, request: Request) -> Response | None:
            try:
                return self.answer(connection, request, process_request)
            except Exception as error:  # noqa: BLE001 - one line, never a traceback
                print(f"bbzide: error answering {request.path[:80]!r}: "
                      f"{type(error).__name__}: {error}", file=sys.stderr)
                return _text(connection, HTTPStatus.INTERNAL_SERVER_ERROR, "internal error")

        return route, admit

    def answer(
        self,
        connection: ServerConnection,
        request: Request,
        process_request: ProcessRequest | None,
    ) -> Response | None:
        headers: dict[str, str] = {}
        for name in CHECKED_HEADERS:
            values = request.headers.get_all(name)
            if len(values) > 1:  # which one would count? (a smuggling attempt, or a broken client)
                return _text(connection, HTTPStatus.BAD_REQUEST, f"duplicate {name} header")
            if values:
                headers[name] = values[0]
        verdict = check_request(self.policy, request.path, headers, connection.local_address[:2])
        if not verdict.allowed:
            assert verdict.status is not None
            return _text(connection, verdict.status, verdict.reason)
        if any(value.lower() == "websocket" for value in request.headers.get_all("Upgrade")):
            return None  # the handshake goes on: `route` picks the handler
        page = self.routes.pages.get(request.path.partition("?")[0])
        if page is not None:
            response = Response(HTTPStatus.OK, "OK", Headers({
                "Content-Type": page.content_type,
                "Content-Length": str(len(page.body)),
                "Cache-Control": "no-store",
            }), page.body)
        elif process_request is not None:
            path, _, query = request.path.partition("?")
            if path == "/" and query and self.routes.on_visit is not None:
                self.routes.on_visit(query)
            response = process_request(connection, request)
            if response is not None and response.status_code >= 400 and not response.body:
                status = HTTPStatus(response.status_code)  # viser's 404 has no text: give one
                response = _text(connection, status, status.phrase.lower())
        else:
            response = _text(connection, HTTPStatus.NOT_FOUND, "not found")
        if response is not None:
            self._decorate(response, verdict, connection.local_address[1])
        return response

    def _decorate(self, response: Response, verdict: Verdict, port: int) -> None:
        response.headers["Content-Security-Policy"] = FRAME_POLICY
        response.headers["X-Content-Type-Options"] = "nosniff"
        if verdict.set_cookie:
            response.headers["Set-Cookie"] = self.policy.cookie_header(port)


def _text(connection: ServerConnection, status: HTTPStatus, reason: str) -> Response:
    """A one-line plain-text answer; it may quote the request (a host name), so the browser is
    told never to read it as anything but text."""
    response = connection.respond(status, reason + "\n")
    response.headers["X-Content-Type-Options"] = "nosniff"
    return response


@contextlib.contextmanager
def _serve_through(gate: Gate) -> Iterator[None]:
    """While viser starts: every `websockets.asyncio.server.serve(...)` goes through `gate`."""
    module = websockets.asyncio.server
    original = module.serve

    def guarded_serve(handler: SocketHandler, *args: object, **kwargs: object) -> object:
        handler, kwargs["process_request"] = gate.wrap(
            handler, kwargs.get("process_request")  # type: ignore[arg-type]
        )
        kwargs.setdefault("create_connection", AnsweringConnection)
        return original(handler, *args, **kwargs)  # type: ignore[arg-type]

    module.serve = guarded_serve  # type: ignore[assignment,misc]
    try:
        yield
    finally:
        module.serve = original  # type: ignore[misc]


#: Longest request head read before answering 431: `websockets` itself allows up to 128 header
#: lines of 8 KB; a browser's head is 1-2 KB, so 64 KB is far above any real one.
MAX_HEAD_BYTES = 64 * 1024


def head_problem(head: bytes) -> tuple[HTTPStatus, str] | None:
    """Why the IDE's port cannot take a request with this head (request line and headers,
    without the blank line), or None: it serves GET requests without a body only."""
    lines = head.split(b"\n")
    parts = lines[0].strip().split(b" ")
    if len(parts) != 3:
        return HTTPStatus.BAD_REQUEST, "malformed request line"
    method, _, version = parts
    if method != b"GET":
        return HTTPStatus.METHOD_NOT_ALLOWED, "only GET requests and websockets are served here"
    if version != b"HTTP/1.1":
        return HTTPStatus.HTTP_VERSION_NOT_SUPPORTED, "HTTP/1.1 only"
    for line in lines[1:]:
        name, colon, value = line.partition(b":")
        if not colon:
            return HTTPStatus.BAD_REQUEST, "malformed header line"
        name, value = name.strip().lower(), value.strip()
        if name == b"transfer-encoding":
            return HTTPStatus.BAD_REQUEST, "request bodies are not accepted"
        if name == b"content-length":
            if not value.isdigit():
                return HTTPStatus.BAD_REQUEST, "bad Content-Length"
            if int(value) > 0:
                return HTTPStatus.BAD_REQUEST, "request bodies are not accepted"
    return None


class AnsweringConnection(ServerConnection):
    """A `websockets` connection that answers, rather than drops, a request it cannot take."""

    _head = b""
    _decided = False

    def data_received(self, data: bytes) -> None:
        if self._decided:
            super().data_received(data)
            return
        self._head += data
        end = max(self._head.find(b"\r\n\r\n"), self._head.find(b"\n\n"))
        if end < 0:
            if len(self._head) > MAX_HEAD_BYTES:
                self._answer(HTTPStatus.REQUEST_HEADER_FIELDS_TOO_LARGE, "request head too large")
            return
        problem = head_problem(self._head[:end].replace(b"\r\n", b"\n"))
        if problem is not None:
            self._answer(*problem)
            return
        self._decided = True
        received, self._head = self._head, b""
        super().data_received(received)

    def _answer(self, status: HTTPStatus, reason: str) -> None:
        self._decided = True
        body = (reason + "\n").encode()
        self.transport.write(
            f"HTTP/1.1 {status.value} {status.phrase}\r\n"
            "Content-Type: text/plain; charset=utf-8\r\n"
            f"Content-Length: {len(body)}\r\nConnection: close\r\n\r\n".encode() + body
        )
        self.transport.close()


#: Failures of a request the client got wrong (it was answered 400 or the connection dropped).
CLIENT_FAULTS = (
    websockets.exceptions.InvalidMessage,
    websockets.exceptions.InvalidHandshake,
    EOFError,
    OSError,
    TimeoutError,
)


class _OneLineRecords(logging.Filter):
    """Drops handshake failures caused by the client; shortens anything else to one line."""

    def filter(self, record: logging.LogRecord) -> bool:
        error = record.exc_info[1] if record.exc_info else None
        if record.getMessage() == "opening handshake failed" and (
            error is None or isinstance(error, CLIENT_FAULTS)
        ):
            return False
        if error is not None:
            record.msg = f"bbzide: {record.getMessage()}: {type(error).__name__}: {error}"
            record.args = None
            record.exc_info = None
            record.exc_text = None
        return True


#: The start of viser's warning for a message to a disconnected client (viser 1.1.1), a regex.
CLOSED_TAB_UPDATE = r"Queued a \w+ on a closed connection"


def quiet_closed_tab_updates() -> None:
    """Drop viser's warning for a panel update that reached a tab after it closed."""
    warnings.filterwarnings("ignore", message=CLOSED_TAB_UPDATE, category=UserWarning)


def quiet_handshake_errors() -> None:
    """Install `_OneLineRecords` on the `websockets` server logger (once)."""
    logger = logging.getLogger("websockets.server")
    if not any(isinstance(each, _OneLineRecords) for each in logger.filters):
        logger.addFilter(_OneLineRecords())
