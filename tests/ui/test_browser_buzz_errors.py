"""Typing real Buzz in the browser editor: the real front end's errors become markers.

The world is the in-test double; the compiler front end is the real one, so the marker's line,
column and message are the Buzz compiler's. The listing in the Build tab is the real `.basm`
regrouped under its source lines.
"""

from __future__ import annotations

from collections.abc import Iterator

import pytest
from browser import UI_WAIT_MS, UI_WAIT_S, wait_until
from doubles import FrontEndBackend
from ide_harness import IdeSession, running_ide

SCRIPT = (
    "# a counter every robot keeps\n"
    "var count = 0\n"
    "\n"
    "function init() {\n"
    "  count = 0\n"
    "}\n"
    "\n"
    "function step() {\n"
    "  count = count + 1\n"
    "}\n"
)


@pytest.fixture(scope="module")
def ide(tmp_path_factory: pytest.TempPathFactory) -> Iterator[IdeSession]:
    script = tmp_path_factory.mktemp("buzz") / "counter.bzz"
    script.write_text(SCRIPT)
    with running_ide(script, FrontEndBackend(), "fake-table", 10) as session:
        yield session


def test_real_syntax_error_marker_and_fix(ide: IdeSession) -> None:
    app = ide.app
    assert app.session.outcome is not None and app.session.outcome.ok
    source = ide.editor.locator("#source")
    source.click()
    ide.page.keyboard.press("Control+End")
    ide.page.keyboard.type("if count > 10 {\n")  # Buzz needs parentheses: error at line 11
    ide.settled("if count > 10 {")  # a half-typed "i" may have compiled and reloaded on the way
    marker = ide.editor.locator(".bbz-markers .error-line")
    marker.wait_for(timeout=UI_WAIT_MS)
    first = app.session.outcome.diagnostics[0]
    assert (first.line, first.col) == (11, 3) and "expected (" in first.message
    assert marker.get_attribute("data-line") == "11"
    assert ide.editor.locator(".error-span").first.inner_text() == "count"
    assert "11:3: Syntax error: expected (" in ide.editor.locator("#diagnostics").inner_text()
    ide.screenshot("buzz_syntax_error")
    generation = app.controller.status.program_generation
    step = ide.shown_step()
    wait_until(lambda: ide.shown_step() > step + 3, UI_WAIT_S,
               message="robots keep running the old code")
    assert app.controller.status.program_generation == generation  # the error loads nothing
    fixed = SCRIPT + "if (count > 10) {\n  count = 0\n}\n"
    source.fill(fixed)  # one input event: one upload
    marker.wait_for(state="detached", timeout=UI_WAIT_MS)
    sim = app.backend.created[-1]  # type: ignore[attr-defined]
    wait_until(lambda: sim.program.text == fixed, UI_WAIT_S, message="robots on the fixed code")
    assert app.controller.status.program_generation > generation
    ide.page.get_by_role("tab", name="Build").click()
    listing = ide.page.locator("pre.asm-listing")
    listing.wait_for(timeout=UI_WAIT_MS)
    assert "count = count + 1" in listing.inner_text() and "add" in listing.inner_text()
    ide.screenshot("buzz_build_view")
    ide.page.get_by_role("tab", name="counter.bzz").click()


def test_pitfall_warning_shows_in_the_editor(ide: IdeSession) -> None:
    source = ide.editor.locator("#source")
    source.fill(SCRIPT + "if (not count) {\n  count = 1\n}\n")
    warning = ide.editor.locator("#diagnostics .diag-warning")
    warning.wait_for(timeout=UI_WAIT_MS)
    assert "11:4:" in warning.first.inner_text() and "truth value" in warning.first.inner_text()
    assert ide.editor.locator('.bbz-markers .warning-line[data-line="11"]').count() == 1
    assert ide.editor.locator(".bbz-markers .error-line").count() == 0
    ide.screenshot("buzz_pitfall_warning")
