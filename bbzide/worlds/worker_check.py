"""What a Dask worker must have to run bbzide's experiments: the project, from the same sources
and the same pinned dependencies as the machine that submits the runs.

Design: `probe()` runs on every worker before the first task (`executors.DaskExecutor`). This
module is shipped to the workers *by value* (`cloudpickle.register_pickle_by_value`), so it must
import nothing but the standard library at module level: on a worker without bbzide the probe
still unpickles and reports "cannot import bbzide" instead of the task failing to unpickle. The
submitting machine runs the same probe and `mismatch` compares the two reports: a worker whose
sources (the package's code and data, the examples the experiments read) or pinned dependency
versions differ could give other results, so it is refused too, with one line saying what
differs and how to fix it.

A worker that joins after the check would fail differently: Dask unpickles a task as it reads
the scheduler's message, and a task that names a bbzide function ends the worker there (the
task then waits forever if no other worker is left). So each task travels as bytes (`ship`)
and the task Dask sees is `pickle.loads(those bytes)`, which needs only the standard library
to unpickle: the bytes unpickle into the call itself, so a missing bbzide is the task's own
`ModuleNotFoundError`, which reaches the submitting machine like any task error.
"""

from __future__ import annotations

import hashlib
import importlib
import importlib.metadata
import platform
import re
import tomllib
from pathlib import Path
from typing import Any

PROJECT = "bbzide"
#: The files a run reads: the package's code and data, and the example scripts and belief maps
#: next to it (examples/ of the checkout, which experiments compile from).
SOURCE_SUFFIXES = (".py", ".bzz", ".bst", ".csv")
#: How to give a worker the project; every refusal ends with it.
INSTALL_HINT = ("on every worker machine, check out the same commit and install it from the "
                "lock file (`make setup`, or `pip install -e '.[cluster]'`), then start "
                "`dask worker` from that environment")


def _sources_digest(root: Path) -> str:
    digest = hashlib.sha256()
    for folder in (root / PROJECT, root / "examples"):
        for path in sorted(folder.rglob("*")):
            if path.suffix in SOURCE_SUFFIXES and "__pycache__" not in path.parts:
                digest.update(str(path.relative_to(root)).encode() + b"\0")
                digest.update(path.read_bytes())
    return digest.hexdigest()


def _pinned_versions(root: Path) -> dict[str, str | None]:
    """The installed version of every core dependency the checkout's pyproject.toml pins.

    Read from the checkout, not from the installed metadata (`importlib.metadata.requires`):
    started from the checkout's folder, Python finds a `bbzide.egg-info` left there by an older
    install before the venv's own record, and client and worker would then compare different
    lists of pins."""
    try:
        with (root / "pyproject.toml").open("rb") as file:
            requirements = tomllib.load(file)["project"]["dependencies"]
    except (OSError, KeyError, tomllib.TOMLDecodeError):
        return {}   # no checkout beside the package: `mismatch` refuses such a worker anyway
    versions: dict[str, str | None] = {}
    for requirement in requirements:
        name = re.match(r"[A-Za-z0-9_.-]+", requirement)
        if name is None:
            continue
        try:
            versions[name.group(0)] = importlib.metadata.version(name.group(0))
        except importlib.metadata.PackageNotFoundError:
            versions[name.group(0)] = None
    return versions


def probe() -> dict[str, Any]:
    """This process's Python, and its bbzide: importable, from which sources, with which pins."""
    report: dict[str, Any] = {"python": ".".join(platform.python_version_tuple()[:2])}
    try:
        package = importlib.import_module(PROJECT)
    except ImportError as error:
        report["error"] = f"cannot import {PROJECT} ({error})"
        return report
    root = Path(package.__file__).resolve().parents[1]
    report["root"] = str(root)
    report["examples"] = (root / "examples").is_dir()
    report["sources"] = _sources_digest(root)
    report["versions"] = _pinned_versions(root)
    return report


def mismatch(worker: dict[str, Any], here: dict[str, Any]) -> str | None:
    """Why a worker (its `probe()` report) cannot run this machine's runs, or None."""
    if "error" in worker:
        return worker["error"]
    if worker["python"] != here["python"]:
        return f"it runs Python {worker['python']}, this machine {here['python']}"
    if not worker["examples"]:
        return (f"its {PROJECT} at {worker['root']} has no examples/ folder beside it "
                "(installed from a wheel, not from a checkout)")
    for name, version in here["versions"].items():
        if worker["versions"].get(name) != version:
            return (f"it has {name} {worker['versions'].get(name) or 'not installed'}, this "
                    f"machine {version}")
    if worker["sources"] != here["sources"]:
        return (f"its {PROJECT} sources at {worker['root']} differ from this machine's "
                "(another commit, or local changes)")
    return None


class _Call:
    """Pickles as `function(item)`: unpickling it runs the task and gives its result."""

    def __init__(self, function: Any, item: Any) -> None:
        self.function, self.item = function, item

    def __reduce__(self) -> tuple[Any, tuple[Any]]:
        return self.function, (self.item,)


def ship(function: Any, item: Any) -> bytes:
    """The task `function(item)` as bytes that `pickle.loads` runs (cloudpickle: functions of
    `__main__` and of modules registered by value travel with it)."""
    import cloudpickle  # with distributed (the cluster extra), like every caller of `ship`

    return cloudpickle.dumps(_Call(function, item))
