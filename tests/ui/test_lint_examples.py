"""The undefined-global lint on every shipped script: no false warnings.

Each example (`examples/<world>/*.bzz`, its world from the scenario beside it) and each
lesson's starter and solution (the world of the lesson's scenario) is compiled for its world
and linted with that world's host functions: a warning there would teach a student to distrust
the editor. Field names (`t.x`, `neighbors.filter`, `r.front`) are keys, never globals.
"""

from __future__ import annotations

import tomllib
from pathlib import Path

import pytest

from bbzide.compiler.call_sites import lint_globals, robot_phrase
from bbzide.ui.world_adapter import WorldsBackend

REPO = Path(__file__).resolve().parents[2]
BACKEND = WorldsBackend()


def shipped_scripts() -> list[tuple[Path, str]]:
    found = []
    for script in sorted((REPO / "examples").glob("*/*.bzz")):
        scenario = script.with_suffix(".toml")
        if scenario.is_file():
            found.append((script, tomllib.loads(scenario.read_text())["world"]))
    for lesson in sorted((REPO / "bbzide" / "lessons").glob("*/scenario.toml")):
        world = tomllib.loads(lesson.read_text())["world"]
        found.extend((lesson.parent / name, world) for name in ("starter.bzz", "solution.bzz"))
    return found


def lint(text: str, path: Path, world: str) -> list[str]:
    _, program = BACKEND.compile(text, path, world)
    return [f"{where.line}:{where.col} {message}"
            for where, message in lint_globals(program, BACKEND.host_names(world),
                                               robot_phrase(world))]


@pytest.mark.parametrize(("script", "world"), shipped_scripts(),
                         ids=lambda value: value.parent.name + "/" + value.name
                         if isinstance(value, Path) else value)
def test_no_shipped_script_gets_a_lint_warning(script: Path, world: str) -> None:
    assert lint(script.read_text(), script, world) == []


def test_field_names_are_not_globals(tmp_path: Path) -> None:
    path = tmp_path / "fields.bzz"
    text = ("t = {.x = 1, .front = 2}\n"
            "function init() {\n"
            "  t.x = t.front + t.filter\n"
            "  var near = neighbors.filter(function(rid, d) { return d.distance < 10 })\n"
            "  nosuch.x = 1\n"
            "}\n"
            "function step() { }\n")
    warnings = lint(text, path, "kilobot")
    assert len(warnings) == 1 and warnings[0].startswith("5:2 `nosuch` is never defined")
