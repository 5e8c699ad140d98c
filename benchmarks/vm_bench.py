"""Instruction and control-step rate of the BittyBuzz VM model, per profile and GC mode.

Scripts (ours, beside this file):
* ``vm_loop.bzz`` — loop-heavy, ~3,400 instructions per control step (the size of the
  reference measurement);
* ``vm_neighbors.bzz`` — neighbor-heavy: ``neighbors.foreach/reduce/filter`` over 15
  neighbors (added once after the top-level code, as a robot's receive handler would: in
  the heap on normal builds, in the ring buffer on XTREME ones), one Buzz closure call
  per neighbor and library call — the call path of the worlds' listeners.

Each run: construct, ``set_bcode``, the top-level code, then ``step`` called repeatedly
(the firmware's loop, ``pop`` variant) for a fixed CPU time. Modes: ``stress`` collects
before every instruction (the reference ``bbzvm_step``), ``fast`` is the default fast VM
(compiled collector, provably changeless collections skipped — ARCHITECTURE.md "Two modes,
and the seam").
Printed: instructions/s, steps/s, fast/stress ratio, and the ratio to the C BittyBuzz built
with -O2 on this machine (≈ 1.2 M instructions/s on a 3,400-instruction loop step; the
reference runs its GC before every instruction). Rates are per second of this process's
CPU time (``time.process_time``): the machine is shared, and wall time would measure the
other jobs as much as the VM (the load average is printed first). The first fast run also
would pay numba's first-call compilation (once per cache, ``bbzide/vm/compiled/__pycache__``), so a
short untimed warm-up run comes first and its duration is printed.

    PYTHONPATH=. python benchmarks/vm_bench.py [seconds per run, default 2]
"""

from __future__ import annotations

import os
import sys
import time
from pathlib import Path

from bbzide.compiler import bbzfloat, bittybuzz_string_table, compile_file
from bbzide.vm import neighbors
from bbzide.vm.profiles import PROFILES, Profile
from bbzide.vm.vm import VM, State

HERE = Path(__file__).resolve().parent
#: instructions/s of the reference C BittyBuzz (-O2) on the loop script, this machine
C_REFERENCE_RATE = 1.2e6
#: neighbors the neighbor-heavy script sees (the Kilobot neighbors capacity)
NEIGHBORS = 15


def _load(script: str) -> tuple[bytes, list[str]]:
    # the BittyBuzz string table: library names (``neighbors``, ...) at their firmware ids
    program = compile_file(HERE / script, string_table=bittybuzz_string_table([])).to_bbo()
    return program.bbo, program.strings


def add_neighbors(vm: VM, count: int = NEIGHBORS) -> None:
    """``count`` neighbors at 10, 20, ... cm (bbzfloat bits or u8, as the build stores)."""
    for rid in range(1, count + 1):
        values = (10.0 * rid, 3.0 * rid, 0.0)
        if vm.profile.neighbors_floats:
            d, a, e = (bbzfloat.from_float(v) for v in values)
        else:
            d, a, e = (min(255, round(v)) for v in values)
        neighbors.add(vm, neighbors.NeighborEntry(rid, d, a, e))


def bench(profile: Profile, stress_gc: bool, script: str, seconds: float
          ) -> tuple[float, float] | str:
    """(instructions/s, steps/s), or a reason string when the script cannot run."""
    bbo, strings = _load(script)
    vm = VM(profile, stress_gc=stress_gc)
    vm.construct()
    vm.set_bcode(bbo)
    vm.run(max_instructions=1_000_000)
    if vm.state == State.ERROR:
        return f"top level: {vm.error.name}"
    vm.state = State.READY
    if "neighbors" in script:
        add_neighbors(vm)
    step_sid = strings.index("step")
    steps = 0
    start_instr = vm.instructions_executed
    t0 = time.process_time()
    while time.process_time() - t0 < seconds:
        vm.push_nil()  # self: bbzvm_function_call consumes the entry below the closure
        vm.function_call(step_sid, 0)
        if vm.state == State.ERROR:
            return f"step: {vm.error.name} at pc {vm.pc}"
        vm.pop()
        steps += 1
    dt = time.process_time() - t0
    return (vm.instructions_executed - start_instr) / dt, steps / dt


def main() -> None:
    seconds = float(sys.argv[1]) if len(sys.argv) > 1 else 2.0
    # the machine is shared: the load average says how much the figures are worth
    print("load average (1, 5, 15 min): " + ", ".join(f"{x:.2f}" for x in os.getloadavg()))
    started = time.perf_counter()
    bench(PROFILES["kilobot"], False, "vm_neighbors.bzz", 0.05)  # compiles (or loads) numba
    print(f"warm-up (numba compile or cache load): {time.perf_counter() - started:.1f} s; "
          "rates per CPU second")
    print(f"{'script':16s} {'profile':9s} {'mode':6s} {'instr/s':>10s} {'steps/s':>9s} "
          f"{'fast/stress':>11s} {'vs C -O2':>8s}")
    for script in ("vm_loop.bzz", "vm_neighbors.bzz"):
        for profile in PROFILES.values():
            rates: dict[str, float] = {}
            for mode in ("stress", "fast"):
                # stress mode is ~20x slower: a shorter window keeps `make bench` short
                window = seconds / 4 if mode == "stress" else seconds
                result = bench(profile, mode == "stress", script, window)
                if isinstance(result, str):
                    print(f"{script:16s} {profile.name:9s} {mode:6s} skipped ({result})")
                    continue
                ips, sps = result
                rates[mode] = ips
                ratio = f"{ips / rates['stress']:10.1f}x" if mode == "fast" and \
                    "stress" in rates else ""
                print(f"{script:16s} {profile.name:9s} {mode:6s} {ips:10,.0f} {sps:9,.1f} "
                      f"{ratio:>11s} {ips / C_REFERENCE_RATE:7.2f}x")


if __name__ == "__main__":
    main()
