"""Lines the conformance tests want printed at the end of a pytest run (see conftest.py)."""

from __future__ import annotations

SUMMARY: list[str] = []
