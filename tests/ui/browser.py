"""Headless Chromium for the browser tests (recipe: ui-stack-notes §3).

Debian's /usr/bin/chromium through Playwright's Python package. One Chromium per process and
set of flags serves one module after another: each `chromium_context` is a fresh browser
context of it (its own cookies, storage and cache, as a new profile has), so a module does not
pay for starting a browser (~1.3 s on an idle machine, over 2 s in a full parallel run).
`close_browsers` ends them; tests/ui/conftest.py calls it before a module of another kind runs,
since between its calls Playwright's sync API leaves its event loop marked as running in the
test thread.

Every request the pages make is recorded in `context.foreign_requests` when it goes anywhere but
127.0.0.1 (tests assert that list stays empty). Requests are only observed, never routed: a
Playwright route handler runs only while the test thread is inside a Playwright call, so routing
would stall the editor's fetches whenever a test sleeps or polls the server.
"""

from __future__ import annotations

import contextlib
import socket
import time
from collections.abc import Callable, Iterator

CHROMIUM = "/usr/bin/chromium"
CHROMIUM_ARGS = [
    "--headless",
    "--no-sandbox",
    "--disable-gpu",
    "--disable-quic",
    "--no-first-run",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
]
#: Pages draw at most ~15 frames a second. viser draws continuously for 250 ms after every
#: scene update, so a running swarm keeps its page drawing as fast as it can; in software WebGL
#: (no GPU) that took ~1.7 of the machine's 2 cores, starving the tests that run beside it.
#: Every frame a test waits for still comes (`get_render`, screenshots), only fewer of them.
FRAME_INTERVAL_MS = 66
FRAME_PACING = f"""
window.requestAnimationFrame = (draw) => setTimeout(() => draw(performance.now()),
                                                    {FRAME_INTERVAL_MS});
window.cancelAnimationFrame = (id) => clearTimeout(id);
"""
#: First frame in software WebGL takes 3-13 s on 2 shared cores (ui-stack-notes §3).
FIRST_RENDER_TIMEOUT_MS = 60_000
#: How long a UI reaction (a save, a compile, a robots' reload, an error marker, a pause) may
#: take before a test calls it hung. It bounds liveness, not speed: during a full-suite run on
#: the 2 shared cores a reload took over 15 s; speed figures live in benchmarks/.
UI_WAIT_S = 60.0
UI_WAIT_MS = int(UI_WAIT_S * 1000)


def free_port() -> int:
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        return probe.getsockname()[1]


def wait_until(
    predicate: Callable[[], object],
    timeout: float = 30.0,
    interval: float = 0.05,
    message: str = "condition",
) -> object:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        value = predicate()
        if value:
            return value
        time.sleep(interval)
    raise AssertionError(f"timed out after {timeout} s waiting for {message}")


#: Clicks `set_checkbox` makes before it calls a checkbox deaf to them.
CHECKBOX_CLICKS = 3


def set_checkbox(box: object, checked: bool) -> None:
    """Click checkbox `box` (a Playwright locator) until the page shows it `checked`, as a user
    clicks again a box that did not tick. Playwright's `set_checked` raises when its click left
    the state as it was: a click that landed while the control panel was still laying out a
    folder just opened around the box (the panel and the folder's wrapper were reported
    covering it). The box is clicked again only while it still shows the old state."""
    from playwright.sync_api import Error as PlaywrightError

    for _click in range(CHECKBOX_CLICKS):
        if box.is_checked() == checked:  # type: ignore[attr-defined]
            return
        with contextlib.suppress(PlaywrightError):
            box.set_checked(checked)  # type: ignore[attr-defined]
    if box.is_checked() != checked:  # type: ignore[attr-defined]
        raise AssertionError(f"{CHECKBOX_CLICKS} clicks left the checkbox at {not checked}")


#: the Playwright driver and its browsers, by their extra flags (`shared_browser`)
_playwright: list[object] = []
_browsers: dict[tuple[str, ...], object] = {}


def shared_browser(extra_args: tuple[str, ...] = ()) -> object:
    """This process's Chromium started with `extra_args`, started on first use."""
    if not _playwright:
        from playwright.sync_api import sync_playwright

        _playwright.append(sync_playwright().start())
    if extra_args not in _browsers:
        _browsers[extra_args] = _playwright[0].chromium.launch(  # type: ignore[attr-defined]
            executable_path=CHROMIUM, headless=True, args=[*CHROMIUM_ARGS, *extra_args])
    return _browsers[extra_args]


def close_browsers() -> None:
    """Close every shared Chromium and stop the Playwright driver (nothing if none runs)."""
    for browser in _browsers.values():
        browser.close()  # type: ignore[attr-defined]
    _browsers.clear()
    if _playwright:
        _playwright.pop().stop()  # type: ignore[attr-defined]


@contextlib.contextmanager
def chromium_context(
    width: int = 1400, height: int = 900, extra_args: tuple[str, ...] = ()
) -> Iterator[object]:
    context = shared_browser(tuple(extra_args)).new_context(  # type: ignore[attr-defined]
        viewport={"width": width, "height": height})
    foreign: list[str] = []

    def record(request: object) -> None:
        url = request.url  # type: ignore[attr-defined]
        if not url.startswith(("http://127.0.0.1", "ws://127.0.0.1", "data:", "blob:")):
            foreign.append(url)

    context.add_init_script(FRAME_PACING)
    context.on("request", record)
    context.foreign_requests = foreign  # type: ignore[attr-defined]
    try:
        yield context
    finally:
        context.close()


#: How long a page may take to show viser's "Software WebGL rendering detected" notice after
#: its first frame (it comes with the first frames; a machine with a GPU never shows it).
GL_NOTICE_WAIT_MS = 5_000


def dismiss_software_gl_notice(page: object) -> bool:
    """Close viser's software-WebGL notice (top of the 3D view) the way a user would, with its
    close button, so a screenshot shows the scene; False when no notice came."""
    from playwright.sync_api import TimeoutError as PlaywrightTimeout

    notice = page.locator(  # type: ignore[attr-defined]
        ".mantine-Notification-root", has_text="Software WebGL").first
    try:
        notice.wait_for(state="visible", timeout=GL_NOTICE_WAIT_MS)
    except PlaywrightTimeout:
        return False
    notice.locator("button").first.click()
    notice.wait_for(state="detached", timeout=GL_NOTICE_WAIT_MS)
    return True


def render_barrier(page: object, client: object) -> None:
    """Return once `client`'s tab has rendered a frame (`get_render`), rendered at half its
    canvas's size: a render of another shape makes the tab report a camera of that shape, and
    the scene frames a tab whose canvas changed shape again (`SwarmScene.aim_camera`), moving
    a camera a test has just set."""
    box = page.locator("canvas").first.bounding_box()  # type: ignore[attr-defined]
    client.get_render(  # type: ignore[attr-defined]
        height=max(1, round(box["height"] / 2)), width=max(1, round(box["width"] / 2)))


def open_app_page(context: object, app: object) -> object:
    """A new tab on `app` (IdeApp or ReplayApp), returned once the websocket is up and a
    first frame has been rendered: what a user sees when the page has loaded."""
    page = context.new_page()  # type: ignore[attr-defined]
    page.set_default_timeout(FIRST_RENDER_TIMEOUT_MS)
    page.goto(app.url, wait_until="domcontentloaded")  # type: ignore[attr-defined]
    server = app.server  # type: ignore[attr-defined]
    wait_until(lambda: server.get_clients(), UI_WAIT_S, message="websocket")
    page.wait_for_selector("canvas")
    client = next(iter(server.get_clients().values()))
    started = time.monotonic()
    render_barrier(page, client)
    print(f"first render after {time.monotonic() - started:.1f} s")
    return page
