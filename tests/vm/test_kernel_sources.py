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
def test_a_kernel_is_compiled_for_its_argument_types_never_for_constant_values() -> None:
    """A kernel that another calls with a constant (`_obj_alloc(..., 1, 0)`) gets one machine
    code, not one per constant: each would cost the set-up its compile time again."""
    from numba.core import types
    from numba.core.registry import CPUDispatcher

    from bbzide.vm.compiled import fastbatch, fasthost, fastinbox, fastloop, fastreceive
    from bbzide.worlds.commands import load_script
    from bbzide.worlds.engine import Simulation
    from bbzide.worlds.registry import WORLDS

    for world in ("kilobot", "m300"):
        spec = WORLDS[world]
        program = load_script(REPO / spec.example, spec.host_names, [])
        Simulation(world, program, robots=4, seed=1, watch=()).run(3)
    modules = (fastgc, fastloop, fastbatch, fasthost, fastinbox, fastreceive)
    kernels = [kernel for module in modules for kernel in vars(module).values()
               if isinstance(kernel, CPUDispatcher)]
    compiled = [(kernel.py_func.__qualname__, signature)
                for kernel in kernels for signature in kernel.signatures]
    assert "_obj_alloc" in {name for name, _ in compiled}  # called from compiled code only
    by_value = [(name, signature) for name, signature in compiled
                if any(isinstance(argument, types.Literal) for argument in signature)]
    assert by_value == []
