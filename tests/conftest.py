"""Shared pytest setup: the tests directory is importable (`import corpus`), the property tests'
Hypothesis profile, and the run ends with the conformance corpus pass counts.

Every test module that imports a corpus folder from `tests/corpus.py` is a corpus test; its
parametrised tests (one case per corpus script or run) are tallied per test function and printed
in the terminal summary, so `make test` shows e.g. "bo byte-identical: 81/81".
"""

from __future__ import annotations

from collections import defaultdict

import corpus
import pytest
from hypothesis import HealthCheck, settings

# Property tests judge behaviour, not speed: no per-example deadline and no "too slow" health
# check, which a loaded machine trips (the default deadline is 200 ms of wall time). With `CI`
# set, Hypothesis starts from its own "ci" profile (the same two, and derandomised examples, so
# a CI result reproduces); this profile extends whichever is loaded, so local runs get the same
# tolerance and keep exploring new examples.
settings.register_profile(
    "bbzide",
    settings.default,
    deadline=None,
    suppress_health_check=[HealthCheck.too_slow],
)
settings.load_profile("bbzide")

_CORPUS_PATHS = {corpus.CORPUS, corpus.COMPILER_DIR, corpus.COMPILER_ERRORS_DIR, corpus.BBZ_DIR}
_tally: dict[str, list[int]] = defaultdict(lambda: [0, 0])  # passed, run
_corpus_items: dict[str, str] = {}


def _is_corpus_module(module: object) -> bool:
    return any(
        isinstance(value, type(corpus.CORPUS)) and value in _CORPUS_PATHS
        for value in vars(module).values()
    )


def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    for item in items:
        module = getattr(item, "module", None)
        if module is None or not hasattr(item, "callspec") or not _is_corpus_module(module):
            continue
        name = f"{module.__name__.rsplit('.', 1)[-1]}::{item.originalname}"
        _corpus_items[item.nodeid] = name


def pytest_runtest_logreport(report: pytest.TestReport) -> None:
    name = _corpus_items.get(report.nodeid)
    if name is None:
        return
    if report.when == "call" or (report.when == "setup" and not report.passed):
        counts = _tally[name]
        counts[1] += 1
        counts[0] += int(report.passed)


def pytest_terminal_summary(terminalreporter: pytest.TerminalReporter) -> None:
    if not _tally and not corpus.REPORTED:
        return
    terminalreporter.section("conformance corpus: passed / run")
    for label in sorted(corpus.REPORTED):
        passed, run = corpus.REPORTED[label]
        terminalreporter.write_line(f"{passed:5d} / {run:<5d} {label}")
    for name in sorted(_tally):
        passed, run = _tally[name]
        terminalreporter.write_line(f"{passed:5d} / {run:<5d} {name}")
