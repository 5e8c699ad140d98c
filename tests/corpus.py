"""Where the conformance corpus is, for tests and benchmarks.

The corpus (`shared/conformance/`, the reference toolchains' outputs) sits beside the repository
in CI and on developer machines (`<repo>/../shared/conformance`); a git worktree may sit deeper,
so every ancestor of the repository is tried. `BBZIDE_CORPUS` overrides the search. A missing
corpus is an error, never a skip: CI must run the whole corpus.
"""

from __future__ import annotations

import os
from pathlib import Path

REPO_ROOT = Path(__file__).resolve().parent.parent


def corpus_root() -> Path:
    override = os.environ.get("BBZIDE_CORPUS")
    if override:
        return Path(override).resolve()
    for ancestor in REPO_ROOT.parents:
        candidate = ancestor / "shared" / "conformance"
        if candidate.is_dir():
            return candidate
    raise FileNotFoundError(
        "conformance corpus not found: expected shared/conformance beside the repository "
        "(or set BBZIDE_CORPUS)"
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
