"""Shared pytest setup: the tests directory is importable (`import corpus`), the property tests'
Hypothesis profile, the order that lets `make test` keep every core busy, and the run ends
with the conformance corpus pass counts.

Parallel runs (pytest-xdist, `make test` passes `--dist loadfile`): each worker is a process
of its own that takes whole test modules, so a module- or class-scoped fixture (a running IDE
and its Chromium, a recorded replay, a swarm run shared by a module's asserts) is built once,
as in a serial run. (`--dist loadgroup` with groups per shared fixture would balance finer, but
pytest-xdist 3.8 marks a group by rewriting the test's node id, which pytest 9.2 no longer
reads: its groups are silently ignored.) Tests marked `slow` come first, so their modules are
handed out first: a long module handed out last would keep one worker busy while the others
sit idle.

Every test module that imports a corpus folder from `tests/corpus.py` is a corpus test; its
parametrised tests (one case per corpus script or run) are tallied per test function and printed
in the terminal summary, so `make test` shows e.g. "bo byte-identical: 81/81". The tally travels
with each test's report (its `user_properties`) and the loop-style counts of `corpus.report` with
each worker's output, so a parallel run prints the same summary as a serial one.
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
#: the user property naming a corpus case's tally line (it travels in the test's reports)
_TALLY_PROPERTY = "corpus_tally"
#: the key of a worker's `corpus.report` counts in its output to the controlling process
_REPORTED_OUTPUT = "corpus_reported"
_tally: dict[str, list[int]] = defaultdict(lambda: [0, 0])  # passed, run


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
        item.user_properties.append((_TALLY_PROPERTY, name))
    # tests marked `slow` first (a stable sort: the rest keep their order), see above
    items.sort(key=lambda item: item.get_closest_marker("slow") is None)


def pytest_runtest_logreport(report: pytest.TestReport) -> None:
    name = dict(report.user_properties).get(_TALLY_PROPERTY)
    if name is None:
        return
    if report.when == "call" or (report.when == "setup" and not report.passed):
        counts = _tally[name]
        counts[1] += 1
        counts[0] += int(report.passed)


def pytest_sessionfinish(session: pytest.Session) -> None:
    output = getattr(session.config, "workeroutput", None)  # set in an xdist worker only
    if output is not None:
        output[_REPORTED_OUTPUT] = dict(corpus.REPORTED)


@pytest.hookimpl(optionalhook=True)  # a pytest-xdist hook: the controller hears a worker end
def pytest_testnodedown(node: object, error: object) -> None:
    reported = getattr(node, "workeroutput", {}).get(_REPORTED_OUTPUT, {})
    corpus.REPORTED.update({label: tuple(counts) for label, counts in reported.items()})


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
