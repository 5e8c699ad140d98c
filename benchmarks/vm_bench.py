"""Instruction rate of the BittyBuzz VM model (vm-core).

Runs the corpus script ``loops_locals`` (loop-heavy: locals, arithmetic, tables) with the
``init``/``step`` functions called repeatedly, per profile and GC mode, and prints
instructions/s and steps/s. Reference: the C BittyBuzz -O2 on this machine ≈ 1.2 M instr/s.

    PYTHONPATH=. /work/venv/bin/python benchmarks/vm_bench.py
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

from bbzide.vm.profiles import KILOBOT, PC, Profile
from bbzide.vm.vm import VM, State

BBZ = Path("/work/shared/conformance/bbz")
C_REFERENCE_RATE = 1.2e6


def _sid(name: str, script: str) -> int:
    return (BBZ / f"{script}.bst").read_text().splitlines().index(name)


def bench(profile: Profile, stress_gc: bool, script: str = "loops_locals",
          seconds: float = 2.0) -> tuple[float, float]:
    vm = VM(profile, stress_gc=stress_gc)
    vm.construct()
    vm.set_bcode((BBZ / f"{script}.bbo").read_bytes())
    log = _sid("log", script)
    vm.function_register(log, "h_print", lambda v: v.ret0())
    vm.run(max_instructions=10_000_000)
    vm.state = State.READY
    step_sid = _sid("step", script)
    steps = 0
    start_instr = vm.instructions_executed
    t0 = time.perf_counter()
    while time.perf_counter() - t0 < seconds and vm.state == State.READY:
        vm.push_nil()  # self: bbzvm_function_call consumes the entry below the closure
        vm.function_call(step_sid, 0)
        vm.pop()
        steps += 1
    dt = time.perf_counter() - t0
    return (vm.instructions_executed - start_instr) / dt, steps / dt


def main() -> None:
    seconds = float(sys.argv[1]) if len(sys.argv) > 1 else 2.0
    for profile in (PC, KILOBOT):
        for stress in (True, False):
            ips, sps = bench(profile, stress, seconds=seconds)
            mode = "stress_gc" if stress else "fast"
            print(f"{profile.name:8s} {mode:9s} {ips:12,.0f} instr/s {sps:9,.0f} steps/s "
                  f"({ips / C_REFERENCE_RATE:.2f}x the C reference)")


if __name__ == "__main__":
    main()
