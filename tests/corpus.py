"""Where the conformance corpus is, for tests and benchmarks.

The corpus (`tests/conformance/`: our Buzz scripts and the reference toolchains' outputs for
them, see its README) is part of the repository. `BBZIDE_CORPUS` points the tests at another
copy. A missing corpus is an error, never a skip: every run checks the whole corpus.
"""

from __future__ import annotations

import os
from pathlib import Path

REPO_ROOT = Path(__file__).resolve().parent.parent


def corpus_root() -> Path:
    override = os.environ.get("BBZIDE_CORPUS")
    if override:
        chosen = Path(override).resolve()
        if not chosen.is_dir():
            raise FileNotFoundError(f"BBZIDE_CORPUS={override}: no such folder")
        return chosen
    bundled = REPO_ROOT / "tests" / "conformance"
    if bundled.is_dir():
        return bundled
    raise FileNotFoundError(
        f"conformance corpus not found: expected {bundled} (part of the repository; "
        "restore it with git, or point BBZIDE_CORPUS at a copy)"
    )


CORPUS = corpus_root()
COMPILER_DIR = CORPUS / "compiler"
COMPILER_ERRORS_DIR = COMPILER_DIR / "errors"
BBZ_DIR = CORPUS / "bbz"
BBZCONF = CORPUS / "tools" / "bbzconf.py"

#: Pass counts that loop-style corpus tests report (label -> (passed, run)); the terminal
#: summary of `tests/conftest.py` prints them beside the per-case tallies.
REPORTED: dict[str, tuple[int, int]] = {}


def report(label: str, passed: int, run: int) -> None:
    """Record a corpus pass count for the end-of-run summary (and print it for `-s` runs)."""
    REPORTED[label] = (passed, run)
    print(f"{label}: {passed}/{run}")
