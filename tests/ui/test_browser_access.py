"""Who can reach a running IDE, tried in a real (headless) Chromium and with plain HTTP clients.

The attacks: a page served from another origin (127.0.0.5, and another port of 127.0.0.1, which
is "same-site" and so carries the IDE's cookie) tries to overwrite the script with a blind POST,
to read the editor and the script, and to open the editor's and viser's websockets; a page whose
domain resolves to 127.0.0.1 (DNS rebinding, simulated with Chromium's host resolver rules)
opens the IDE by that name even with the token; a plain client (what `curl` does) sends every
route and websocket handshake without the token, with a forged Host and with an Origin. The IDE
itself must keep working with the token, also bound on every interface (``--host 0.0.0.0``) and
loaded through a non-loopback address of this machine.
"""

from __future__ import annotations

import contextlib
import http.client
import http.server
import json
import socket
import threading
from collections.abc import Iterator
from pathlib import Path

import pytest
import websockets.sync.client
from browser import UI_WAIT_S, chromium_context, free_port, open_app_page, wait_until
from doubles import FakeBackend
from ide_harness import SCREENSHOT_DIR, IdeSession, editor_text
from test_browser_replay import toy_replay_session

from bbzide.ui.access import cookie_name
from bbzide.ui.app import IdeApp
from bbzide.ui.replay_app import ReplayApp
from bbzide.ui.run_controller import RunSettings

SCRIPT = "# guarded\nfunction init() {\n  x = 1\n}\n\nfunction step() {\n  x = x + 1\n}\n"
VISER_PROTOCOL = "viser-v1.1.1"  # the subprotocol viser's own client asks for

#: What a hostile page runs: every way in that a page has, each result recorded.
ATTACK_JS = """
async (ide) => {
  const results = {};
  const body = JSON.stringify({op: "save", text: "pwned", base_revision: 0, id: 1});
  try {
    await fetch(ide + "/editor/socket", {method: "POST", mode: "no-cors", body});
    results.blind_post = "sent";
  } catch (error) { results.blind_post = "failed"; }
  for (const path of ["/editor/", "/", "/editor/dist/editor.js", "/editor/reference.md"]) {
    try {
      const answer = await fetch(ide + path);
      results["read " + path] = "READ " + answer.status + " " + (await answer.text()).slice(0, 30);
    } catch (error) { results["read " + path] = "blocked"; }
  }
  const socketTry = (url, protocols) => new Promise((resolve) => {
    const socket = new WebSocket(url, protocols);
    socket.onopen = () => {
      socket.send(JSON.stringify({id: 2, op: "source"}));
      socket.send(body);
      socket.onmessage = (message) => resolve("OPEN and answered: " + message.data.slice(0, 60));
    };
    socket.onerror = () => resolve("refused");
    socket.onclose = (event) => resolve("closed " + event.code);
  });
  const ws = ide.replace("http://", "ws://");
  results.editor_socket = await socketTry(ws + "/editor/socket", []);
  results.viser_socket = await socketTry(ws + "/", [VISER]);
  return results;
}
"""


#: The rebinding attacker's domain: this browser resolves it to 127.0.0.1, as a DNS server
#: under the attacker's control would once its page is loaded.
REBOUND = "rebind.example"


@pytest.fixture(scope="module")
def ide(tmp_path_factory: pytest.TempPathFactory) -> Iterator[IdeSession]:
    script = tmp_path_factory.mktemp("access") / "main.bzz"
    script.write_text(SCRIPT)
    app = IdeApp(script, FakeBackend(), RunSettings("fake-table", 5, 1, 30.0),
                 port=free_port()).start(run=False)
    try:
        with chromium_context(extra_args=(f"--host-resolver-rules=MAP {REBOUND} 127.0.0.1",)
                              ) as context:
            yield IdeSession(app, context, open_app_page(context, app))
    finally:
        app.stop()


def origin_of(app: IdeApp, host: str = "127.0.0.1") -> str:
    return f"http://{host}:{app.server.get_port()}"


@contextlib.contextmanager
def hostile_site(host: str) -> Iterator[str]:
    """Another web site: a page served from `host` on a port of its own; yields its address."""
    page = b"<!doctype html><title>elsewhere</title><p>an ordinary page elsewhere</p>"

    class Handler(http.server.BaseHTTPRequestHandler):
        def do_GET(self) -> None:  # noqa: N802 - stdlib naming
            self.send_response(200)
            self.send_header("Content-Type", "text/html")
            self.send_header("Content-Length", str(len(page)))
            self.end_headers()
            self.wfile.write(page)

        def log_message(self, format: str, *args: object) -> None:  # noqa: A002
            return

    server = http.server.ThreadingHTTPServer((host, 0), Handler)
    thread = threading.Thread(target=server.serve_forever, daemon=True)
    thread.start()
    try:
        yield f"http://{host}:{server.server_address[1]}/"
    finally:
        server.shutdown()
        server.server_close()


@pytest.mark.parametrize("attacker_host", ["127.0.0.5", "127.0.0.1"])
def test_a_page_of_another_origin_can_neither_write_read_nor_connect(
    ide: IdeSession, attacker_host: str
) -> None:
    """127.0.0.1 on another port is the hard case: same site, so the browser sends the IDE's
    cookie (this context has loaded the IDE); only the origin checks stand in the way."""
    app = ide.app
    revision, clients = app.session.revision, set(app.server.get_clients())
    with hostile_site(attacker_host) as site:
        page = ide.context.new_page()  # type: ignore[attr-defined]
        try:
            page.goto(site)
            results = page.evaluate(ATTACK_JS.replace("VISER", json.dumps(VISER_PROTOCOL)),
                                    origin_of(app))
        finally:
            page.close()
    print(json.dumps(results, indent=1))
    assert results["editor_socket"] in ("refused", "closed 1006"), results
    assert results["viser_socket"] in ("refused", "closed 1006"), results
    assert not any(str(value).startswith("READ") for value in results.values()), results
    assert Path(app.session.path).read_text() == SCRIPT  # nothing written
    assert app.session.revision == revision and app.session.text == SCRIPT
    assert set(app.server.get_clients()) == clients  # no viser client was let in


def test_a_rebound_domain_is_refused_even_with_the_token(ide: IdeSession) -> None:
    """DNS rebinding: `rebind.example` resolves to 127.0.0.1 in this browser; its page would be
    same-origin with the IDE if the IDE answered to that name."""
    app = ide.app
    clients = set(app.server.get_clients())
    page = ide.context.new_page()  # type: ignore[attr-defined]
    try:
        answer = page.goto(app.url.replace("127.0.0.1", REBOUND))
        assert answer is not None and answer.status == 403
        assert "unknown host" in page.content()
        opened = page.evaluate("""(url) => new Promise((resolve) => {
            const socket = new WebSocket(url);
            socket.onopen = () => resolve("OPEN");
            socket.onerror = () => resolve("refused");
        })""", f"ws://{REBOUND}:{app.server.get_port()}/editor/socket")
        assert opened == "refused"
    finally:
        page.close()
    assert set(app.server.get_clients()) == clients


def plain_get(port: int, path: str, host: str = "127.0.0.1", **headers: str) -> tuple[int, str]:
    connection = http.client.HTTPConnection(host, port, timeout=UI_WAIT_S)
    try:
        connection.request("GET", path, headers=headers)
        answer = connection.getresponse()
        return answer.status, answer.read(200).decode("utf-8", "replace")
    finally:
        connection.close()


def handshake(port: int, path: str, host: str = "127.0.0.1", **headers: str) -> str:
    """A websocket handshake sent as raw bytes (as `curl` would): "open" (101) or the status."""
    fields = {"Host": f"{host}:{port}", "Upgrade": "websocket", "Connection": "Upgrade",
              "Sec-WebSocket-Key": "dGhlIHNhbXBsZSBub25jZQ==", "Sec-WebSocket-Version": "13"}
    if path == "/":
        fields["Sec-WebSocket-Protocol"] = VISER_PROTOCOL
    fields.update(headers)
    head = f"GET {path} HTTP/1.1\r\n" + "".join(f"{k}: {v}\r\n" for k, v in fields.items())
    status = raw_status(port, head.encode() + b"\r\n", host)
    return "open" if status == "101" else status


def raw_status(port: int, request: bytes, host: str = "127.0.0.1") -> str:
    """Send `request` as it is; the status code of the answer ("" if there was none)."""
    with socket.create_connection((host, port), timeout=UI_WAIT_S) as connection:
        connection.sendall(request)
        first_line = connection.recv(4096).split(b"\r\n", 1)[0].split()
    return first_line[1].decode() if len(first_line) > 1 else ""


def test_without_the_token_a_plain_client_gets_nothing(ide: IdeSession) -> None:
    app = ide.app
    port = app.server.get_port()
    for path in ("/", "/index.html", "/editor/", "/editor/dist/editor.js", "/editor/reference",
                 "/editor/socket", "/no-such-file"):
        status, text = plain_get(port, path)
        assert status == 403 and "token" in text, (path, status, text)
    assert plain_get(port, "/?token=not-the-token")[0] == 403
    assert handshake(port, "/") == "403"
    assert handshake(port, "/editor/socket") == "403"
    assert Path(app.session.path).read_text() == SCRIPT


def test_a_forged_host_or_origin_is_refused_even_with_the_token(ide: IdeSession) -> None:
    app = ide.app
    port = app.server.get_port()
    token = app.token
    for host in (f"evil.example:{port}", f"127.0.0.1:{port + 1}", "localhost"):
        assert plain_get(port, f"/?token={token}", Host=host)[0] == 403, host
        assert handshake(port, "/editor/socket", Host=host,
                         Authorization=f"token {token}") == "403"
    assert handshake(port, "/editor/socket", Origin="http://127.0.0.5:8000",
                     Authorization=f"token {token}") == "403"
    assert handshake(port, "/", Origin="null", Authorization=f"token {token}") == "403"
    # two Host headers: the check must not read one while something else uses the other
    twice = f"GET /?token={token} HTTP/1.1\r\nHost: 127.0.0.1:{port}\r\nHost: evil\r\n\r\n"
    assert raw_status(port, twice.encode()) == "400"
    # the same requests with the IDE's own names pass
    assert plain_get(port, f"/?token={token}", Host=f"localhost:{port}")[0] == 200
    assert handshake(port, "/editor/socket", Origin=origin_of(app),
                     Authorization=f"token {token}") == "open"


def test_with_the_token_a_script_can_use_the_editor_socket(ide: IdeSession) -> None:
    """`Authorization: token ...` (scripted use) and the cookie both open the socket."""
    app = ide.app
    port = app.server.get_port()
    for headers in ({"Authorization": f"token {app.token}"},
                    {"Cookie": f"{cookie_name(port)}={app.token}"}):
        with websockets.sync.client.connect(f"ws://127.0.0.1:{port}/editor/socket",
                                            additional_headers=headers) as socket_:
            socket_.send(json.dumps({"id": 7, "op": "source"}))
            reply = json.loads(socket_.recv(timeout=UI_WAIT_S))
        assert reply["id"] == 7 and reply["code"] == 200 and reply["text"] == SCRIPT


def test_the_ide_works_with_the_token_and_sets_its_cookie(ide: IdeSession) -> None:
    editor = ide.editor
    source = editor.locator("#source")  # type: ignore[attr-defined]
    wait_until(lambda: editor_text(source) == SCRIPT, UI_WAIT_S, message="script in the editor")
    cookies = {c["name"]: c for c in ide.context.cookies()}  # type: ignore[attr-defined]
    cookie = cookies[cookie_name(ide.app.server.get_port())]
    assert cookie["value"] == ide.app.token and cookie["httpOnly"]
    assert cookie["sameSite"] == "Strict"
    assert ide.page.evaluate("document.cookie") == ""  # type: ignore[attr-defined]
    source.click()
    ide.page.keyboard.press("Control+End")  # type: ignore[attr-defined]
    ide.page.keyboard.type("# typed\n")  # type: ignore[attr-defined]
    ide.settled("# typed")
    assert Path(ide.app.session.path).read_text().endswith("# typed\n")
    ide.screenshot("access_ide_with_token")
    ide.app.session.edit_from_browser(SCRIPT)  # back to the text the other tests expect


def machine_address() -> str | None:
    """A non-loopback IPv4 address of this machine: the one its route to the outside uses (a UDP
    socket's connect only picks the route; nothing is sent), or None without a network."""
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as probe:
        try:
            probe.connect(("198.51.100.1", 9))  # TEST-NET-2: never a real host
        except OSError:
            return None
        address = probe.getsockname()[0]
    return None if address.startswith("127.") else address


def test_bound_on_every_interface_the_ide_works_through_the_machines_address(
    ide: IdeSession, tmp_path: Path
) -> None:
    """`--host 0.0.0.0` for a classroom: another machine opens http://<this machine>:<port>/.
    It listens on every interface for the test's length, behind its own random token."""
    address = machine_address()
    if address is None:
        pytest.skip("this machine has no non-loopback IPv4 address to load the IDE through")
    script = tmp_path / "main.bzz"
    script.write_text(SCRIPT)
    app = IdeApp(script, FakeBackend(), RunSettings("fake-table", 5, 1, 30.0), host="0.0.0.0",
                 port=free_port()).start(run=False)
    try:
        port = app.server.get_port()
        assert plain_get(port, "/", host=address)[0] == 403  # the token is still needed
        assert plain_get(port, f"/?token={app.token}", host=address,
                         Host=f"evil.example:{port}")[0] == 403
        url = app.url.replace("127.0.0.1", address)
        page = open_app_page(ide.context, _At(app, url))
        try:
            frame = page.frame_locator("iframe.bbzide-editor")
            source = frame.locator("#source")
            wait_until(lambda: editor_text(source) == SCRIPT, UI_WAIT_S,
                       message="script in the editor loaded through " + address)
            source.click()
            page.keyboard.press("Control+End")
            page.keyboard.type("# from afar\n")
            wait_until(lambda: app.session.text.endswith("# from afar\n"), UI_WAIT_S,
                       message="the edit saved")
            SCREENSHOT_DIR.mkdir(parents=True, exist_ok=True)
            page.screenshot(path=str(SCREENSHOT_DIR / "access_wildcard_bind.png"))
        finally:
            page.close()
        assert script.read_text().endswith("# from afar\n")
    finally:
        app.stop()


class _At:
    """`app` as `open_app_page` sees it, reached at another address."""

    def __init__(self, app: IdeApp, url: str) -> None:
        self.server = app.server
        self.url = url


def test_the_replay_is_guarded_the_same_way(tmp_path: Path) -> None:
    """`bbzide replay` stands on the same server: no token, a forged host, another origin: 403."""
    session = toy_replay_session(tmp_path / "toy.rrd", steps=5)
    app = ReplayApp(session, port=free_port()).start()
    try:
        port = app.server.get_port()
        assert plain_get(port, "/")[0] == 403
        assert handshake(port, "/") == "403"
        assert plain_get(port, f"/?token={app.token}", Host=f"evil.example:{port}")[0] == 403
        assert handshake(port, "/", Origin="http://127.0.0.5:8000",
                         Authorization=f"token {app.token}") == "403"
        assert plain_get(port, f"/?token={app.token}")[0] == 200
        assert handshake(port, "/", Authorization=f"token {app.token}") == "open"
    finally:
        app.stop()
