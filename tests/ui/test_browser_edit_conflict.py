"""A stale editor tab never overwrites newer text: it shows the conflict and keeps both texts.

The stale tab runs on Playwright's fake clock, so its 400 ms typing debounce and its polls fire
only when the test advances the clock: the file is changed behind the tab's back (an external
save, as another editor or another tab does) between the user's typing and the tab's upload,
with no race against real time. The tab's save then carries a base revision older than the
file's; the IDE refuses it (409), the file keeps the newer text, the tab keeps the user's text
and offers "Take disk version" or "Overwrite with mine".
"""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import pytest
from browser import UI_WAIT_MS, UI_WAIT_S, wait_until
from doubles import FakeBackend
from ide_harness import SCREENSHOT_DIR, IdeSession, editor_text, running_ide

from bbzide.ui.program_session import write_atomically

SCRIPT = "# shared\nfunction init() {\n  x = 1\n}\n"
#: Past the editor's typing debounce (EDIT_DEBOUNCE_MS = 400 in editor/src/editor.js) and a poll.
PAST_DEBOUNCE_MS = 1000


@pytest.fixture(scope="module")
def ide(tmp_path_factory: pytest.TempPathFactory) -> Iterator[IdeSession]:
    script = tmp_path_factory.mktemp("conflict") / "main.bzz"
    script.write_text(SCRIPT)
    with running_ide(script, FakeBackend(), "fake-table", 3, run=False) as session:
        yield session


def stale_tab(ide: IdeSession) -> object:
    """The editor in a tab of its own, on a fake clock, showing the file's current text."""
    page = ide.context.new_page()  # type: ignore[attr-defined]
    page.set_viewport_size({"width": 640, "height": 360})
    page.clock.install()
    page.goto(ide.app.editor_url)  # the IDE's cookie (set by the main tab) lets it in
    source = page.locator("#source")
    text = ide.app.session.text
    wait_until(lambda: editor_text(source) == text, UI_WAIT_S, message="the tab loaded")
    return page


def type_at_end(page: object, text: str) -> None:
    page.locator("#source").click()  # type: ignore[attr-defined]
    page.keyboard.press("Control+End")  # type: ignore[attr-defined]
    page.keyboard.type(text)  # type: ignore[attr-defined]


def save_behind_the_tabs_back(ide: IdeSession, text: str) -> None:
    write_atomically(ide.app.session.path, text)
    wait_until(lambda: ide.app.session.text == text, UI_WAIT_S, message="external save seen")


def test_a_stale_tab_keeps_both_texts_and_overwrites_only_when_told(ide: IdeSession) -> None:
    session = ide.app.session
    page = stale_tab(ide)
    try:
        type_at_end(page, "# mine\n")
        theirs = SCRIPT + "# theirs\n"
        save_behind_the_tabs_back(ide, theirs)
        revision = session.revision
        page.clock.run_for(PAST_DEBOUNCE_MS)  # type: ignore[attr-defined]  # the upload goes
        notice = page.locator("#conflict")  # type: ignore[attr-defined]
        notice.wait_for(state="visible", timeout=UI_WAIT_MS)
        mine = editor_text(page.locator("#source"))  # type: ignore[attr-defined]
        assert mine.endswith("# mine\n") and "# theirs" not in mine  # the user's text stays
        assert Path(session.path).read_text() == theirs  # the newer text was not overwritten
        assert session.revision == revision
        assert "not saved" in page.locator("#status").inner_text()  # type: ignore[attr-defined]
        SCREENSHOT_DIR.mkdir(parents=True, exist_ok=True)
        page.screenshot(path=str(SCREENSHOT_DIR / "edit_conflict_notice.png"))  # type: ignore[attr-defined]
        page.clock.run_for(PAST_DEBOUNCE_MS)  # type: ignore[attr-defined]  # polls: no reload
        assert editor_text(page.locator("#source")) == mine  # type: ignore[attr-defined]
        page.locator("#overwrite").click()  # type: ignore[attr-defined]
        wait_until(lambda: session.text == mine, UI_WAIT_S, message="overwrite saved")
        assert Path(session.path).read_text() == mine
        notice.wait_for(state="hidden", timeout=UI_WAIT_MS)
    finally:
        page.close()  # type: ignore[attr-defined]


def test_a_stale_tab_can_take_the_disk_version(ide: IdeSession) -> None:
    session = ide.app.session
    page = stale_tab(ide)
    try:
        type_at_end(page, "# draft\n")
        theirs = session.text + "# from vim\n"
        save_behind_the_tabs_back(ide, theirs)
        page.clock.run_for(PAST_DEBOUNCE_MS)  # type: ignore[attr-defined]
        page.locator("#conflict").wait_for(state="visible", timeout=UI_WAIT_MS)  # type: ignore[attr-defined]
        assert Path(session.path).read_text() == theirs
        page.locator("#take-disk").click()  # type: ignore[attr-defined]
        source = page.locator("#source")  # type: ignore[attr-defined]
        wait_until(lambda: editor_text(source) == theirs, UI_WAIT_S, message="disk text shown")
        page.clock.run_for(PAST_DEBOUNCE_MS)  # type: ignore[attr-defined]
        type_at_end(page, "# next\n")  # the tab is in step again: its next save goes through
        page.clock.run_for(PAST_DEBOUNCE_MS)  # type: ignore[attr-defined]
        wait_until(lambda: session.text == theirs + "# next\n", UI_WAIT_S, message="saved")
        assert page.locator("#conflict").is_hidden()  # type: ignore[attr-defined]
    finally:
        page.close()  # type: ignore[attr-defined]
