"""The teaching track: every lesson is complete, its reference solution passes its automatic
check and its starter script fails it; a student's work is kept per lesson and can be reset;
`bbzide lesson` lists, checks and opens lessons."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from bbzide.cli import main
from bbzide.lessons import catalog
from bbzide.lessons.checks import CHECKS, run_check
from bbzide.ui import commands
from tests.ui.browser import free_port, wait_until

LESSONS = catalog.lessons()


def lesson_id(lesson: catalog.Lesson) -> str:
    return lesson.name


@pytest.fixture(autouse=True)
def lessons_home(tmp_path: Path, monkeypatch) -> Path:
    home = tmp_path / "work"
    monkeypatch.setenv(catalog.HOME_VARIABLE, str(home))
    return home


def test_the_track_has_eight_lessons_across_both_worlds():
    assert len(LESSONS) >= 8
    assert [lesson.number for lesson in LESSONS] == list(range(1, len(LESSONS) + 1))
    assert {lesson.world for lesson in LESSONS} >= {"kilobot", "crazyflie"}
    assert {"memory", "pitfalls"} <= {lesson.slug for lesson in LESSONS}
    assert set(CHECKS) == {lesson.slug for lesson in LESSONS}      # one check per lesson


@pytest.mark.parametrize("lesson", LESSONS, ids=lesson_id)
def test_each_lesson_has_its_text_scenario_starter_and_solution(lesson):
    text = lesson.text
    for section in ("## Objective", "## Buzz concepts", "## Hints", "## What the check looks at"):
        assert section in text, f"{lesson.name}/lesson.md lacks {section}"
    scenario = lesson.scenario()
    assert scenario.scripts() == [lesson.starter.resolve()]
    assert lesson.solution.read_text() != lesson.starter.read_text()


@pytest.mark.parametrize("lesson", LESSONS, ids=lesson_id)
def test_the_reference_solution_passes_and_the_starter_fails(lesson):
    solved = run_check(lesson, lesson.solution)
    assert solved.passed, solved.render()
    started = run_check(lesson, lesson.starter)
    assert not started.passed
    assert started.look_at, "a failed check says what to look at"


def test_a_script_that_does_not_compile_fails_with_the_compiler_message(tmp_path):
    broken = tmp_path / "broken.bzz"
    broken.write_text("function step() {\n  led(\n}\n")
    verdict = run_check(catalog.lesson(1), broken)
    assert not verdict.passed and verdict.summary == "the script does not compile"
    assert "broken.bzz:" in verdict.look_at[0]


def test_the_memory_starter_runs_out_of_heap_and_says_where_to_look():
    verdict = run_check(catalog.lesson(6), catalog.lesson(6).starter)
    assert "stopped with an error" in verdict.summary and "heap map" in verdict.summary
    assert any("MEM" in line for line in verdict.look_at)


def test_work_is_kept_per_lesson_and_reset_restores_the_starter(lessons_home):
    first = catalog.lesson(1)
    work = catalog.work_file(first)
    assert work == lessons_home / "01-first-light.bzz"
    assert work.read_text() == first.starter.read_text()
    work.write_text(first.solution.read_text())
    assert catalog.work_file(first).read_text() == first.solution.read_text()   # kept
    assert catalog.work_file(catalog.lesson(2)) != work                        # per lesson
    catalog.reset_work(first)
    assert work.read_text() == first.starter.read_text()


def test_without_the_override_work_goes_to_the_user_data_dir(tmp_path, monkeypatch):
    monkeypatch.delenv(catalog.HOME_VARIABLE)
    monkeypatch.setenv("XDG_DATA_HOME", str(tmp_path / "data"))
    assert catalog.lessons_home() == tmp_path / "data" / "bbzide" / "lessons"


def test_cli_lists_checks_and_resets(lessons_home, capsys):
    assert main(["lesson"]) == 0
    listing = capsys.readouterr().out
    assert all(lesson.title in listing for lesson in LESSONS)
    assert str(lessons_home) in listing

    assert main(["lesson", "2", "--check"]) == 1        # not started yet: a one-line error
    assert "you have not started lesson 2" in capsys.readouterr().err

    assert main(["lesson", "2", "--reset"]) == 0        # creates the work copy
    capsys.readouterr()
    assert main(["lesson", "2", "--check"]) == 1        # the starter fails
    out = capsys.readouterr().out
    assert "FAIL: even ids must be green and odd ids blue" in out and "robot 0" in out

    (lessons_home / "02-who-am-i.bzz").write_text(catalog.lesson(2).solution.read_text())
    assert main(["lesson", "2", "--check"]) == 0
    assert "PASS" in capsys.readouterr().out

    assert main(["lesson", "99"]) == 1
    assert "no lesson 99" in capsys.readouterr().err


def test_opening_a_lesson_prints_it_and_edits_the_work_copy_in_its_scenario(
        lessons_home, monkeypatch, capsys):
    seen = {}

    def serve(app, open_browser):  # noqa: ANN001, ANN202 - stands for the Ctrl-C loop
        try:
            wait_until(lambda: app.controller.last_frame is not None)
            with app.controller.locked() as handle:
                seen["positions"] = handle.frame().positions.copy()
            seen["settings"] = app.controller.settings
        finally:
            app.stop()
        return 0

    monkeypatch.setattr(commands, "serve_until_interrupted", serve)
    assert main(["lesson", "3", "--no-browser", "--paused", "--port", str(free_port())]) == 0
    out = capsys.readouterr().out
    assert "# Who is around? Counting neighbours" in out
    work = lessons_home / "03-neighbours.bzz"
    assert f"editing {work}" in out and work.read_text() == catalog.lesson(3).starter.read_text()
    pinned = [p[:2] for p in catalog.lesson(3).scenario().groups[0].positions]
    assert np.allclose(seen["positions"], pinned)
    assert seen["settings"].robots == 5 and seen["settings"].scenario.world == "kilobot"
