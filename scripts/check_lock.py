"""Refuse a venv whose packages are not the ones pyproject.toml pins.

`make setup` installs requirements.lock, not pyproject.toml: a dependency added to (or re-pinned
in) pyproject.toml without `make lock` would otherwise be missing or at another version with no
word about it. This reads every requirement of [project] dependencies and of each extra (all of
them exact pins, `name==version`) and compares it with what is installed; any difference is one
line naming the package, then the remedy, and exit status 1.
"""

from __future__ import annotations

import sys
import tomllib
from importlib import metadata
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
LOCK_NAME = "requirements.lock"


def pinned_requirements(pyproject: dict) -> list[str]:
    """Every requirement string of the project, its extras included. An extra that names the
    project itself (`bbzide[cluster]` in `dev`) adds that extra's pins, which are read anyway."""
    project = pyproject["project"]
    requirements = list(project.get("dependencies", []))
    for extra in project.get("optional-dependencies", {}).values():
        requirements.extend(extra)
    own = project.get("name")
    return [r for r in requirements if r.partition("[")[0].strip() != own]


def mismatches(requirements: list[str]) -> list[str]:
    """One line per requirement the installed packages do not meet exactly."""
    problems = []
    for requirement in requirements:
        name, separator, version = requirement.partition("==")
        name, version = name.strip(), version.strip()
        if not separator:
            problems.append(f"{requirement!r} is not an exact pin (name==version)")
            continue
        try:
            installed = metadata.version(name)
        except metadata.PackageNotFoundError:
            problems.append(f"{name}=={version} is not installed (not in {LOCK_NAME})")
            continue
        if installed != version:
            problems.append(f"{name}: pyproject.toml pins {version}, {LOCK_NAME} has {installed}")
    return problems


def main() -> int:
    with open(REPO / "pyproject.toml", "rb") as handle:
        problems = mismatches(pinned_requirements(tomllib.load(handle)))
    for problem in problems:
        print(f"check_lock: {problem}", file=sys.stderr)
    if problems:
        print(f"check_lock: {LOCK_NAME} is older than pyproject.toml: run `make lock`, "
              "then `make setup`", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
