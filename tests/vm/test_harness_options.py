"""Every harness command line of the corpus (.cmd) parses into options; bad --reg values fail."""

from __future__ import annotations

import pytest
from corpus import BBZ_DIR

from bbzide.harness.options import (
    HarnessOptionError,
    HostKind,
    group_registrations,
    parse_harness_arguments,
    split_command_line,
)


def harness_lines() -> list[tuple[str, list[str], str]]:
    """(harness program, its arguments, dump file) of every run in the corpus."""
    runs = []
    for cmd in sorted(BBZ_DIR.glob("*.cmd")):
        for line in cmd.read_text().splitlines():
            words = split_command_line(line.split("#", 1)[0])
            if words and words[0] in ("bbzharness-pc", "bbzavr.py"):
                redirect = words.index(">")
                runs.append((words[0], words[1:redirect], words[redirect + 1]))
    return runs


RUNS = harness_lines()


def test_corpus_has_92_runs() -> None:
    assert len(RUNS) == 92


@pytest.mark.parametrize("run", RUNS, ids=[r[2] for r in RUNS])
def test_every_corpus_run_parses(run) -> None:
    _, args, _ = run
    options = parse_harness_arguments(args, BBZ_DIR)
    assert options.bytecode.exists()
    assert options.inject is None or options.inject.exists()
    assert options.loop in ("pop", "robot")
    assert options.registrations[0].name == "log"


def test_table_fields_group() -> None:
    regs = group_registrations(["log=print", "math.min=min", "math.max=reti:3", "led=ret0/1"])
    assert [r.name for r in regs] == ["log", "math", "led"]
    assert regs[1].kind is None
    assert regs[1].fields == (("min", HostKind("min")), ("max", HostKind("reti", 3)))
    assert regs[2].kind == HostKind("ret0", 1)


@pytest.mark.parametrize("bad", ["log", "log=shout", "x=ret0/a", ".f=ret0", "=print"])
def test_bad_registration(bad: str) -> None:
    with pytest.raises(HarnessOptionError):
        group_registrations([bad])
