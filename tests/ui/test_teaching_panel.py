"""The IDE's Lessons menu, Save setup, `?scenario=` links and a scenario's `steps`, on a real
IdeApp (real worlds, real viser server; no browser: tests/ui/test_browser_lessons.py clicks
the same panel in Chromium)."""

from __future__ import annotations

import http.client
import threading
from collections.abc import Callable, Iterator
from pathlib import Path

import pytest

from bbzide.lessons import catalog
from bbzide.ui.app import IdeApp
from bbzide.ui.run_controller import RunSettings
from bbzide.ui.scenario_links import EXAMPLES_FOLDER
from bbzide.ui.watches import Watch
from bbzide.ui.world_adapter import WorldsBackend
from bbzide.worlds.scenario import load_scenario
from tests.ui.browser import UI_WAIT_S, free_port, wait_until
from tests.worlds.fingerprint import fingerprint

SCRIPT = "var n = 3\nfunction init() {\n}\nfunction step() {\n  n = n + 1\n}\n"


@pytest.fixture
def lessons_home(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    home = tmp_path / "work"
    monkeypatch.setenv(catalog.HOME_VARIABLE, str(home))
    monkeypatch.setenv("XDG_DATA_HOME", str(tmp_path / "data"))  # examples' scratch copies
    return home


@pytest.fixture
def ide(tmp_path: Path, lessons_home: Path) -> Iterator[IdeApp]:
    script = tmp_path / "mine.bzz"
    script.write_text(SCRIPT)
    folder = tmp_path / "class"
    folder.mkdir()
    app = IdeApp(script, WorldsBackend(), RunSettings("kilobot", 4, 1, 0.0), port=free_port(),
                 scenario_folder=folder)
    app.start(run=False)
    try:
        yield app
    finally:
        app.stop()


def settle(app: IdeApp, worker: threading.Thread | None) -> None:
    """Wait for the panel's background action and the run thread to apply what it sent."""
    assert worker is not None
    worker.join(UI_WAIT_S)
    assert not worker.is_alive() and app.controller.flush(UI_WAIT_S)


def run_in_panel(app: IdeApp, action: Callable[[], object]) -> None:
    settle(app, app.teaching._in_background(action))  # noqa: SLF001 - what a click does


def test_open_check_and_reset_a_lesson_from_the_menu(ide: IdeApp, lessons_home: Path) -> None:
    teaching = ide.teaching
    lesson = catalog.lesson(4)
    teaching.choice.value = "4. " + lesson.title
    run_in_panel(ide, teaching._open_chosen)  # noqa: SLF001 - the Open button's action
    work = lessons_home / "04-hop-count.bzz"
    assert ide.session.path == work.resolve()
    assert ide.session.text == lesson.starter.read_text()
    settings = ide.controller.settings
    assert (settings.world, settings.robots, settings.seed) == ("kilobot", 10, 3)
    assert settings.scenario.world_options == {"spacing": 0.07}
    assert "Objective" in teaching.text.content and not teaching.check_button.disabled

    failed = teaching.check()
    assert failed is not None and not failed.passed
    assert "FAIL" in teaching.verdict.content and "Look at" in teaching.verdict.content

    ide.session.edit_from_browser(lesson.solution.read_text())   # the solution pasted
    passed = teaching.check()
    assert passed is not None and passed.passed, passed
    assert "PASS" in teaching.verdict.content
    assert work.read_text() == lesson.solution.read_text()       # the work is kept per lesson

    teaching.reset()
    assert work.read_text() == lesson.starter.read_text()
    assert ide.session.text == lesson.starter.read_text()


def test_a_scenario_pauses_at_its_steps_and_says_so(ide: IdeApp) -> None:
    run_in_panel(ide, lambda: ide.teaching.open_lesson(catalog.lesson(4)))
    wait_until(lambda: not ide.controller.status.running
               and ide.controller.status.step == 30, UI_WAIT_S, message="pause at step 30")
    assert "paused at step 30" in (ide.controller.status.notice or "")
    assert "pauses at step 30" in ide.teaching.about.content
    assert "`hops`" in ide.teaching.about.content           # the scenario's watches
    assert ide.controller.watches == ("hops",)
    # the Watches folder plots it from the scenario's first step on
    assert ide.watch_book.watches == [Watch("expression", "hops")]
    steps, _values = ide.watch_book.series(Watch("expression", "hops"))
    assert steps[0] == 1 and steps[-1] == 30
    ide.controller.play()                                    # Play runs on past it
    wait_until(lambda: ide.controller.status.step > 30, UI_WAIT_S, message="steps past 30")
    assert ide.controller.status.notice is None


def test_save_setup_round_trips_to_the_same_run(ide: IdeApp, tmp_path: Path) -> None:
    run_in_panel(ide, lambda: ide.teaching.open_lesson(catalog.lesson(3)))
    ide.teaching.pin.value = True
    saved = ide.teaching.save_setup(Path("saved.toml"))
    assert saved == ide.session.path.parent / "saved.toml"
    assert "Saved" in ide.teaching.message.content
    running = ide.controller.settings.scenario
    loaded = load_scenario(saved)
    assert (loaded.world, loaded.robots, loaded.seed, loaded.steps, loaded.watch) == (
        running.world, running.robots, running.seed, running.steps, running.watch)
    assert loaded.scripts() == [ide.session.path]
    assert loaded.world_options == running.world_options
    assert fingerprint(loaded.simulation(), 10) == fingerprint(running.simulation(), 10)
    again = load_scenario(ide.teaching.save_setup(tmp_path / "again.toml"))
    assert again == loaded                                  # save -> load -> save: the same


def test_save_setup_refuses_a_file_that_is_not_toml(ide: IdeApp, tmp_path: Path) -> None:
    assert ide.teaching.save_setup(tmp_path / "x.txt") is None
    assert "ends in .toml" in ide.teaching.message.content


def test_a_link_opens_an_example_on_a_scratch_copy(ide: IdeApp, tmp_path: Path) -> None:
    settle(ide, ide._on_visit("token=x&scenario=example/kilobot/gradient"))  # noqa: SLF001
    assert "Opened" in ide.teaching.message.content, ide.teaching.message.content
    shipped = EXAMPLES_FOLDER / "kilobot" / "gradient.bzz"
    assert ide.session.path != shipped and ide.session.path.is_relative_to(tmp_path / "data")
    assert ide.session.text == shipped.read_text()
    assert ide.controller.settings.scenario == load_scenario(
        EXAMPLES_FOLDER / "kilobot" / "gradient.toml").with_script(ide.session.path)


@pytest.mark.parametrize("name, words", [
    ("../../etc/passwd", "not a path"),
    ("/etc/passwd", "not a path"),
    ("example/../../README", "not a path"),
    ("nothing-here", "no scenario nothing-here.toml"),
])
def test_a_link_outside_what_the_ide_may_open_is_refused(ide: IdeApp, name: str,
                                                          words: str) -> None:
    before = ide.session.path
    ide.teaching._open_link_name(name)  # noqa: SLF001 - what the hook runs in the background
    assert "not opened" in ide.teaching.message.content and words in \
        ide.teaching.message.content, ide.teaching.message.content
    assert ide.session.path == before


def test_a_malformed_linked_scenario_shows_its_line_and_key(ide: IdeApp) -> None:
    folder = ide.teaching.scenario_folder
    assert folder is not None
    (folder / "a.bzz").write_text(SCRIPT)
    (folder / "broken.toml").write_text(
        'version = 1\nworld = "kilobot"\n\n[[robots]]\ncount = -2\nscript = "a.bzz"\n')
    ide.teaching._open_link_name("broken")  # noqa: SLF001
    assert "broken.toml:5: robots[0].count: must be &gt;= 1" in ide.teaching.message.content
    (folder / "fine.toml").write_text(
        'version = 1\nworld = "kilobot"\nsteps = 5\n\n[[robots]]\ncount = 2\nscript = "a.bzz"\n')
    run_in_panel(ide, lambda: ide.teaching._open_link_name("fine"))  # noqa: SLF001
    assert ide.session.path == (folder / "a.bzz").resolve()   # a class folder: edited in place
    assert ide.controller.settings.robots == 2


def get_page(app: IdeApp, query: str, **headers: str) -> int:
    """GET the IDE's page with `query`, as a browser following a link does; the status."""
    connection = http.client.HTTPConnection("127.0.0.1", app.server.get_port(), timeout=UI_WAIT_S)
    try:
        connection.request("GET", "/?" + query, headers=headers)
        return connection.getresponse().status
    finally:
        connection.close()


def test_a_link_with_the_token_opens_its_lesson(ide: IdeApp, lessons_home: Path) -> None:
    assert get_page(ide, f"token={ide.token}&scenario=lesson/3") == 200
    work = (lessons_home / "03-neighbours.bzz").resolve()
    wait_until(lambda: ide.session.path == work and ide.teaching.lesson is not None,
               UI_WAIT_S, message="lesson 3 open")
    assert ide.teaching.lesson == catalog.lesson(3)


@pytest.mark.parametrize("query, headers", [
    ("token=wrong-token-123&scenario=lesson/3", {}),
    ("scenario=lesson/3", {"Sec-Fetch-Site": "cross-site", "Sec-Fetch-Mode": "navigate",
                           "Sec-Fetch-Dest": "document"}),
])
def test_a_link_without_the_token_opens_nothing(ide: IdeApp, query: str,
                                                headers: dict[str, str],
                                                monkeypatch: pytest.MonkeyPatch) -> None:
    seen: list[str] = []   # the hook runs before the answer is sent: no waiting needed
    monkeypatch.setattr(ide.teaching, "open_link", seen.append)
    assert get_page(ide, query, **headers) == 403
    assert seen == []
    assert get_page(ide, f"token={ide.token}&scenario=lesson/3", **headers) == 200
    assert seen == [f"token={ide.token}&scenario=lesson/3"]   # the same request with it does


def test_a_refused_link_is_said_on_the_status_line(ide: IdeApp) -> None:
    ide.teaching._open_link_name("../../etc/passwd")  # noqa: SLF001
    assert "not opened" in (ide.controller.status.notice or "")
    ide.controls.refresh_status()
    assert "not opened" in ide.controls.status_line.content


def test_a_lesson_in_another_world_switches_the_world_and_keeps_its_scenario(
        ide: IdeApp) -> None:
    lesson = catalog.lesson(7)
    scenario = lesson.scenario()
    assert scenario.world == "crazyflie"   # the IDE started on the Kilobot table
    run_in_panel(ide, lambda: ide.teaching.open_lesson(lesson))
    settings = ide.controller.settings
    assert (settings.world, settings.robots) == ("crazyflie", scenario.robots)
    assert settings.scenario.world_options == scenario.world_options
    assert ide.session.outcome is not None and ide.session.outcome.ok

    def running_world() -> str | None:
        with ide.controller.locked() as handle:
            return None if handle is None else handle.sim.world.name

    wait_until(lambda: running_world() == "crazyflie", UI_WAIT_S,
               message="the crazyflie swarm built")
    assert ide.controls.world.value == "crazyflie"


def test_ide_takes_a_scenario_folder_for_links(tmp_path: Path, lessons_home: Path,
                                               monkeypatch: pytest.MonkeyPatch,
                                               capsys: pytest.CaptureFixture[str]) -> None:
    from bbzide.cli import main
    from bbzide.ui import commands

    script = tmp_path / "mine.bzz"
    script.write_text(SCRIPT)
    seen: dict[str, object] = {}

    def serve(app: IdeApp, open_browser: bool) -> int:  # stands for the Ctrl-C loop
        seen["folder"] = app.teaching.scenario_folder
        app.stop()
        return 0

    monkeypatch.setattr(commands, "serve_until_interrupted", serve)
    assert main(["ide", str(script), "--scenarios", str(tmp_path), "--no-browser", "--paused",
                 "--port", str(free_port())]) == 0
    assert seen["folder"] == tmp_path
    assert main(["ide", str(script), "--scenarios", str(tmp_path / "none"), "--no-browser",
                 "--port", str(free_port())]) == 1
    err = capsys.readouterr().err
    assert "--scenarios" in err and "no such folder" in err and "Traceback" not in err
