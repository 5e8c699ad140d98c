"""The CodeMirror editor teaches Buzz, in headless Chromium on the real Kilobot world.

Completion offers the world's host functions (from bbzide/worlds/reference.py, the table the
reference page is made of), hovering a built-in or host function shows its signature, doc and
memory cost, Ctrl-Z undoes an edit after it was saved and compiled, and the reference page is
served inside the IDE. Screenshots (1400x900) land in $BBZIDE_SCREENSHOTS.
"""

from __future__ import annotations

from collections.abc import Iterator

import pytest
from browser import UI_WAIT_MS, UI_WAIT_S, wait_until
from ide_harness import SCREENSHOT_DIR, IdeSession, editor_text, running_ide

from bbzide.compiler.reference import BUILTINS
from bbzide.ui.world_adapter import WorldsBackend
from bbzide.worlds.reference import HOST_FUNCTIONS

BACKEND = WorldsBackend()

SCRIPT = (
    "# teaching the editor\n"
    "var colour = 1\n"
    "\n"
    "function init() {\n"
    "  neighbors.broadcast(\"hello\", id)\n"
    "}\n"
    "\n"
    "function step() {\n"
    "  var seen = neighbors.count()\n"
    "  led(colour)\n"
    "}\n"
)


@pytest.fixture(scope="module")
def ide(tmp_path_factory: pytest.TempPathFactory) -> Iterator[IdeSession]:
    script = tmp_path_factory.mktemp("editor") / "teach.bzz"
    script.write_text(SCRIPT)
    with running_ide(script, BACKEND, "kilobot", 4) as session:
        yield session


def host_doc(world: str, name: str) -> tuple[str, str]:
    entry = next(e for e in HOST_FUNCTIONS[world] if e.name == name)
    return entry.signature, entry.doc


def hover_text(ide: IdeSession, text: str) -> None:
    """Move the mouse over the second character of the first `text` in the editor."""
    offset = SCRIPT.index(text) + 1
    where = ide.editor.locator("#source").evaluate(
        "(_, offset) => { const r = window.buzzEditor.view.coordsAtPos(offset);"
        " return {x: (r.left + r.right) / 2, y: (r.top + r.bottom) / 2}; }", offset)
    frame = ide.page.locator("iframe.bbzide-editor").bounding_box()  # type: ignore[attr-defined]
    ide.page.mouse.move(frame["x"] + where["x"] + 3, frame["y"] + where["y"])  # type: ignore[attr-defined]


def test_completion_offers_the_worlds_host_functions(ide: IdeSession) -> None:
    editor = ide.editor
    source = editor.locator("#source")
    wait_until(lambda: editor_text(source) == SCRIPT, UI_WAIT_S, message="script shown")
    source.click()
    keyboard = ide.page.keyboard
    keyboard.press("Control+End")
    keyboard.type("mot")
    options = editor.locator(".cm-tooltip-autocomplete .cm-completionLabel")
    options.first.wait_for(timeout=UI_WAIT_MS)
    labels = options.all_inner_texts()
    assert "motion" in labels, labels  # a Kilobot host function
    signature, doc = host_doc("kilobot", "motion")
    info = editor.locator(".cm-completionInfo")
    info.wait_for(timeout=UI_WAIT_MS)
    assert signature in info.inner_text() and doc.split("(")[0].strip() in info.inner_text()
    ide.screenshot("editor_autocomplete")
    keyboard.press("Enter")
    wait_until(lambda: editor_text(source).endswith("motion"), UI_WAIT_S, message="accepted")
    keyboard.type("(1)")
    ide.settled("motion(1)")
    keyboard.type("\nneighbors.")
    members = editor.locator(".cm-tooltip-autocomplete .cm-completionLabel")
    members.first.wait_for(timeout=UI_WAIT_MS)
    offered = set(members.all_inner_texts())
    assert {"broadcast", "listen", "count"} <= offered, offered
    keyboard.press("Escape")
    source.fill(SCRIPT)
    wait_until(lambda: ide.app.session.text == SCRIPT, UI_WAIT_S, message="script restored")


def test_hover_shows_the_doc_and_memory_cost(ide: IdeSession) -> None:
    editor = ide.editor
    source = editor.locator("#source")
    wait_until(lambda: editor_text(source) == SCRIPT, UI_WAIT_S, message="script shown")
    tooltip = editor.locator(".cm-tooltip-hover .bbz-doc")
    hover_text(ide, "led(colour)")
    tooltip.wait_for(timeout=UI_WAIT_MS)
    signature, doc = host_doc("kilobot", "led")
    assert signature in tooltip.inner_text() and "RGB LED" in tooltip.inner_text()
    ide.screenshot("editor_hover_host_function")
    ide.page.mouse.move(5, 5)
    tooltip.wait_for(state="detached", timeout=UI_WAIT_MS)
    broadcast = next(e for e in BUILTINS if e.name == "neighbors.broadcast")
    hover_text(ide, "broadcast(")
    tooltip.wait_for(timeout=UI_WAIT_MS)
    text = tooltip.inner_text()
    assert broadcast.signature in text and "Memory:" in text and "out-queue" in text
    ide.screenshot("editor_hover_builtin")


def test_undo_works_across_a_compile(ide: IdeSession) -> None:
    app = ide.app
    editor = ide.editor
    source = editor.locator("#source")
    wait_until(lambda: editor_text(source) == SCRIPT, UI_WAIT_S, message="script shown")
    compiled_before = app.session.outcome.revision if app.session.outcome else -1
    source.click()
    ide.page.keyboard.press("Control+End")
    ide.page.keyboard.type("x = 1")
    ide.settled("x = 1")  # saved and compiled: the page got a new state and new markers
    assert app.session.outcome is not None and app.session.outcome.revision > compiled_before
    editor.locator("#compile").click()  # one more compile, as Ctrl-S does
    wait_until(lambda: app.session.outcome.revision == app.session.revision, UI_WAIT_S,
               message="compiled")
    source.focus()
    ide.page.keyboard.press("Control+z")
    wait_until(lambda: editor_text(source) == SCRIPT, UI_WAIT_S, message="undone in the editor")
    wait_until(lambda: app.session.text == SCRIPT, UI_WAIT_S, message="the undo saved")
    ide.page.keyboard.press("Control+y")
    wait_until(lambda: app.session.text == SCRIPT + "x = 1", UI_WAIT_S, message="redone")
    source.fill(SCRIPT)
    wait_until(lambda: app.session.text == SCRIPT, UI_WAIT_S, message="script restored")


def test_reference_page_in_the_ide(ide: IdeSession) -> None:
    page = ide.context.new_page()  # type: ignore[attr-defined]
    try:
        page.goto(ide.app.editor_url + "reference")
        page.locator("#reference h2").first.wait_for(timeout=UI_WAIT_MS)
        headings = page.locator("#reference h2").all_inner_texts()
        assert "Built-ins" in headings and "Host functions of each world" in headings
        signature, _doc = host_doc("kilobot", "motion")
        assert signature in page.locator("#reference").inner_text()
        assert page.locator("#built-ins").count() == 1  # sections can be linked to
        assert "Generated by" not in page.locator("#reference").inner_text()  # a note for editors
        SCREENSHOT_DIR.mkdir(parents=True, exist_ok=True)
        page.screenshot(path=str(SCREENSHOT_DIR / "editor_reference_page.png"))
    finally:
        page.close()
    link = ide.editor.locator("#reference-link")
    assert link.get_attribute("href") == "reference"
