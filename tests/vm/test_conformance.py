"""The VM model against the corpus: every harness run of ``bbz/*.cmd`` (92 runs).

Each run is replayed with :func:`bbzide.harness.runner.run_command_line` (the reference harness's
options; ``bbzharness-pc`` → the PC profile, ``bbzavr.py`` → the Kilobot profile) and its
``#BBZDUMP 1`` text is compared with the reference dump by the corpus's own tool
(``tools/bbzconf.py``): level (a) byte-exact (heap bytes except C-closure pointers) and level
(b) semantic. A failing run is reported with bbzconf's first lines: the dump, the field or
the heap byte offsets that differ. The pass counts at both levels are printed at the end of
the pytest run (``tests/corpus.py`` ``report``).
"""

from __future__ import annotations

import contextlib
import functools
import importlib.util
import io
import sys
import tempfile
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).parent))

from corpus import BBZ_DIR, BBZCONF, report  # noqa: E402

from bbzide.harness.options import split_command_line  # noqa: E402
from bbzide.harness.runner import run_command_line  # noqa: E402
from bbzide.vm.profiles import KILOBOT, PC  # noqa: E402

HARNESSES = {"bbzharness-pc": PC, "bbzavr.py": KILOBOT}


def _bbzconf():  # noqa: ANN202 - the corpus tool as a module
    spec = importlib.util.spec_from_file_location("bbzconf", BBZCONF)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def corpus_runs() -> list[tuple[str, str, list[str]]]:
    """(dump file, harness, arguments) of every harness line of ``bbz/*.cmd``."""
    runs = []
    for cmd in sorted(Path(BBZ_DIR).glob("*.cmd")):
        for line in cmd.read_text().splitlines():
            words = split_command_line(line)
            if not words or words[0] not in HARNESSES:
                continue
            redirect = words.index(">")
            runs.append((words[redirect + 1], words[0], words[1:redirect]))
    return runs


RUNS = corpus_runs()


def _compare(tool, reference: Path, mine: Path, semantic: bool) -> tuple[int, str]:  # noqa: ANN001
    buf = io.StringIO()
    with contextlib.redirect_stdout(buf):
        differences = tool.compare(str(reference), str(mine), semantic)
    return differences, buf.getvalue()


@functools.cache
def results() -> dict[str, tuple[int, str, int, str]]:
    """dump name → (level a differences, report, level b differences, report)."""
    tool = _bbzconf()
    out: dict[str, tuple[int, str, int, str]] = {}
    with tempfile.TemporaryDirectory() as tmp:
        for name, harness, argv in RUNS:
            run = run_command_line(argv, Path(BBZ_DIR), HARNESSES[harness])
            mine = Path(tmp) / name
            mine.write_text("\n".join(run.lines) + "\n")
            reference = Path(BBZ_DIR) / name
            da, ra = _compare(tool, reference, mine, semantic=False)
            db, rb = _compare(tool, reference, mine, semantic=True)
            out[name] = (da, ra, db, rb)
    a = sum(1 for v in out.values() if v[0] == 0)
    b = sum(1 for v in out.values() if v[2] == 0)
    report("VM harness runs equal at level (a) (bbzconf diff)", a, len(out))
    report("VM harness runs equal at level (b) (bbzconf sdiff)", b, len(out))
    return out


def test_the_corpus_has_92_harness_runs() -> None:
    assert len(RUNS) == 92
    assert all((Path(BBZ_DIR) / name).exists() for name, _, _ in RUNS)


@pytest.mark.parametrize("name", [r[0] for r in RUNS])
def test_run_matches_reference_at_level_a(name: str) -> None:
    differences, report, _, _ = results()[name]
    first = "\n".join(report.splitlines()[:6])
    assert differences == 0, f"{name}: {differences} difference(s) at level (a):\n{first}"


@pytest.mark.parametrize("name", [r[0] for r in RUNS])
def test_run_matches_reference_at_level_b(name: str) -> None:
    _, _, differences, report = results()[name]
    first = "\n".join(report.splitlines()[:6])
    assert differences == 0, f"{name}: {differences} difference(s) at level (b):\n{first}"


def test_a_changed_heap_byte_is_reported(tmp_path: Path) -> None:
    """The comparison can fail: one flipped heap byte in our dump is named by offset."""
    tool = _bbzconf()
    name, harness, argv = RUNS[0]
    run = run_command_line(argv, Path(BBZ_DIR), HARNESSES[harness])
    lines = list(run.lines)
    i = next(k for k, line in enumerate(lines) if line.startswith("heap "))
    heap = bytearray(bytes.fromhex(lines[i][5:]))
    offset = len(heap) - 1  # a segment byte: never masked
    heap[offset] ^= 0xFF
    lines[i] = "heap " + heap.hex()
    mine = tmp_path / name
    mine.write_text("\n".join(lines) + "\n")
    differences, report = _compare(tool, Path(BBZ_DIR) / name, mine, semantic=False)
    assert differences == 1
    assert f"[{offset}]" in report
