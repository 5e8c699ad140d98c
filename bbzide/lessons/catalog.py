"""The lessons that exist (the `NN-slug` folders beside this file) and each student's work.

Design: the folders are the catalogue: a lesson's number and slug come from its folder name,
its title from the first `# ` line of `lesson.md`, its world from `scenario.toml` (the starter
is the script the scenario names). A student's work on lesson `NN-slug` is one file,
`<lessons home>/NN-slug.bzz`, copied from the starter the first time the lesson is opened and
saved by the IDE's editor at every change; `reset_work` copies the starter over it again. The
lessons home is `$BBZIDE_LESSONS_HOME` when set, else `bbzide/lessons` under the user's data
directory (`$XDG_DATA_HOME`, by default `~/.local/share`), beside the IDE's scratch copies.
"""

from __future__ import annotations

import os
import re
import shutil
from dataclasses import dataclass
from functools import cache
from pathlib import Path

from bbzide.diagnostics import UserError
from bbzide.worlds.scenario import Scenario, load_scenario

LESSONS_FOLDER = Path(__file__).resolve().parent
#: A lesson folder's name: two digits, a dash, a slug (the check's key in checks.py).
FOLDER_NAME = re.compile(r"(\d\d)-([a-z0-9-]+)\Z")
#: Environment variable that moves the students' work elsewhere (a class share, a test).
HOME_VARIABLE = "BBZIDE_LESSONS_HOME"


class LessonError(UserError):
    """No such lesson, or a lesson whose work file cannot be written."""


@dataclass(frozen=True)
class Lesson:
    number: int
    slug: str
    folder: Path

    @property
    def name(self) -> str:
        return self.folder.name

    @property
    def text(self) -> str:
        return (self.folder / "lesson.md").read_text(encoding="utf-8")

    @property
    def title(self) -> str:
        for line in self.text.splitlines():
            if line.startswith("# "):
                return line[2:].strip()
        return self.slug

    @property
    def starter(self) -> Path:
        return self.folder / "starter.bzz"

    @property
    def solution(self) -> Path:
        return self.folder / "solution.bzz"

    @property
    def scenario_path(self) -> Path:
        return self.folder / "scenario.toml"

    def scenario(self) -> Scenario:
        return load_scenario(self.scenario_path)

    @property
    def world(self) -> str:
        return self.scenario().world


@cache
def lessons() -> tuple[Lesson, ...]:
    """Every lesson, in number order."""
    found = []
    for folder in sorted(LESSONS_FOLDER.iterdir()):
        match = FOLDER_NAME.match(folder.name)
        if match and folder.is_dir():
            found.append(Lesson(int(match.group(1)), match.group(2), folder))
    return tuple(found)


def lesson(number: int) -> Lesson:
    """Lesson `number`, or a user error listing the numbers there are."""
    for candidate in lessons():
        if candidate.number == number:
            return candidate
    numbers = ", ".join(str(x.number) for x in lessons())
    raise LessonError(f"no lesson {number}; the lessons are {numbers} (bbzide lesson lists them)")


def lessons_home() -> Path:
    """Where students' work is kept (see the module doc)."""
    override = os.environ.get(HOME_VARIABLE)
    if override:
        return Path(override)
    data_home = Path(os.environ.get("XDG_DATA_HOME") or Path.home() / ".local" / "share")
    return data_home / "bbzide" / "lessons"


def work_path(chosen: Lesson) -> Path:
    return lessons_home() / f"{chosen.name}.bzz"


def work_file(chosen: Lesson) -> Path:
    """The student's work on `chosen`, created from the starter the first time."""
    path = work_path(chosen)
    if not path.exists():
        _copy_starter(chosen, path)
    return path


def reset_work(chosen: Lesson) -> Path:
    """Put the starter back in place of the student's work ("reset lesson")."""
    path = work_path(chosen)
    _copy_starter(chosen, path)
    return path


def _copy_starter(chosen: Lesson, path: Path) -> None:
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        shutil.copyfile(chosen.starter, path)
    except OSError as error:
        raise LessonError(f"cannot write your work file {path}: {error.strerror or error} "
                          f"(set {HOME_VARIABLE} to a folder you can write)") from None
