"""`make setup` compiles the kernels again when a file they are built from changes: its stamp
depends on the Makefile's KERNEL_SOURCES, which must name every file the kernel cache's digest
reads (fastgc.kernel_sources), or a change to one of them would leave the first swarm after a
pull compiling for 30-60 s."""

from __future__ import annotations

import shutil
import subprocess
from pathlib import Path

import pytest

from bbzide.vm.compiled import fastgc

REPO = Path(__file__).resolve().parents[2]


def _makefile_variable(name: str) -> list[str]:
    # -q: question mode, nothing is built; -p prints the variables, := ones already expanded
    database = subprocess.run(["make", "-qp"], cwd=REPO, capture_output=True, text=True).stdout
    for line in database.splitlines():
        if line.startswith(f"{name} := "):
            return line.split(" := ", 1)[1].split()
    raise AssertionError(f"the Makefile defines no {name}")


@pytest.mark.skipif(shutil.which("make") is None, reason="needs make, as `make setup` does")
def test_makefile_kernel_sources_are_the_digests_sources() -> None:
    listed = {(REPO / path).resolve() for path in _makefile_variable("KERNEL_SOURCES")}
    digested = {path.resolve() for path in fastgc.kernel_sources()}
    assert listed == digested
    assert len(digested) > 10  # the compiled folder's modules and the layouts
