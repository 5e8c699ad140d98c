"""The Lessons menu and Save setup in headless Chromium on the real worlds: a lesson opens from
the menu on the student's copy of its starter, Check says FAIL and what to look at, the pasted
reference solution passes, Reset lesson (once confirmed) brings the starter back, and Save
setup writes a scenario that loads. Screenshots (1400x900) land in $BBZIDE_SCREENSHOTS."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import pytest
from browser import UI_WAIT_MS, UI_WAIT_S, wait_until
from ide_harness import IdeSession, editor_text, running_ide

from bbzide.lessons import catalog
from bbzide.ui.teaching_panel import lesson_label
from bbzide.ui.world_adapter import WorldsBackend
from bbzide.worlds.scenario import load_scenario

BACKEND = WorldsBackend()

LESSON = catalog.lesson(2)


@pytest.fixture(scope="module")
def ide(tmp_path_factory: pytest.TempPathFactory) -> Iterator[IdeSession]:
    folder = tmp_path_factory.mktemp("lessons")
    with pytest.MonkeyPatch.context() as patch:
        patch.setenv(catalog.HOME_VARIABLE, str(folder / "work"))
        script = folder / "start.bzz"
        script.write_text("function init() {\n}\nfunction step() {\n}\n")
        with running_ide(script, BACKEND, "kilobot", 4) as session:
            yield session


def click_button(ide: IdeSession, name: str) -> None:
    ide.page.get_by_role("button", name=name).click()  # type: ignore[attr-defined]


def open_lesson_from_the_menu(ide: IdeSession) -> Path:
    """Chooses LESSON in the Lessons menu and opens it; returns the student's work copy once
    the editor shows its starter and the panel its objective."""
    page = ide.page
    page.locator("input[value='(choose a lesson)']").first.click()  # type: ignore[attr-defined]
    option = page.get_by_role("option", name=lesson_label(LESSON))  # type: ignore[attr-defined]
    option.wait_for(timeout=UI_WAIT_MS)
    ide.screenshot("lessons_menu")
    option.click()
    click_button(ide, "Open lesson")
    work = catalog.work_path(LESSON).resolve()
    wait_until(lambda: ide.app.session.path == work, UI_WAIT_S, message="the work copy open")
    source = ide.editor.locator("#source")
    starter = LESSON.starter.read_text()
    wait_until(lambda: editor_text(source) == starter, UI_WAIT_S, message="the starter shown")
    page.get_by_text("Objective").first.wait_for(timeout=UI_WAIT_MS)  # type: ignore[attr-defined]
    return work


def test_a_lesson_opens_from_the_menu_and_passes_once_the_solution_is_pasted(
        ide: IdeSession) -> None:
    page = ide.page
    work = open_lesson_from_the_menu(ide)
    source = ide.editor.locator("#source")
    starter = LESSON.starter.read_text()

    click_button(ide, "Check")
    page.get_by_text("FAIL").first.wait_for(timeout=UI_WAIT_MS)  # type: ignore[attr-defined]
    assert "Look at" in ide.app.teaching.verdict.content
    ide.screenshot("lesson_check_failed")

    solution = LESSON.solution.read_text()
    source.click()
    page.keyboard.press("Control+A")  # type: ignore[attr-defined]
    page.keyboard.insert_text(solution)  # type: ignore[attr-defined]  # as a paste does
    ide.settled(solution.rstrip()[-20:])
    assert work.read_text() == solution
    click_button(ide, "Check")
    page.get_by_text("PASS").first.wait_for(timeout=UI_WAIT_MS)  # type: ignore[attr-defined]
    ide.screenshot("lesson_check_passed")

    click_button(ide, "Reset lesson")  # asks first, in this tab
    click_button(ide, "Reset to the starter")
    wait_until(lambda: work.read_text() == starter and editor_text(source) == starter,
               UI_WAIT_S, message="the starter back in the file and the editor")


def test_save_setup_writes_a_scenario_of_the_running_lesson(ide: IdeSession) -> None:
    page = ide.page
    if ide.app.session.path != catalog.work_path(LESSON).resolve():  # this test run alone
        open_lesson_from_the_menu(ide)
    # viser's text field is not tied to its label: find it by the name the lesson put there
    field = page.locator(f"input[value='{LESSON.name}.toml']").first  # type: ignore[attr-defined]
    field.fill("class-copy.toml")
    page.keyboard.press("Enter")  # type: ignore[attr-defined]  # (the locator names the old value)
    wait_until(lambda: ide.app.teaching.save_path.value == "class-copy.toml", UI_WAIT_S,
               message="the file name sent")
    click_button(ide, "Save setup")
    page.get_by_text("Saved").first.wait_for(timeout=UI_WAIT_MS)  # type: ignore[attr-defined]
    saved = Path(ide.app.session.path).parent / "class-copy.toml"
    loaded = load_scenario(saved)
    assert loaded == LESSON.scenario().with_script(ide.app.session.path)
    ide.screenshot("save_setup")
