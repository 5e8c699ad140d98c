"""The memory debugger's journey in headless Chromium on a real M300 drone (a 60,000-byte heap).

A click on a block of the heap map names that object: its index, byte offset, size, type and
who refers to it, the same facts the inspector reads from the VM (checked against the paused
robot's inspection, not against fixed text). The World setup folder draws robot ids over the
drones and rebuilds the world with the options typed in its field.
"""

from __future__ import annotations

import shutil
from collections.abc import Iterator
from pathlib import Path

import pytest
from browser import UI_WAIT_MS, UI_WAIT_S, set_checkbox, wait_until
from ide_harness import IdeSession, running_ide

from bbzide.ui.world_adapter import WorldsBackend

BACKEND = WorldsBackend()

REPO = Path(__file__).resolve().parents[2]
DRONES = 6


@pytest.fixture(scope="module")
def ide(tmp_path_factory: pytest.TempPathFactory) -> Iterator[IdeSession]:
    script = tmp_path_factory.mktemp("m300") / "flocking.bzz"
    shutil.copy(REPO / "examples" / "m300" / "flocking.bzz", script)
    with running_ide(script, BACKEND, "m300", DRONES) as session:
        yield session


def test_a_click_on_a_heap_block_names_its_object(ide: IdeSession) -> None:
    app, page = ide.app, ide.page
    wait_until(lambda: app.controller.status.step >= 20, UI_WAIT_S, message="20 steps")
    app.controller.pause()
    wait_until(lambda: not app.controller.status.running, UI_WAIT_S, message="the pause")
    client = next(iter(app.server.get_clients().values()))
    app._select(client, 0)  # noqa: SLF001 - what a click on drone 0 does (tested elsewhere)
    with app.controller.locked() as sim:
        view = sim.inspect(0)
    assert view.heap_size == 60000
    table = next(row for row in view.objects if row.name == "nbx")  # `var nbx = {}`
    block = page.locator(f'.heap-map rect[data-start="{table.offset}"]').first  # type: ignore[attr-defined]
    block.wait_for(timeout=UI_WAIT_MS)
    block.scroll_into_view_if_needed()
    block.click()
    picked = page.locator(".bbz-heap-pick")  # type: ignore[attr-defined]
    expected = f"#{table.index} @{table.offset}, 9 B: table"
    wait_until(lambda: picked.inner_text().startswith(expected), UI_WAIT_S,
               message=f"the picked object {expected!r}")
    text = picked.inner_text()
    assert "global `nbx`" in text and "name: nbx" in text
    assert page.locator(".heap-map rect.picked").count() >= 1  # type: ignore[attr-defined]
    ide.screenshot("memory-m300-heap-click")
    # another block: the box follows the click (an int of the same heap)
    number = next(row for row in view.objects if row.type_name == "int" and row.referrers)
    page.locator(f'.heap-map rect[data-start="{number.offset}"]').first.click()  # type: ignore[attr-defined]
    second = f"#{number.index} @{number.offset}, 9 B: int"
    wait_until(lambda: picked.inner_text().startswith(second), UI_WAIT_S,
               message="the second pick")


def test_robot_ids_and_world_options_from_the_world_setup_folder(ide: IdeSession) -> None:
    app, page = ide.app, ide.page
    page.get_by_text("World setup").click()  # type: ignore[attr-defined]
    set_checkbox(page.get_by_label("Robot ids"), True)  # type: ignore[attr-defined]
    labels = app.world_setup.labels
    wait_until(lambda: len(labels._labels) == DRONES, UI_WAIT_S,  # noqa: SLF001
               message="one label per drone")
    assert sorted(labels._texts) == sorted(str(i) for i in range(DRONES))  # noqa: SLF001
    ide.screenshot("memory-m300-robot-ids")
    # (viser's text field's label names another id: the field is the input after the label)
    options = page.locator(  # type: ignore[attr-defined]
        "xpath=//label[text()='World options']/following::input[1]")
    options.fill("targets=5")
    options.press("Enter")
    wait_until(lambda: app.controller.settings.world_options == {"targets": 5}, UI_WAIT_S,
               message="the typed option in the settings")

    def targets() -> int:
        with app.controller.locked() as sim:
            return 0 if sim is None else len(sim.sim.world.targets)
    wait_until(lambda: targets() == 5, UI_WAIT_S, message="a field with 5 targets")
    options.fill("no_such_option=1")
    options.press("Enter")
    wait_until(lambda: "no_such_option" in (app.controller.status.error or ""), UI_WAIT_S,
               message="the bad option's one-line error")
    assert "Traceback" not in app.controller.status.error
