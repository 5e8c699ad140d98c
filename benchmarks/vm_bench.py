"""Instruction rate of the BittyBuzz VM model against the C BittyBuzz (-O2), script by script.

Scripts (ours, beside this file), each with its profile and neighbour count:
* ``vm_loop.bzz`` — loop-heavy, ~3,400 instructions per control step;
* ``vm_neighbors.bzz`` — ``neighbors.foreach/reduce/filter`` over 15 neighbours, one Buzz
  closure call per neighbour and library call (the listener-style call path);
* ``kilobot_gradient.bzz`` — a Kilobot distance gradient (``neighbors.reduce``, broadcast, LED);
* ``kilobot_foreach.bzz`` — a Kilobot behaviour iterating neighbours (``neighbors.foreach``);
* ``crazyflie_avoid.bzz`` — a Crazyflie neighbour avoidance (float distances, ``foreach``).
Neighbours are added once after the top-level code (in the heap on normal builds, in the ring
buffer on XTREME ones); host functions (``led``, ``motion``, ``velocity``) return at once.

Each run: construct, ``set_bcode``, host functions, the top-level code, the neighbours, then
``step`` called repeatedly for a fixed CPU time. Modes: ``stress`` collects before every
instruction (the reference ``bbzvm_step``), ``fast`` is the default fast VM (ARCHITECTURE.md
"Two modes, and the seam"). Rates are per second of CPU time (``time.process_time`` here, the
harness's ``clock()`` for C): the machine is shared, and wall time would measure the other
jobs as much as the VM (the load average is printed before and after).

The C figure. With ``BBZIDE_BITTYBUZZ_SRC`` naming a BittyBuzz checkout (the directory that
holds ``src/bittybuzz/bbzvm.c``), the library is compiled with ``gcc -O2`` into a temporary
directory together with ``bbz_c_rate.c`` (our harness) and a ``config.h`` written from the
profile, and run on the same ``.bbo``; C and ours run alternately, ``ROUNDS`` times, and the
best rate of each is compared. The library counts no instructions, so the C rate is its
steps/s times the instructions per step our VM counts on the same script. x86-64 C objects
are 9 bytes, so the C heap is the profile's scaled to hold as many objects (the same
collections, none running out of memory). Without the checkout the figures measured for issue
20 (:data:`CITED_C_RATES`) are printed as the anchor instead.

    PYTHONPATH=. python benchmarks/vm_bench.py [seconds per run, default 2]
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

from bbzide.compiler import bbzfloat, bittybuzz_string_table, compile_file
from bbzide.vm import neighbors
from bbzide.vm.profiles import PROFILES, Profile
from bbzide.vm.vm import VM, State

HERE = Path(__file__).resolve().parent
#: the environment variable naming the user's BittyBuzz checkout
SOURCE_VARIABLE = "BBZIDE_BITTYBUZZ_SRC"
#: C -O2 instructions/s measured on 2026-11-24 on this project's 2-core machine (load ~1),
#: the C BittyBuzz library built with -O2 in a harness that only counts instructions, on the
#: issue's versions of these scripts (issue 20's table; low-high of its runs)
CITED_C_RATES: dict[str, tuple[float, float]] = {
    "vm_loop.bzz": (2.0e6, 2.6e6),
    "vm_neighbors.bzz": (0.95e6, 0.95e6),
    "kilobot_gradient.bzz": (0.93e6, 1.08e6),
    "kilobot_foreach.bzz": (0.92e6, 0.95e6),
    "crazyflie_avoid.bzz": (0.87e6, 0.93e6),
}
#: the goal of issue 20: every script at least as fast as the C -O2 build
GOAL_RATIO = 1.0
#: alternate runs of C and ours per script: the best of two rounds takes out a burst of
#: another job on the shared machine without making `make bench` long
ROUNDS = 2
#: steps between two readings of the CPU clock, here and in bbz_c_rate.c: reading it costs
#: a system call (milliseconds on a loaded machine), not to be counted as VM time
CLOCK_EVERY = 64
#: bytes of a C object on x86-64 (1 metadata byte + an 8-byte pointer)
C_OBJECT_SIZE = 9


@dataclass(frozen=True)
class Case:
    """One benchmark script: its profile, neighbours seen and host functions called."""

    script: str
    profile: str
    neighbours: int
    hosts: tuple[str, ...] = ()


CASES = [
    Case("vm_loop.bzz", "pc", 0),
    Case("vm_neighbors.bzz", "kilobot", 15),
    Case("kilobot_gradient.bzz", "kilobot", 15, ("led",)),
    Case("kilobot_foreach.bzz", "kilobot", 15, ("motion",)),
    Case("crazyflie_avoid.bzz", "crazyflie", 10, ("velocity",)),
]


def _load(case: Case) -> tuple[bytes, list[str]]:
    # the BittyBuzz string table: library names at their firmware ids, then the host names
    table = bittybuzz_string_table(list(case.hosts))
    program = compile_file(HERE / case.script, string_table=table).to_bbo()
    return program.bbo, program.strings


def add_neighbors(vm: VM, count: int) -> None:
    """``count`` neighbors at 10, 20, ... cm (bbzfloat bits or u8, as the build stores);
    ``bbz_c_rate.c`` adds the same."""
    for rid in range(1, count + 1):
        values = (10.0 * rid, 3.0 * rid, 0.0)
        if vm.profile.neighbors_floats:
            d, a, e = (bbzfloat.from_float(v) for v in values)
        else:
            d, a, e = (min(255, round(v)) for v in values)
        neighbors.add(vm, neighbors.NeighborEntry(rid, d, a, e))


def _host_return(vm: VM) -> None:
    vm.ret0()


def ours(case: Case, stress_gc: bool, seconds: float) -> tuple[float, float] | str:
    """(instructions/s, instructions per step) of our VM, or a reason it cannot run."""
    bbo, strings = _load(case)
    vm = VM(PROFILES[case.profile], stress_gc=stress_gc)
    vm.construct()
    vm.set_bcode(bbo)
    for name in case.hosts:
        vm.function_register(strings.index(name), name, _host_return)
    vm.run(max_instructions=1_000_000)
    if vm.state == State.ERROR:
        return f"top level: {vm.error.name}"
    vm.state = State.READY
    add_neighbors(vm, case.neighbours)
    step_sid = strings.index("step")
    steps = 0
    start_instr = vm.instructions_executed
    t0 = time.process_time()
    spent = 0.0
    while spent < seconds:
        vm.push_nil()  # self: bbzvm_function_call consumes the entry below the closure
        vm.function_call(step_sid, 0)
        if vm.state == State.ERROR:
            return f"step: {vm.error.name} at pc {vm.pc}"
        vm.pop()
        steps += 1
        if steps % CLOCK_EVERY == 0:
            spent = time.process_time() - t0
    dt = time.process_time() - t0
    done = vm.instructions_executed - start_instr
    return done / dt, done / steps


def library_dir() -> Path | None:
    """``src/bittybuzz`` of the checkout named by ``BBZIDE_BITTYBUZZ_SRC``, if usable."""
    root = os.environ.get(SOURCE_VARIABLE)
    if not root:
        return None
    for candidate in (Path(root) / "src" / "bittybuzz", Path(root) / "bittybuzz", Path(root)):
        if (candidate / "bbzvm.c").is_file() and (candidate / "config.h.in").is_file():
            return candidate
    return None


def _config_h(p: Profile) -> str:
    """``config.h`` of BittyBuzz's CMake configure step, for profile ``p`` on x86-64."""
    heap = p.heap_size * C_OBJECT_SIZE // p.obj_size
    values = {
        "BBZHEAP_SIZE": heap, "BBZHEAP_ELEMS_PER_TSEG": p.elems_per_tseg,
        "BBZSTACK_SIZE": p.stack_size, "BBZHEAP_RSV_ACTREC_MAX": f"(uint16_t){p.rsv_actrec}",
        "BBZVSTIG_CAP": p.vstig_cap, "BBZNEIGHBORS_CAP": p.neighbors_cap,
        "BBZINMSG_QUEUE_CAP": p.in_queue_cap, "BBZOUTMSG_QUEUE_CAP": p.out_queue_cap,
        "BBZLAMPORT_THRESHOLD": p.lamport_threshold, "BBZHEAP_GCMARK_DEPTH": p.gcmark_depth,
        "BBZMSG_IN_PROC_MAX": p.msg_in_proc_max,
        "BBZNEIGHBORS_CLR_PERIOD": p.neighbors_clr_period,
        "BBZNEIGHBORS_MARK_TIME": p.neighbors_mark_time,
    }
    flags = {"BBZ_XTREME_MEMORY": p.xtreme, "BBZ_NEIGHBORS_USE_FLOATS": p.neighbors_floats,
             "BBZ_ENABLE_FLOAT_OPERATIONS": p.float_ops,
             "BBZ_BYTEWISE_ASSIGNMENT": p.bytewise_assignment,
             "BBZ_DISABLE_SWARMLIST_BROADCASTS": True}  # CMake's default (ON)
    lines = ["#ifndef CONFIG_H", "#define CONFIG_H"]
    lines += [f"#define {name} {value}" for name, value in values.items()]
    lines += [f"#define {name}" for name, on in flags.items() if on]
    return "\n".join([*lines, "#endif", ""])


class CHarness:
    """``bbz_c_rate.c`` built against the user's library, one binary per profile."""

    def __init__(self, library: Path) -> None:
        self.library = library
        self.workdir = Path(tempfile.mkdtemp(prefix="bbzide-c-rate-"))
        self.binaries: dict[str, Path] = {}

    def binary(self, p: Profile) -> Path:
        if p.name not in self.binaries:
            build = self.workdir / p.name
            (build / "bittybuzz").mkdir(parents=True)
            (build / "bittybuzz" / "config.h").write_text(_config_h(p))
            sources = sorted(str(c) for c in self.library.glob("*.c"))
            out = build / "bbz_c_rate"
            # the library's directory's parent, so that "bittybuzz/x.h" finds its headers
            # (our config.h first); -w: the library's own warnings are not ours to show
            subprocess.run(["gcc", "-O2", "-w", "-I", str(build), "-I",
                            str(self.library.parent), str(HERE / "bbz_c_rate.c"), *sources,
                            "-o", str(out), "-lm"], check=True, capture_output=True)
            self.binaries[p.name] = out
        return self.binaries[p.name]

    def steps_per_second(self, case: Case, seconds: float) -> float | str:
        """The C library's control steps per CPU second, or its one-line failure."""
        bbo, strings = _load(case)
        program = self.workdir / (Path(case.script).stem + ".bbo")
        program.write_bytes(bbo)
        args = [str(self.binary(PROFILES[case.profile])), str(program),
                str(strings.index("step")), str(case.neighbours), str(seconds)]
        args += [str(strings.index(name)) for name in case.hosts]
        done = subprocess.run(args, capture_output=True, text=True)
        words = done.stdout.split()
        if done.returncode != 0 or len(words) != 4:
            return (done.stdout or done.stderr).strip() or f"exit {done.returncode}"
        return int(words[1]) / float(words[3])

    def close(self) -> None:
        shutil.rmtree(self.workdir, ignore_errors=True)


def _load_line(when: str) -> str:
    return f"load average {when} (1, 5, 15 min): " + ", ".join(
        f"{x:.2f}" for x in os.getloadavg())


def main() -> None:
    seconds = float(sys.argv[1]) if len(sys.argv) > 1 else 2.0
    print(_load_line("before"))
    started = time.perf_counter()
    ours(CASES[1], False, 0.05)  # compiles (or loads) numba's kernels
    print(f"warm-up (numba compile or cache load): {time.perf_counter() - started:.1f} s")
    library = library_dir()
    harness = None
    if library is not None and shutil.which("gcc"):
        harness = CHarness(library)
        print(f"C: {library} built with gcc -O2, run alternately with ours, best of {ROUNDS}")
    else:
        print(f"C: {SOURCE_VARIABLE} unset (or no gcc): C figures are issue 20's, measured on "
              "2026-11-24 (C BittyBuzz -O2, a harness counting instructions, load ~1)")
    print(f"{'script':21s} {'profile':9s} {'instr/step':>10s} {'C instr/s':>13s} "
          f"{'ours instr/s':>12s} {'stress':>9s} {'vs C':>6s} {'goal':>6s}")
    cpu0 = time.process_time()
    try:
        for case in CASES:
            best_c: float | str = 0.0
            best_ours: float | str = 0.0
            per_step = 0.0
            for _ in range(ROUNDS):  # ours, then C with ours' instructions per step
                result = ours(case, False, seconds)
                if isinstance(result, str):
                    best_ours = result
                    break
                best_ours = max(float(best_ours), result[0])
                per_step = result[1]
                if harness is not None and not isinstance(best_c, str):
                    c_steps = harness.steps_per_second(case, seconds)
                    best_c = c_steps if isinstance(c_steps, str) else \
                        max(best_c, c_steps * per_step)
            if isinstance(best_ours, str):
                print(f"{case.script:21s} {case.profile:9s} skipped ({best_ours})")
                continue
            stress = ours(case, True, seconds / 4)  # ~20x slower: a shorter window
            stress_text = f"{stress[0]:9,.0f}" if not isinstance(stress, str) else "error"
            if harness is None:
                low, high = CITED_C_RATES[case.script]
                c_text = f"{low / 1e6:.2f}-{high / 1e6:.2f} M"
                ratio = f"{best_ours / high:.2f}-{best_ours / low:.2f}x"
            elif isinstance(best_c, str):
                c_text, ratio = "C failed", best_c
            else:
                c_text, ratio = f"{best_c:13,.0f}", f"{best_ours / best_c:5.2f}x"
            print(f"{case.script:21s} {case.profile:9s} {per_step:10,.0f} {c_text:>13s} "
                  f"{best_ours:12,.0f} {stress_text:>9s} {ratio:>6s} >={GOAL_RATIO:.1f}x")
    finally:
        if harness is not None:
            harness.close()
    print(f"CPU time of this process: {time.process_time() - cpu0:.1f} s (C runs in a child "
          "process, its CPU time is its own clock())")
    print(_load_line("after"))


if __name__ == "__main__":
    main()
