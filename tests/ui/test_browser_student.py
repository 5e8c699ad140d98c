"""The student's journey in headless Chromium on the real compiler, VM and Kilobot world.

A first program calls a function that does not exist. Before it runs, the editor warns at the
name (a global nothing defines, with the names that do exist); once the robots run it, the
call's own line carries a runtime marker with how many robots stopped there and the message
in the student's terms, not "wrong operand type" on the `}` after it.
"""

from __future__ import annotations

from collections.abc import Iterator

import pytest
from browser import UI_WAIT_MS
from ide_harness import IdeSession, running_ide

from bbzide.ui.world_adapter import WorldsBackend

BACKEND = WorldsBackend()

ROBOTS = 6
SCRIPT = (
    "var gradient = 0\n"
    "\n"
    "function init() {\n"
    "  gradient = id\n"
    "}\n"
    "\n"
    "function step() {\n"
    "  led(gradient % 7 + 1)\n"
    "  nosuchfunction(gradient)\n"
    "}\n"
)
CALL_LINE = 9


@pytest.fixture(scope="module")
def ide(tmp_path_factory: pytest.TempPathFactory) -> Iterator[IdeSession]:
    script = tmp_path_factory.mktemp("student") / "first.bzz"
    script.write_text(SCRIPT)
    with running_ide(script, BACKEND, "kilobot", ROBOTS) as session:
        yield session


def test_an_undefined_call_is_marked_on_its_own_line(ide: IdeSession) -> None:
    runtime = ide.editor.locator(".bbz-markers .runtime-line")
    runtime.wait_for(timeout=UI_WAIT_MS)
    assert runtime.count() == 1
    assert runtime.get_attribute("data-line") == str(CALL_LINE)
    assert runtime.locator(".robot-count").inner_text() == str(ROBOTS)
    message = ide.editor.locator("#diagnostics .diag-runtime").inner_text()
    assert message == (
        f"runtime error {CALL_LINE}:2 ({ROBOTS} robots stopped here): TYPE: `nosuchfunction` "
        "is nil here: it is not defined, and no host function of the Kilobot has that name")
    assert ide.editor.locator(".error-span").first.inner_text() == "nosuchfunction"
    lint = ide.editor.locator("#diagnostics .diag-warning").inner_text()
    assert lint.startswith(f"warning {CALL_LINE}:2: `nosuchfunction` is never defined")
    assert "Known names:" in lint and "`led`" in lint
    assert ide.editor.locator(f'.bbz-markers [data-line="{CALL_LINE + 1}"]').count() == 0
    ide.screenshot("student_undefined_call")


def test_the_marker_goes_once_the_call_is_fixed(ide: IdeSession) -> None:
    source = ide.editor.locator("#source")
    source.fill(SCRIPT.replace("nosuchfunction(gradient)", "led(gradient)"))
    # the list is redrawn from the new text's compile (the gutter mark goes with the replaced
    # text at once, so it is the list that says the new diagnostics arrived)
    ide.editor.locator("#diagnostics .diag-runtime").wait_for(state="detached", timeout=UI_WAIT_MS)
    assert ide.editor.locator(".bbz-markers .runtime-line").count() == 0
    assert ide.editor.locator("#diagnostics .diag-warning").count() == 0
