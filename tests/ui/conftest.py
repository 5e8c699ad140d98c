"""tests/ui: make the helpers beside the tests importable (`doubles`, `browser`), and end the
shared Chromium (`browser.shared_browser`) once no browser module follows.

The browser modules (test_browser_*.py) share one Chromium per test process while they run one
after another. Before a module of another kind runs, and at the end, it is closed: while the
Playwright driver runs, its event loop counts as running in the test thread between calls, which
`asyncio.run` and libraries that look for a running loop would trip over.
"""

import sys
from collections.abc import Iterator
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent))

from browser import close_browsers  # noqa: E402

BROWSER_MODULE_PREFIX = "test_browser_"


def _is_browser_module(item: pytest.Item | None) -> bool:
    return item is not None and item.path.name.startswith(BROWSER_MODULE_PREFIX)


@pytest.hookimpl(wrapper=True)  # after the module's own teardown, which closes its context
def pytest_runtest_teardown(item: pytest.Item, nextitem: pytest.Item | None) -> Iterator[None]:
    try:
        yield
    finally:
        if not _is_browser_module(nextitem):
            close_browsers()
