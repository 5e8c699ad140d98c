"""RAM of the Crazyflie scripts beside the thesis' Table 4.2 (memory footprint of three
BittyBuzz scripts: exploration 2.48 KB, virtual stigmergy 0.732 KB, neighbors broadcast
0.396 KB).

Runs `bbzide memory` (bbzide/worlds/memory.py) on our equivalents, on the Crazyflie profile in
the Crazyflie world: examples/crazyflie/exploration.bzz (2 drones, the Fig. 4.9 run),
consensus.bzz (10 drones, §4.6.2) and packet_loss.bzz (10 drones, §4.6.1), 600 steps (30 s)
each, and prints a markdown table: bytecode size, peak heap use, smallest heap, smallest stack,
and their sum (the RAM the script needs) beside the paper's figure. The paper's figures are
the flash its scripts occupy (§4.6: 2.48 kB is "0.33 % of the remaining available space", the
740 KB of flash left for bytecode), so they compare with our bytecode column; the RAM columns
answer what the paper leaves open.

    PYTHONPATH=. python experiments/crazyflie_memory.py [steps, default 600]
"""

from __future__ import annotations

import sys
from pathlib import Path

from common import REPO, compile_example, run_script, table

from bbzide.worlds.memory import DEFAULT_STEPS, STACK_ENTRY_BYTES, measure

#: (name in Table 4.2, our example, drones, the paper's figure in KB)
SCRIPTS = (
    ("Exploration", "examples/crazyflie/exploration.bzz", 2, 2.48),
    ("VS", "examples/crazyflie/consensus.bzz", 10, 0.732),
    ("Neighbors broadcast", "examples/crazyflie/packet_loss.bzz", 10, 0.396),
)


def main() -> None:
    steps = int(sys.argv[1]) if len(sys.argv) > 1 else DEFAULT_STEPS
    rows = []
    for name, example, drones, paper in SCRIPTS:
        program = compile_example("crazyflie", example)
        report = measure(Path(example), program, "crazyflie", "crazyflie", drones, steps, 0)
        rows.append((name, f"`{Path(example).name}`", drones, f"{paper:g}",
                     report.bytecode, report.peak_heap, report.min_heap,
                     f"{report.min_stack} ({STACK_ENTRY_BYTES * report.min_stack} B)",
                     f"{report.ram_bytes / 1000:.3f}"))
    print(table(("Table 4.2", "our script", "drones", "paper (KB)", "bytecode (B)",
                 "peak heap (B)",
                 "smallest heap (B)", "smallest stack (entries)", "heap + stack (kB)"),
                rows))
    print(f"\n{steps} steps each, seed 0, Crazyflie profile (heap 3500 B, stack 128 entries); "
          f"run from {REPO}")


if __name__ == "__main__":
    run_script(main)
