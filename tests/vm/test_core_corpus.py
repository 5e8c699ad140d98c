"""vm-core against the corpus: every reference dump of the 92 runs, dump by dump.

Counts dumps equal at level (a) (heap bytes under the C-closure mask, rtobj, ltseg, state,
error, pc, stack). The construct+set_bcode dump must match for every run; the whole-run
counts are printed (later dumps need the runtime libraries of vm-runtime).
Also checks that the fast GC mode gives exactly the stress-mode dumps on the whole corpus.
"""

from __future__ import annotations

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).parent))

from core_driver import heap_differences, parse_reference, run_script  # noqa: E402
from corpus import BBZ_DIR  # noqa: E402

DUMPS = sorted(Path(BBZ_DIR).glob("*.dump"))


def _equal(r, m, obj_size: int) -> bool:  # noqa: ANN001
    return (r.label == m.label and r.state == m.state and r.error == m.error and r.pc == m.pc
            and r.stack == m.stack and r.rtobj == m.rtobj and r.ltseg == m.ltseg
            and not heap_differences(r, m, obj_size))


def test_corpus_present() -> None:
    assert len(DUMPS) == 92


def test_construct_and_set_bcode_match_every_run() -> None:
    failures = []
    for f in DUMPS:
        _, ref, _ = parse_reference(f)
        mine = run_script(Path(BBZ_DIR), f.name)
        size = 9 if f.name.endswith(".pc.dump") else 3
        if not _equal(ref[0], mine[0], size):
            failures.append(f.name)
    print(f"dump 1 (construct+set_bcode): {len(DUMPS) - len(failures)}/{len(DUMPS)} equal")
    assert not failures


def test_corpus_pass_counts_and_prefix() -> None:
    """Every run matches on its leading dumps (setup, script at least); counts printed."""
    total = equal = full = 0
    short = []
    for f in DUMPS:
        _, ref, _ = parse_reference(f)
        mine = run_script(Path(BBZ_DIR), f.name)
        size = 9 if f.name.endswith(".pc.dump") else 3
        prefix = 0
        for r, m in zip(ref, mine, strict=False):
            if not _equal(r, m, size):
                break
            prefix += 1
        total += len(ref)
        equal += prefix
        full += prefix == len(ref) == len(mine)
        if prefix < 3:
            short.append((f.name, prefix))
    print(f"level (a): {full}/{len(DUMPS)} runs fully equal, {equal}/{total} dumps equal "
          "(leading prefix per run)")
    assert not short, short


def test_fast_gc_mode_gives_identical_states() -> None:
    for f in DUMPS:
        stress = run_script(Path(BBZ_DIR), f.name, stress_gc=True)
        fast = run_script(Path(BBZ_DIR), f.name, stress_gc=False)
        assert [(s.label, s.state, s.pc, s.stack, s.rtobj, s.ltseg, s.heap) for s in stress] == \
            [(s.label, s.state, s.pc, s.stack, s.rtobj, s.ltseg, s.heap) for s in fast], f.name
