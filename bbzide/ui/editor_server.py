"""The Buzz editor's page and its websocket, served on the IDE's own (viser's) port.

viser 1.1.1 has no code-editor widget (its multiline text input is a plain textarea without
line numbers, highlighting or markers), so the editor is our own page: `static/editor.html|css`
and CodeMirror 6 with our Buzz mode, completion and hover (editor/src/), which `make setup`
bundles into `static/dist/` (`npm ci` + editor/build.mjs; never committed). It is shown inside
the viser panel in an <iframe src="/editor/">. `editor_routes` hands the page's files, the Buzz
reference page (``/editor/reference``, from the same tables as the completion) and the
websocket, ``/editor/socket``, to `bbzide.ui.viser_server`, which checks every request (token,
origin, host) before they get here. Without a built bundle the page says how to build it.

The page and `ProgramSession` talk over that websocket in JSON: the page sends
``{"id": n, "op": ..., ...}`` and gets ``{"id": n, "code": <HTTP status>, ...}`` back, where
the code keeps HTTP's meaning (200 done, 400 malformed, 409 conflict, 413 too large):

    {"op": "state"}                               -> session.state()
    {"op": "source"}                              -> {revision, text}
    {"op": "save", "text": s, "base_revision": r} -> state and saved_revision (the revision now
                                                     holding s), or 409 with the current
                                                     {revision, text}
    {"op": "compile"}                             -> state
    {"op": "reference"}                           -> {world, items}: the built-ins and the
                                                     world's host functions for completion and
                                                     hover (`completion_items`)
    {"op": "breakpoints", "revision": r,          -> state: the page's breakpoints for text
     "breakpoints": [{line, condition, robot,        revision r (`bbzide.ui.breakpoints`); the
                      hit_count}]}                   ones on lines without code are dropped

Every state carries ``world``, the world the program runs in, so the page asks for the
reference again when the user switches worlds; ``breakpoints`` and ``breakpoints_revision``,
the list in force and the text revision it belongs to; and ``paused``, where the debugger
stopped (``{line, robot, reason, revision}``, the revision of the program the robots run), or
null while the swarm runs.

A save names the revision it was based on; if the file changed since (another tab, an external
editor), nothing is written and the page shows both texts (`ProgramSession.edit_from_browser`).
Only the one `.bzz` file of the session can be written, and only atomically. Each message is
answered in a worker thread (a compile takes up to a second), so viser's event loop, which
carries the 3D scene, never waits for one. A malformed message gets a 4xx answer and the
connection stays open; nothing a page sends reaches the terminal as a traceback.
"""

from __future__ import annotations

import asyncio
import json
import sys
from collections.abc import Callable
from http import HTTPStatus
from pathlib import Path
from typing import Any

from websockets.asyncio.server import ServerConnection
from websockets.exceptions import ConnectionClosed

from bbzide.ui.breakpoints import BadBreakpoint, BreakpointBook, parse_breakpoints
from bbzide.ui.program_session import EditConflict, ProgramSession
from bbzide.ui.viser_server import Page, Routes
from bbzide.worlds.reference import completion_items, reference_markdown

STATIC_DIR = Path(__file__).resolve().parent / "static"
#: Where the editor lives on the IDE's port (viser's own client owns "/").
EDITOR_PATH = "/editor/"
SOCKET_PATH = EDITOR_PATH + "socket"
REFERENCE_PATH = EDITOR_PATH + "reference"
HTML = "text/html; charset=utf-8"
SCRIPT = "application/javascript; charset=utf-8"
STATIC_FILES = {
    EDITOR_PATH: ("editor.html", HTML),
    EDITOR_PATH + "editor.css": ("editor.css", "text/css; charset=utf-8"),
    REFERENCE_PATH: ("reference.html", HTML),
}
#: The bundles `make setup` builds (editor/build.mjs): path on the IDE's port -> file in dist/.
BUNDLE_DIR = STATIC_DIR / "dist"
BUNDLES = {
    EDITOR_PATH + "dist/editor.js": "editor.js",
    EDITOR_PATH + "dist/reference.js": "reference.js",
}
#: What a missing bundle says, in the page and once on the terminal.
BUNDLE_MISSING = ("bbzide: the editor bundle is not built (bbzide/ui/static/dist/): run "
                  "`make setup` (it runs npm ci and editor/build.mjs)")
#: Largest message accepted: a generous bound for a Buzz script (the Kilobot flash is 32 KB);
#: a larger one closes the connection (websocket close code 1009) before it is read whole.
MAX_MESSAGE_BYTES = 2 * 1024 * 1024


class BadMessage(ValueError):
    """A message the editor protocol does not allow; answered with `status`."""

    def __init__(self, message: str, status: HTTPStatus = HTTPStatus.BAD_REQUEST) -> None:
        super().__init__(message)
        self.status = status


def editor_routes(session: ProgramSession, world: Callable[[], str | None] = lambda: None,
                  breakpoints: BreakpointBook | None = None,
                  paused: Callable[[], dict[str, Any] | None] = lambda: None) -> Routes:
    """The editor's pages and socket; `world()` names the world the program runs in now,
    `breakpoints` keeps the gutter's breakpoints, `paused()` says where the debugger stopped."""
    pages = {
        path: Page((STATIC_DIR / name).read_bytes(), mime)
        for path, (name, mime) in STATIC_FILES.items()
    }
    pages.update(bundle_pages())
    pages[REFERENCE_PATH + ".md"] = Page(reference_markdown().encode(),
                                         "text/markdown; charset=utf-8")
    return Routes(pages=pages, sockets={SOCKET_PATH: EditorSocket(
        session, world, breakpoints, paused).serve})


def bundle_pages() -> dict[str, Page]:
    """The built bundles; a missing one is replaced by a script that shows `BUNDLE_MISSING` in
    the page (and the terminal says it once), so the IDE still runs and says what to do."""
    pages = {}
    missing = False
    for path, name in BUNDLES.items():
        try:
            body = (BUNDLE_DIR / name).read_bytes()
        except OSError:
            missing = True
            body = ("document.body.textContent = " + json.dumps(BUNDLE_MISSING) + ";").encode()
        pages[path] = Page(body, SCRIPT)
    if missing:
        print(BUNDLE_MISSING, file=sys.stderr)
    return pages


class EditorSocket:
    """Answers one editor page's messages for as long as its websocket is open."""

    def __init__(self, session: ProgramSession,
                 world: Callable[[], str | None] = lambda: None,
                 breakpoints: BreakpointBook | None = None,
                 paused: Callable[[], dict[str, Any] | None] = lambda: None) -> None:
        self.session = session
        self.world = world
        self.breakpoints = breakpoints if breakpoints is not None else BreakpointBook()
        self.paused = paused

    async def serve(self, connection: ServerConnection) -> None:
        connection.protocol.max_message_size = MAX_MESSAGE_BYTES
        pending: set[asyncio.Task[None]] = set()
        try:
            async for message in connection:
                task = asyncio.create_task(self._reply(connection, message))
                pending.add(task)
                task.add_done_callback(pending.discard)
        except ConnectionClosed:
            pass  # the tab closed or sent what the protocol forbids (e.g. too large)
        finally:
            for task in pending:
                task.cancel()

    async def _reply(self, connection: ServerConnection, message: str | bytes) -> None:
        reply = await asyncio.to_thread(self.answer, message)
        try:
            await connection.send(json.dumps(reply))
        except ConnectionClosed:
            pass  # the tab went away while its answer was computed

    def answer(self, message: str | bytes) -> dict[str, Any]:
        """The reply to one message, always a JSON object with the request's id (if any)."""
        request_id: object = None
        try:
            request = parse_message(message)
            request_id = request.get("id")
            return {"id": request_id, "code": int(HTTPStatus.OK), **self._do(request)}
        except EditConflict as conflict:
            return {"id": request_id, "code": int(HTTPStatus.CONFLICT),
                    "error": "the file changed since this text was loaded",
                    "revision": conflict.revision, "text": conflict.text,
                    **self._state()}
        except BadMessage as bad:
            return {"id": request_id, "code": int(bad.status), "error": str(bad)}
        except BadBreakpoint as bad:
            return {"id": request_id, "code": int(HTTPStatus.BAD_REQUEST), "error": str(bad)}
        except OSError as error:  # the disk refused the save: the page shows why
            return {"id": request_id, "code": int(HTTPStatus.INTERNAL_SERVER_ERROR),
                    "error": f"could not save: {error.strerror or error}",
                    **self._state()}

    def _do(self, request: dict[str, Any]) -> dict[str, Any]:
        session = self.session
        op = request.get("op")
        if op == "state":
            return self._state()
        if op == "source":
            return session.source()
        if op == "compile":
            session.compile_now()
            return self._state()
        if op == "reference":
            world = self.world()
            return {"world": world, "items": completion_items(world)}
        if op == "save":
            text = request.get("text")
            base = request.get("base_revision")
            if not isinstance(text, str):
                raise BadMessage("save needs \"text\": a string")
            if not isinstance(base, int) or isinstance(base, bool):
                raise BadMessage("save needs \"base_revision\": the revision the text is based on")
            saved = session.save_from_browser(text, base_revision=base)
            session.ensure_compiled(saved)
            return {**self._state(), "saved_revision": saved}
        if op == "breakpoints":
            revision = request.get("revision")
            if not isinstance(revision, int) or isinstance(revision, bool):
                raise BadMessage("breakpoints needs \"revision\": the text revision of the lines")
            self.breakpoints.set(revision, parse_breakpoints(request.get("breakpoints")))
            return self._state()
        raise BadMessage(
            f"unknown op {op!r}: state, source, save, compile, reference or breakpoints")

    def _state(self) -> dict[str, Any]:
        return {**self.session.state(), "world": self.world(), **self.breakpoints.state(),
                "paused": self.paused()}


def parse_message(message: str | bytes) -> dict[str, Any]:
    """A message as a JSON object, or `BadMessage` saying what is wrong with it."""
    if isinstance(message, bytes):
        raise BadMessage("send JSON text, not binary frames")
    if len(message) > MAX_MESSAGE_BYTES:  # also bounded by the websocket (see serve)
        raise BadMessage("message too large", HTTPStatus.REQUEST_ENTITY_TOO_LARGE)
    try:
        request = json.loads(message)
    except (json.JSONDecodeError, RecursionError):
        raise BadMessage("not JSON") from None
    if not isinstance(request, dict):
        raise BadMessage("the message must be a JSON object")
    return request
