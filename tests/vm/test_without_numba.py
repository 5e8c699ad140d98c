"""bbzide without numba: the fast mode runs its kernels as plain Python, with the same results.

numba is an optional dependency (the `fast` extra in pyproject.toml): when `import numba` fails,
`bbzide.vm.kernels` hands the kernels back uncompiled and the VM, the in-queue and the swarm step
take their Python paths. This test blocks the import in a child process (``sys.modules["numba"]
= None`` makes every ``import numba`` raise ImportError, as on a machine without it), runs a few
steps of every world's default example there, and compares each run's fingerprint (everything
the run decided, tests/worlds/fingerprint.py) with the same run here, where numba compiles them.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

from bbzide.vm import kernels
from bbzide.worlds.commands import load_script
from bbzide.worlds.engine import Simulation
from bbzide.worlds.registry import WORLDS
from tests.worlds.fingerprint import fingerprint

REPO = Path(__file__).resolve().parents[2]
#: a few robots and steps reach boot, init, the in-queue with messages and a collection in
#: every world's example; the Python kernels are ~100x slower, so the run stays this small
ROBOTS = 4
STEPS = 3

#: the child: numba blocked, then the same runs; prints what it found as one JSON line
CHILD = f"""
import json, sys
sys.modules["numba"] = None
sys.path.insert(0, {str(REPO)!r})
from tests.vm.test_without_numba import world_fingerprints
from bbzide.vm import kernels, vm
print(json.dumps({{"compiled": kernels.COMPILED, "kernel": vm._KERNEL is not None,
                  "numba_loaded": bool(sys.modules.get("numba")),
                  "fingerprints": world_fingerprints()}}))
"""


def world_fingerprints() -> dict[str, str]:
    """The fingerprint of a short run of each world's default example, by world name."""
    prints = {}
    for name, spec in WORLDS.items():
        program = load_script(REPO / spec.example, spec.host_names, [])
        sim = Simulation(name, program, robots=ROBOTS, seed=1, watch=())
        prints[name] = fingerprint(sim, STEPS)
    return prints


def test_without_numba_every_world_runs_the_same() -> None:
    assert kernels.COMPILED, "this process is the compiled side of the comparison: install numba"
    child = subprocess.run([sys.executable, "-c", CHILD], capture_output=True, text=True,
                           cwd=REPO, timeout=600)
    assert child.returncode == 0, child.stderr
    found = json.loads(child.stdout.strip().splitlines()[-1])
    assert found["compiled"] is False and found["kernel"] is False
    assert found["numba_loaded"] is False
    assert found["fingerprints"] == world_fingerprints()
