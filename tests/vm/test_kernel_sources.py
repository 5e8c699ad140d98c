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


@pytest.mark.skipif(not fastgc.COMPILED, reason="numba compiles nothing without numba")
def test_a_kernel_called_with_constants_is_compiled_for_their_types_not_their_values() -> None:
    """A kernel that another calls with constants (`first_free(..., 4, 0)`) gets one machine
    code, not one per constant: each would cost the set-up its compile time again. numba
    resolves a call made from compiled code with `get_call_template`, a constant typed as a
    `Literal`; the kernel must come out compiled (or loaded from the cache) for plain ints."""
    from numba.core import types

    heap = types.Array(types.uint8, 1, "C")
    constants = (types.literal(4), types.literal(0))
    fastgc.first_free.get_call_template((heap, types.int64, types.int64, types.int64,
                                         *constants), {})
    signatures = fastgc.first_free.signatures
    assert (heap, types.int64, types.int64, types.int64, types.int64, types.int64) in signatures
    assert [s for s in signatures if any(isinstance(a, types.Literal) for a in s)] == []
