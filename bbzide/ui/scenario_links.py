"""What a link `http://…/?scenario=NAME&token=…` may open in a running IDE, and nothing else.

Design: a link comes from a web page or a message, not from the person at the keyboard, so it
names a scenario instead of giving a path. A name is one of

    lesson/4, lesson/04-hop-count       a lesson (opened on the student's work copy, as the menu)
    example/kilobot/gradient            a shipped example (examples/<world>/<name>.toml)
    week3/gradient                      a scenario under the folder the IDE was started with
                                        (`bbzide ide --scenarios DIR`); none without that option

(`.toml` may be written or left out). A name is made of plain path parts (letters, digits,
`_`, `-`, `.`, no part starting with a dot, so no `..`, no absolute path, no `~`); the file it
names, symlinks resolved, must lie inside its folder, and so must every script the scenario
runs: a link never reads or opens a file outside the project's examples and lessons and the
folder the user chose. Anything else is refused with a `LinkError` whose one line the IDE
shows. The scenario itself is checked by `bbzide.worlds.scenario.load_scenario` (file:line and
key on a schema error). The token, origin and host checks (`bbzide.ui.access`) run before a
link gets here.
"""

from __future__ import annotations

import os
import re
import shutil
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

from bbzide.diagnostics import UserError

if TYPE_CHECKING:
    from bbzide.lessons.catalog import Lesson
    from bbzide.worlds.scenario import Scenario

#: The repository's examples folder (examples/<world>/<name>.toml).
EXAMPLES_FOLDER = Path(__file__).resolve().parents[2] / "examples"
#: A link's name: path parts of plain characters. 200 characters is far above any real
#: `folder/sub/name` and keeps a pasted blob out of error messages.
NAME_PATTERN = re.compile(r"[A-Za-z0-9_][A-Za-z0-9_.-]*(/[A-Za-z0-9_][A-Za-z0-9_.-]*)*\Z")
MAX_NAME_LENGTH = 200
LESSON_PREFIX, EXAMPLE_PREFIX = "lesson/", "example/"


class LinkError(UserError):
    """A `?scenario=` link that names nothing this IDE may open."""


@dataclass(frozen=True)
class LinkTarget:
    """What a link opens: the scenario, the lesson it belongs to (None: not a lesson), and
    whether its script is a shipped file (edited through a scratch copy, never in place)."""

    scenario: Scenario
    lesson: Lesson | None = None
    shipped: bool = False


def resolve_link(name: str, folder: Path | None = None) -> LinkTarget:
    """The scenario a link's `name` opens (see the module doc), or a `LinkError`."""
    from bbzide.worlds.scenario import load_scenario

    name = name.strip()
    if not name:
        raise LinkError("the link names no scenario (?scenario=lesson/1, "
                        "?scenario=example/kilobot/gradient, ...)")
    if len(name) > MAX_NAME_LENGTH or not NAME_PATTERN.match(name):
        shown = name if len(name) <= 60 else name[:60] + "…"
        raise LinkError(f"a link opens a lesson (lesson/4), an example "
                        f"(example/kilobot/gradient) or a scenario by its name in the IDE's "
                        f"scenario folder, not a path: {shown!r} is refused")
    if name.startswith(LESSON_PREFIX):
        chosen = _lesson(name[len(LESSON_PREFIX):])
        return LinkTarget(chosen.scenario(), lesson=chosen, shipped=True)
    if name.startswith(EXAMPLE_PREFIX):
        path = _inside(EXAMPLES_FOLDER, name[len(EXAMPLE_PREFIX):], "the examples")
        return LinkTarget(_scripts_inside(load_scenario(path), EXAMPLES_FOLDER), shipped=True)
    if folder is None:
        raise LinkError(f"{name!r} is not a lesson (lesson/N) or an example (example/WORLD/NAME), "
                        "and this IDE was started without a scenario folder "
                        "(bbzide ide --scenarios DIR)")
    root = folder.resolve()
    return LinkTarget(_scripts_inside(load_scenario(_inside(root, name, str(root))), root))


def scratch_copy(shipped: Path) -> Path:
    """The file the IDE edits in place of a shipped script (an example): a copy in the user's
    data directory (`~/.local/share/bbzide/scratch/`), made the first time and kept after, so
    the shipped file stays as it is and the user's edits stay too."""
    data_home = Path(os.environ.get("XDG_DATA_HOME") or Path.home() / ".local" / "share")
    scratch = data_home / "bbzide" / "scratch" / shipped.name
    if not scratch.exists():
        scratch.parent.mkdir(parents=True, exist_ok=True)
        shutil.copyfile(shipped, scratch)
    return scratch


def _lesson(key: str) -> Lesson:
    from bbzide.lessons import catalog

    for candidate in catalog.lessons():
        if key in (str(candidate.number), f"{candidate.number:02}", candidate.name):
            return candidate
    names = ", ".join(f"lesson/{each.number}" for each in catalog.lessons())
    raise LinkError(f"no lesson {key!r}; the lessons are {names}")


def _inside(root: Path, relative: str, where: str) -> Path:
    """`root/relative[.toml]`, symlinks resolved, when it is a scenario file inside `root`."""
    if not relative.endswith(".toml"):
        relative += ".toml"
    path = (root / relative).resolve()
    if not path.is_relative_to(root.resolve()):
        raise LinkError(f"{relative} leads outside {where}: refused")
    if not path.is_file():
        raise LinkError(f"no scenario {relative} in {where}")
    return path


def _scripts_inside(scenario: Scenario, root: Path) -> Scenario:
    for script in scenario.scripts():
        if not script.resolve().is_relative_to(root.resolve()):
            raise LinkError(f"{scenario.source}: its script {script} lies outside "
                            f"{root}: a link opens scripts of that folder only")
    return scenario
