"""scripts/check_lock.py: a venv whose packages are not pyproject.toml's pins is named, package by
package, with the remedy (`make lock`), and the project's own venv passes."""

from __future__ import annotations

import importlib.util
import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
SPEC = importlib.util.spec_from_file_location("check_lock", REPO / "scripts" / "check_lock.py")
assert SPEC is not None and SPEC.loader is not None
check_lock = importlib.util.module_from_spec(SPEC)
SPEC.loader.exec_module(check_lock)


def test_every_pin_of_pyproject_and_its_extras_is_read() -> None:
    pyproject = {"project": {"dependencies": ["numpy==2.4.6"],
                             "optional-dependencies": {"fast": ["numba==0.68.1"],
                                                       "dev": ["pytest==9.2.0"]}}}
    assert check_lock.pinned_requirements(pyproject) == [
        "numpy==2.4.6", "numba==0.68.1", "pytest==9.2.0"]


def test_an_extra_naming_the_project_itself_adds_no_requirement_of_its_own() -> None:
    pyproject = {"project": {"name": "bbzide", "dependencies": [],
                             "optional-dependencies": {"cluster": ["dask==2026.8.0"],
                                                       "dev": ["bbzide[cluster]"]}}}
    assert check_lock.pinned_requirements(pyproject) == ["dask==2026.8.0"]


def test_a_missing_package_another_version_and_a_loose_pin_are_each_named() -> None:
    installed_numpy = check_lock.metadata.version("numpy")
    problems = check_lock.mismatches([
        f"numpy=={installed_numpy}", "numpy==0.0.1", "no-such-package-bbzide==1.0", "numpy>=1"])
    assert problems == [
        f"numpy: pyproject.toml pins 0.0.1, requirements.lock has {installed_numpy}",
        "no-such-package-bbzide==1.0 is not installed (not in requirements.lock)",
        "'numpy>=1' is not an exact pin (name==version)",
    ]


def test_this_venv_matches_pyproject() -> None:
    result = subprocess.run([sys.executable, str(REPO / "scripts" / "check_lock.py")],
                            capture_output=True, text=True)
    assert result.returncode == 0, result.stderr
