"""vm tests: print the corpus conformance pass counts in pytest's terminal summary."""

from __future__ import annotations

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).parent))

from conformance_summary import SUMMARY  # noqa: E402


def pytest_terminal_summary(terminalreporter) -> None:  # noqa: ANN001 - pytest's reporter
    for line in SUMMARY:
        terminalreporter.write_line(line)
