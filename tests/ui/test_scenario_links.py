"""What a `?scenario=` link may open: lessons, examples and the IDE's scenario folder, by name;
never a path, never a file (or a script) outside those folders."""

from __future__ import annotations

from pathlib import Path

import pytest

from bbzide.lessons import catalog
from bbzide.ui.scenario_links import EXAMPLES_FOLDER, LinkError, resolve_link
from bbzide.worlds.scenario import ScenarioError

SCRIPT = "function init() {\n}\nfunction step() {\n}\n"


def scenario_text(script: str = "a.bzz") -> str:
    return f'version = 1\nworld = "kilobot"\n[[robots]]\ncount = 2\nscript = "{script}"\n'


@pytest.fixture
def folder(tmp_path: Path) -> Path:
    root = tmp_path / "class"
    (root / "week3").mkdir(parents=True)
    (root / "a.bzz").write_text(SCRIPT)
    (root / "week3" / "gradient.toml").write_text(scenario_text("../a.bzz"))
    return root


@pytest.mark.parametrize("name", ["lesson/4", "lesson/04", "lesson/04-hop-count"])
def test_a_lesson_by_number_or_folder_name(name: str) -> None:
    target = resolve_link(name)
    assert target.lesson == catalog.lesson(4) and target.shipped
    assert target.scenario == catalog.lesson(4).scenario()


@pytest.mark.parametrize("name", ["example/kilobot/gradient", "example/kilobot/gradient.toml"])
def test_an_example_by_world_and_name(name: str) -> None:
    target = resolve_link(name)
    assert target.shipped and target.lesson is None
    assert target.scenario.source == EXAMPLES_FOLDER / "kilobot" / "gradient.toml"


def test_a_scenario_of_the_folder_the_ide_was_started_with(folder: Path) -> None:
    target = resolve_link("week3/gradient", folder)
    assert not target.shipped
    assert target.scenario.scripts() == [(folder / "a.bzz").resolve()]


@pytest.mark.parametrize("name", [
    "../secret", "/etc/passwd", "week3/../../x", "~/x", ".hidden", "week3/.x",
    "example/../README", "a\\b", "x y", "file:///etc/passwd", "a" * 201,
])
def test_paths_are_refused(folder: Path, name: str) -> None:
    with pytest.raises(LinkError, match="not a path"):
        resolve_link(name, folder)


def test_without_a_scenario_folder_only_lessons_and_examples_open() -> None:
    with pytest.raises(LinkError, match="--scenarios DIR"):
        resolve_link("week3/gradient")


def test_no_such_lesson_or_scenario(folder: Path) -> None:
    with pytest.raises(LinkError, match="no lesson '99'"):
        resolve_link("lesson/99")
    with pytest.raises(LinkError, match="no scenario nothing.toml"):
        resolve_link("nothing", folder)


def test_a_symlink_out_of_the_folder_is_refused(folder: Path, tmp_path: Path) -> None:
    outside = tmp_path / "outside"
    outside.mkdir()
    (outside / "a.bzz").write_text(SCRIPT)
    (outside / "s.toml").write_text(scenario_text())
    (folder / "escape.toml").symlink_to(outside / "s.toml")
    with pytest.raises(LinkError, match="leads outside"):
        resolve_link("escape", folder)


def test_a_scenario_whose_script_lies_outside_the_folder_is_refused(folder: Path,
                                                                     tmp_path: Path) -> None:
    (tmp_path / "private.bzz").write_text(SCRIPT)
    (folder / "reach.toml").write_text(scenario_text("../private.bzz"))
    with pytest.raises(LinkError, match="outside"):
        resolve_link("reach", folder)


def test_a_malformed_scenario_names_its_line_and_key(folder: Path) -> None:
    (folder / "bad.toml").write_text(scenario_text().replace("count = 2", "count = 0"))
    with pytest.raises(ScenarioError, match=r"bad\.toml:4: robots\[0\]\.count: must be >= 1"):
        resolve_link("bad", folder)
