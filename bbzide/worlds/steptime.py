"""Step-time estimates of a swarm run: how long each control step would take on the robots.

Design: `StepTimeMeter` reads, after every step of a `Simulation`, each robot's exact counters
from its VM (instructions executed, collections run, the heap's object slots) and the messages
it received that step, and keeps one `StepCounts` per robot-step. The platform cost models of
`bbzide.vm.steptime` turn them into milliseconds; `report` prints min / mean / max per platform
(every platform with a cost model, not only the world's: "what would this step cost on a
Kilobot") beside the world's control period, which an estimate above it would overrun.
Robots whose firmware loop is not the VM model (test doubles) are skipped.
"""

from __future__ import annotations

import statistics
from typing import TYPE_CHECKING, Any

from bbzide.vm.steptime import COST_MODELS, CostModel, StepCounts

if TYPE_CHECKING:
    from bbzide.worlds.engine import Simulation


class StepTimeMeter:
    """Counts of every robot-step of a simulation, sampled by `step()` in place of sim.step()."""

    def __init__(self, sim: Simulation) -> None:
        self.sim = sim
        self.counts: list[StepCounts] = []
        self._last = [self._counters(state) for state in sim.robots]

    @staticmethod
    def _counters(state: Any) -> tuple[int, int, int] | None:
        vm = getattr(getattr(state, "robot", None), "vm", None)
        if vm is None:
            return None
        heap = vm.heap
        return vm.instructions_executed, heap.gc_runs, heap.rtobj // heap.obj_size

    def step(self) -> None:
        sim = self.sim
        limit = {}
        stats = sim.step()
        for i, state in enumerate(sim.robots):
            now = self._counters(state)
            before = self._last[i]
            self._last[i] = now
            if now is None or before is None or state.failure is not None:
                continue
            instructions = now[0] - before[0]
            collections = now[1] - before[1]
            if instructions == 0 and collections == 0:
                continue            # asleep or not stepped
            profile = state.robot.profile
            cap = limit.setdefault(id(profile), profile.msg_in_proc_max)
            self.counts.append(StepCounts(
                instructions=instructions, gc_runs=collections,
                # The slots each collection walks lie between the step's first and last rtobj.
                gc_slots=collections * (before[2] + now[2]) / 2,
                messages=min(int(stats.received[i]), cap)))

    def run(self, steps: int) -> None:
        for _ in range(steps):
            self.step()

    def milliseconds(self, model: CostModel) -> list[float]:
        return [model.milliseconds(c) for c in self.counts]


def summary_rows(meter: StepTimeMeter) -> list[dict[str, Any]]:
    """One row per platform with a cost model: min / mean / sd / max estimated ms per step."""
    rows = []
    for model in COST_MODELS.values():
        times = meter.milliseconds(model)
        if not times:
            continue
        rows.append({"platform": model.platform, "steps": len(times), "min": min(times),
                     "mean": statistics.fmean(times),
                     "sd": statistics.pstdev(times) if len(times) > 1 else 0.0,
                     "max": max(times), "uncertainty": model.uncertainty,
                     "source": model.source})
    return rows


def report(meter: StepTimeMeter) -> str:
    """The table `bbzide run --steptime` prints."""
    rows = summary_rows(meter)
    if not rows:
        return "step time: no robot-step of the VM model was run"
    period_ms = meter.sim.world.step_seconds * 1000
    counts = meter.counts
    lines = [f"estimated step time per platform ({len(counts)} robot-steps; mean per step: "
             f"{statistics.fmean(c.instructions for c in counts):.0f} instructions, "
             f"{statistics.fmean(c.gc_runs for c in counts):.0f} collections, "
             f"{statistics.fmean(c.messages for c in counts):.1f} messages)",
             f"{'platform':<10} {'min ms':>9} {'mean ms':>9} {'sd':>8} {'max ms':>9}  basis"]
    for row in rows:
        band = ("" if row["uncertainty"] == 1.0
                else f" (x{row['uncertainty']:g} either way)")
        lines.append(f"{row['platform']:<10} {row['min']:>9.2f} {row['mean']:>9.2f} "
                     f"{row['sd']:>8.2f} {row['max']:>9.2f}  {row['source']}{band}")
    lines.append(f"this world's control period: {period_ms:g} ms")
    return "\n".join(lines)
