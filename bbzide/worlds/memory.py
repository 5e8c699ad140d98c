"""How much RAM a script needs on a platform (`bbzide memory SCRIPT --platform P`, whose
command line is in bbzide/worlds/commands.py): how much RAM a script needs on a platform (thesis
Table 4.2: the memory footprint of three BittyBuzz scripts on the Crazyflie).

Design: the script runs as a swarm in the platform's world (or in `--world W` with the
platform's profile), for `--steps` control steps, on the byte-faithful heap and stack model.
Three figures come out of it, each over every robot of the run:
  * the heap's peak use at the platform's heap size: the high-water mark of the heap's two
    pointers (objects from the bottom, table segments from the top), as the firmware's
    `bbzheap` would reach it; it includes garbage that a collection had not yet reclaimed;
  * the smallest heap the run needs: the least heap size (bytes) at which no robot fails in
    those steps, found by bisection (one run per probe: the run is deterministic for a seed,
    and a larger heap never makes a script fail that ran in a smaller one);
  * the smallest stack it needs, in entries of 2 bytes (u16 heap indices), by the same
    bisection on the stack size.
The RAM a script needs is the smallest heap plus the smallest stack in bytes: what a build of
the platform must reserve for this script beyond the VM's fixed structures (queues, neighbor
ring, registers). A script that fails at the platform's own sizes is reported as such. The
bytecode's size (the .bbo the robot's flash holds) is reported too: the thesis' Table 4.2 is
that figure (§4.6: "the memory occupied by a user defined behavior ... 2.48 kB (0.33 % of
the remaining available space)", the 740 KB of flash left for bytecode).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from bbzide.diagnostics import UserError

#: Steps when --steps is not given: 30 s of Crazyflie time (50 ms steps), long enough for the
#: thesis' scripts to reach their steady state (exploration legs of 2 s, consensus in < 1 s).
DEFAULT_STEPS = 600
#: Bytes per stack entry: BittyBuzz's stack holds u16 heap indices.
STACK_ENTRY_BYTES = 2


@dataclass(frozen=True)
class MemoryReport:
    """What `bbzide memory` measured (bytes unless said otherwise)."""

    script: str
    platform: str
    world: str
    robots: int
    steps: int
    seed: int
    heap_size: int          # the platform's heap
    stack_size: int         # the platform's stack, entries
    peak_heap: int          # heap high-water mark at the platform's heap size, worst robot
    min_heap: int           # smallest heap with no robot failing
    min_stack: int          # smallest stack (entries) with no robot failing
    bytecode: int           # bytes of the compiled .bbo (flash)

    @property
    def ram_bytes(self) -> int:
        return self.min_heap + STACK_ENTRY_BYTES * self.min_stack

    def text(self) -> str:
        return "\n".join([
            f"{self.script} on {self.platform} (heap {self.heap_size} B, stack "
            f"{self.stack_size} entries): {self.world} world, {self.robots} robot(s), "
            f"{self.steps} steps, seed {self.seed}",
            f"  heap: peak use {self.peak_heap} B (worst robot); runs in {self.min_heap} B "
            f"at least",
            f"  stack: {self.min_stack} entries at least ({STACK_ENTRY_BYTES * self.min_stack} B)",
            f"  RAM the script needs: {self.ram_bytes} B = {self.ram_bytes / 1000:.3f} kB "
            f"(smallest heap + smallest stack)",
            f"  bytecode (flash): {self.bytecode} B",
        ])


def _first_failure(sim: Any) -> str | None:
    failures = sim.failures
    if not failures:
        return None
    f = failures[0].failure
    return f"robot {failures[0].robot_id}: {getattr(f, 'reason', f)} ({getattr(f, 'message', '')})"


def measure(script: Path, program: Any, world: str, platform: str, robots: int, steps: int,
            seed: int, world_options: dict[str, Any] | None = None) -> MemoryReport:
    """Run `program` and bisect the heap and stack sizes (see the module docstring)."""
    from bbzide.vm.profiles import PROFILES
    from bbzide.worlds.engine import RobotGroup, Simulation

    base = PROFILES[platform]
    options = dict(world_options or {})

    def run(profile: Any) -> tuple[str | None, int]:
        sim = Simulation(world, None, seed=seed, world_options=options,
                         groups=[RobotGroup(robots, program, profile)])
        for _ in range(steps):
            sim.step()
            if sim.failures:
                break
        peak = max((state.robot.vm.heap.peak_used for state in sim.robots
                    if state.robot is not None), default=0)
        return _first_failure(sim), peak

    failure, peak = run(base)
    if failure is not None:
        raise UserError(f"{script} fails on {platform} with its own heap and stack within "
                        f"{steps} steps: {failure}")

    def smallest(low: int, high: int, fits: Callable[[int], bool]) -> int:
        """The least n in (low, high] with fits(n), given fits(high) and not fits(low)."""
        while high - low > 1:
            middle = (low + high) // 2
            if fits(middle):
                high = middle
            else:
                low = middle
        return high

    def heap_fits(n: int) -> bool:
        return run(dataclasses.replace(base, heap_size=n))[0] is None

    objects_reserved = base.rsv_actrec * base.obj_size   # the heap's fixed bottom part
    # The peak is usually enough (the collector runs every step, so little garbage is ever
    # counted in it): one probe there narrows the search to below it.
    high = peak if objects_reserved < peak < base.heap_size and heap_fits(peak) else base.heap_size
    min_heap = smallest(objects_reserved, high, heap_fits)
    min_stack = smallest(0, base.stack_size, lambda n: run(
        dataclasses.replace(base, stack_size=n))[0] is None)
    return MemoryReport(str(script), platform, world, robots, steps, seed, base.heap_size,
                        base.stack_size, peak, min_heap, min_stack, len(program.bbo))
