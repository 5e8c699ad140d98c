"""The IDE in a real (headless) Chromium, on the in-test world double: UI mechanics only.

What a user does: the page loads and draws the swarm, Play advances the step counter, typing a
syntax error puts a marker on that line while the robots keep running, fixing it reloads them,
an external save reloads the editor, a script stuck in a loop leaves the controls answering, and
two tabs keep their own selections. The same flows on the real compiler/VM/worlds are in
test_browser_real.py.
"""

from __future__ import annotations

import io
import time
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest
from browser import UI_WAIT_MS, UI_WAIT_S, render_barrier, wait_until
from doubles import FakeBackend
from ide_harness import IdeSession, editor_text, running_ide
from PIL import Image

from bbzide.ui.program_session import write_atomically
from bbzide.ui.viser_server import AMBIENT_INTENSITY

SCRIPT = "# demo\nfunction init() {\n  x = 1\n}\n\nfunction step() {\n  x = x + 1\n}\n"


@pytest.fixture(scope="module")
def ide(tmp_path_factory: pytest.TempPathFactory) -> Iterator[IdeSession]:
    script = tmp_path_factory.mktemp("ide") / "main.bzz"
    script.write_text(SCRIPT)
    with running_ide(script, FakeBackend(), "fake-table", 25) as session:
        yield session


def test_page_loads_and_scene_renders(ide: IdeSession) -> None:
    shot = ide.screenshot("mechanics_loaded")
    pixels = np.asarray(Image.open(io.BytesIO(shot.read_bytes())).convert("RGB"), dtype=np.float32)
    canvas = ide.page.locator("canvas").first.bounding_box()
    x0, y0 = int(canvas["x"]), int(canvas["y"])
    scene = pixels[y0 : y0 + int(canvas["height"]), x0 : x0 + int(canvas["width"])]
    assert scene.std() > 10, "the 3D view is blank"
    editor_lines = ide.editor.locator(".cm-line")
    assert editor_lines.count() == SCRIPT.count("\n") + 1
    assert ide.editor.locator(".tok-keyword").first.inner_text() == "function"
    assert ide.context.foreign_requests == []  # nothing leaves the machine


def test_the_scene_is_lit_without_a_shadow_pass(ide: IdeSession) -> None:
    """Nothing in the scene casts a shadow, so no light renders a shadow map each frame."""
    lights = ide.page.evaluate("""() => {
        const lights = [];
        window.__viserMutable.scene.traverse((node) => {
            if (node.isLight) lights.push({ type: node.type, shadow: node.castShadow });
        });
        return lights;
    }""")
    assert any(light["type"] == "DirectionalLight" for light in lights), lights
    assert [light for light in lights if light["shadow"]] == []


def test_the_scene_is_lit_without_an_environment_map(ide: IdeSession) -> None:
    """An ambient light stands in for the environment map, which a page without a GPU spent
    seconds filtering before its first frame."""
    lighting = ide.page.evaluate("""() => {
        const ambient = [];
        const scene = window.__viserMutable.scene;
        scene.traverse((node) => { if (node.isAmbientLight) ambient.push(node.intensity); });
        return { environment: scene.environment !== null, ambient };
    }""")
    assert lighting == {"environment": False, "ambient": [AMBIENT_INTENSITY]}


def test_play_advances_the_step_counter(ide: IdeSession) -> None:
    ide.page.get_by_role("button", name="Pause").click()
    wait_until(lambda: "paused" in ide.status_text(), UI_WAIT_S, message="paused")
    before = ide.shown_step()
    ide.page.get_by_role("button", name="Play").click()
    wait_until(lambda: ide.shown_step() > before + 5, UI_WAIT_S, message="step counter to advance")
    ide.page.get_by_role("button", name="Pause").click()
    wait_until(lambda: "paused" in ide.status_text(), UI_WAIT_S, message="paused")
    paused = ide.shown_step()
    ide.page.get_by_role("button", name="Step", exact=True).click()
    wait_until(lambda: ide.shown_step() == paused + 1, UI_WAIT_S, message="one step")
    ide.page.get_by_role("button", name="Play").click()


def test_syntax_error_marks_the_line_and_the_fix_reloads_the_robots(ide: IdeSession) -> None:
    # Typing is character by character, and on a loaded machine the 400 ms debounce may fire
    # mid-word: a prefix such as "red = @" is a valid program for the double, so the program
    # generation is read only once the whole line is compiled, and the fix is awaited by its
    # text, not by counting reloads.
    app = ide.app
    source = ide.editor.locator("#source")
    source.click()
    ide.page.keyboard.press("Control+End")
    ide.page.keyboard.type("\nred = @@ 2")
    ide.settled("red = @@ 2")
    line = app.session.text.splitlines().index("red = @@ 2") + 1
    assert line == SCRIPT.count("\n") + 2 == 10  # SCRIPT ends with a newline: one line past
    marker = ide.editor.locator(".bbz-markers .error-line")
    wait_until(lambda: marker.get_attribute("data-line") == "10", UI_WAIT_S, message="marker on 10")
    assert ide.editor.locator(".error-span").first.inner_text().startswith("@")
    assert "10:6" in ide.editor.locator("#diagnostics").inner_text()
    ide.screenshot("mechanics_syntax_error")
    generation = app.controller.status.program_generation
    running = app.session.last_good
    assert running is not None and "@@" not in running.program.text
    step = ide.shown_step()
    wait_until(lambda: ide.shown_step() > step + 3, UI_WAIT_S,
               message="robots keep running the old code")
    assert app.controller.status.program_generation == generation
    assert "@@" in Path(app.session.path).read_text()  # the edit is saved, broken or not
    for _ in range(4):
        ide.page.keyboard.press("Backspace")  # "red = @@ 2" -> "red = "
    ide.page.keyboard.type("2")
    ide.settled("\nred = 2")
    assert app.session.outcome is not None and app.session.outcome.ok
    marker.wait_for(state="detached", timeout=UI_WAIT_MS)
    sim = app.backend.created[-1]  # type: ignore[attr-defined]
    wait_until(
        lambda: sim.program.text.endswith("\nred = 2"), UI_WAIT_S,
        message="robots on the fixed code",
    )
    assert app.controller.status.program_generation > generation
    wait_until(lambda: ide.shown_step() > 0, UI_WAIT_S, message="running")


def choose_world(ide: IdeSession, current: str, wanted: str) -> None:
    ide.page.locator(f"input[value='{current}']").first.click()  # Mantine's combobox
    ide.page.get_by_role("option", name=wanted).click()


def test_build_view_and_world_selector(ide: IdeSession) -> None:
    app = ide.app
    backend = app.backend
    ide.page.get_by_role("tab", name="Build").click()
    ide.page.get_by_text("Footprint on fakebot").wait_for(timeout=UI_WAIT_MS)
    good = app.session.last_good
    assert good is not None
    assert ide.page.get_by_text(f"{len(good.program.bbo)}").count() >= 1
    listing = ide.page.locator("pre.asm-listing")
    assert "function init() {" in listing.inner_text()  # source lines above their code
    ide.screenshot("mechanics_build_view")
    ide.page.get_by_role("tab", name="main.bzz").click()
    created = len(backend.created)
    choose_world(ide, "fake-table", "fake-lab")
    wait_until(lambda: len(backend.created) > created, UI_WAIT_S, message="new world")
    assert backend.created[-1].world == "fake-lab"
    choose_world(ide, "fake-lab", "fake-table")
    wait_until(lambda: backend.created[-1].world == "fake-table", UI_WAIT_S, message="back")


def test_external_save_reloads_the_editor(ide: IdeSession) -> None:
    app = ide.app
    new_text = SCRIPT + "# saved by another editor\n"
    saved_at = time.monotonic()
    write_atomically(app.session.path, new_text)
    wait_until(
        lambda: app.session.text == new_text, UI_WAIT_S, interval=0.01, message="server reload"
    )
    print(f"disk save -> reloaded in {time.monotonic() - saved_at:.2f} s (goal: editor_bench)")
    source = ide.editor.locator("#source")
    wait_until(lambda: editor_text(source) == new_text, UI_WAIT_S,
               message="editor shows the new text")


def test_two_tabs_keep_their_own_selection(ide: IdeSession) -> None:
    app = ide.app
    page2, client2 = ide.open_tab()
    try:
        clients = app.server.get_clients()
        first = next(c for c in clients.values() if c.client_id != client2.client_id)
        page2.wait_for_selector("canvas")
        render_barrier(page2, client2)
        ide.click_robot(ide.page, first, 3)
        ide.page.get_by_text("Robot 3").first.wait_for(timeout=UI_WAIT_MS)
        ide.click_robot(page2, client2, 7)
        page2.get_by_text("Robot 7").first.wait_for(timeout=UI_WAIT_MS)
        assert app._inspectors[first.client_id].selected == 3
        assert app._inspectors[client2.client_id].selected == 7
        assert ide.page.get_by_text("Robot 7").count() == 0  # tab 1 still shows its own robot
        ide.screenshot("mechanics_selected_robot3")
        app.controller.play()
    finally:
        page2.close()
        app.controller.play()


def test_infinite_loop_leaves_the_controls_responsive(ide: IdeSession) -> None:
    app = ide.app
    app.controller.play()
    source = ide.editor.locator("#source")
    source.fill(SCRIPT + "while(1) {}\n")
    wait_until(
        lambda: (
            app.controller.status.step_started_at is not None
            and time.monotonic() - app.controller.status.step_started_at > 1.0
        ),
        UI_WAIT_S,
        message="a long step",
    )
    wait_until(lambda: "one step has run for" in ide.status_text(), UI_WAIT_S,
               message="long-step warning")
    ide.screenshot("mechanics_stuck_step")
    clicked_at = time.monotonic()
    ide.page.get_by_role("button", name="Pause").click()
    wait_until(
        lambda: app.controls.status_line.content and "paused" in ide.status_text(),
        UI_WAIT_S,
        message="pause to take effect",
    )
    print(f"pause honoured after {time.monotonic() - clicked_at:.2f} s (one stuck step is 1.5 s)")
    source.fill(SCRIPT)
    ide.page.get_by_role("button", name="Play").click()
    step = ide.shown_step()
    wait_until(lambda: ide.shown_step() > step + 5, UI_WAIT_S, message="running again")


def test_tab_enter_and_shift_tab_indent_like_an_editor(ide: IdeSession) -> None:
    app = ide.app
    source = ide.editor.locator("#source")
    source.fill("")
    source.click()
    keyboard = ide.page.keyboard
    keyboard.type("function f() {")
    keyboard.press("Enter")  # one level in after an opening brace
    keyboard.type("x = 1")
    keyboard.press("Enter")  # keeps the level
    keyboard.type("y = 2")
    keyboard.press("Shift+Tab")  # back to column 0
    keyboard.press("Home")
    keyboard.press("Tab")  # "  y = 2"
    keyboard.press("Shift+Tab")  # "y = 2"
    keyboard.press("End")
    keyboard.press("Enter")
    keyboard.type("}")
    expected = "function f() {\n  x = 1\ny = 2\n}"
    wait_until(
        lambda: editor_text(source) == expected,
        UI_WAIT_S,
        message=f"{expected!r}, not {editor_text(source)!r}",
    )
    wait_until(lambda: app.session.text == expected, UI_WAIT_S, message="saved")
    source.fill(SCRIPT)
    wait_until(lambda: app.session.text == SCRIPT, UI_WAIT_S, message="script restored")


def test_a_300_line_script_loads_numbers_its_lines_and_saves_typing(ide: IdeSession) -> None:
    app = ide.app
    body = "".join(
        f"function f{i}(a, b) {{\n  var s = a * {i} + b  # comment {i}\n  return s\n}}\n"
        for i in range(75)
    )
    assert body.count("\n") == 300
    write_atomically(app.session.path, body)
    source = ide.editor.locator("#source")
    wait_until(lambda: editor_text(source) == body, UI_WAIT_S, message="300 lines in the editor")
    source.click()
    ide.page.keyboard.press("Control+End")
    ide.page.keyboard.type("# end\n")
    wait_until(lambda: app.session.text.endswith("# end\n"), UI_WAIT_S, message="typed text saved")
    # the editor scrolled to the end: the last line's number is drawn, and every line highlighted
    last_number = ide.editor.locator(".cm-lineNumbers .cm-gutterElement", has_text="302")
    last_number.wait_for(timeout=UI_WAIT_MS)
    last_comment = ide.editor.locator(".cm-line", has_text="comment 74").locator(".tok-comment")
    assert last_comment.count() == 1
    ide.screenshot("mechanics_300_lines")
