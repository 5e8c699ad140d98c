"""Step-time estimates: what a control step would cost on a robot's microcontroller.

Design: the model knows exactly what a step does — instructions executed, collections run (the
reference VM collects before every instruction and before each incoming message, so a step runs
about as many collections as instructions), the object slots each collection walks (the heap's
rtobj at that moment) and the messages processed. A platform's `CostModel` turns these counts
into cycles with a linear law

    cycles = per_step + per_instruction * I + per_gc_slot * (G * S) + per_message * M

(G collections over S object slots on average), then into milliseconds through the clock.

The Kilobot's coefficients (ATmega328P, 8 MHz) are fitted to cycle counts measured on the
reference VM built for that chip and run cycle-exactly in simavr, on the same scripts and the
same incoming messages as the model (benchmarks/steptime/: the measured CSV, the Buzz scripts,
`fit.py` that refits them and reports the held-out error, and README.md with the method).
The Crazyflie's (STM32F405, Cortex-M4 at 168 MHz) are not measured: they are the Kilobot's
cycles scaled by `CORTEX_M4_CYCLE_RATIO`, an argument from instruction width (see there), so
its estimate carries a band of a factor two either way (`low`/`high`).
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class StepCounts:
    """What one control step of one robot did (exact, from the VM model)."""

    instructions: int
    gc_runs: int
    gc_slots: float          # sum over the step's collections of the object slots walked
    messages: int            # incoming messages processed (at most msg_in_proc_max)


@dataclass(frozen=True)
class CostModel:
    """Cycles per counted event on one platform, and its clock."""

    platform: str
    clock_hz: float
    per_step: float
    per_instruction: float
    per_gc_slot: float
    per_message: float
    #: multiplicative uncertainty of the estimate (1.0: measured; 2.0: "within a factor 2")
    uncertainty: float
    source: str

    def cycles(self, counts: StepCounts) -> float:
        return (self.per_step + self.per_instruction * counts.instructions
                + self.per_gc_slot * counts.gc_slots + self.per_message * counts.messages)

    def milliseconds(self, counts: StepCounts) -> float:
        return 1000.0 * self.cycles(counts) / self.clock_hz


#: Kilobot: least-squares fit (benchmarks/steptime/fit.py) to the cycles measured in simavr on
#: the training scripts of benchmarks/steptime/kilobot_cycles.csv; fit.py prints these numbers
#: and the held-out error, and tests/vm/test_steptime.py checks that they still agree. Held out
#: of the fit, three scripts' mean step is predicted within 9 % (-8.7, -1.3, +6.7 %), every
#: single step within 10 %. The collector dominates: ~128 cycles per object slot walked, and
#: it runs before every instruction (a step of 50 instructions over 100 slots: ~0.8 M cycles,
#: ~100 ms at 8 MHz).
KILOBOT = CostModel(
    platform="kilobot", clock_hz=8_000_000, per_step=70043.0, per_instruction=5936.6,
    per_gc_slot=127.6, per_message=19874.7, uncertainty=1.0,
    source="measured: reference VM on an ATmega328P in simavr (benchmarks/steptime)")

#: Cortex-M4 cycles per ATmega328P cycle for the same VM code. The VM's hot loops (the
#: collector's walk over object slots, the instruction dispatch) handle 16-bit heap indices
#: and 8-bit flags: an 8-bit AVR needs two instructions per 16-bit operation and 2-cycle
#: loads, where the M4 does one single-cycle instruction, so about 1/2 to 1/4 of the cycles;
#: flash wait states at 168 MHz (5, mostly hidden by the ART cache) push it back toward 1/2.
#: 1/3 is the middle; the band is a factor 2 either way (`uncertainty`).
CORTEX_M4_CYCLE_RATIO = 1 / 3


def scaled(base: CostModel, platform: str, clock_hz: float, ratio: float,
           uncertainty: float, source: str) -> CostModel:
    """`base`'s cycle costs times `ratio`, at another clock."""
    return CostModel(platform=platform, clock_hz=clock_hz, per_step=base.per_step * ratio,
                     per_instruction=base.per_instruction * ratio,
                     per_gc_slot=base.per_gc_slot * ratio,
                     per_message=base.per_message * ratio, uncertainty=uncertainty,
                     source=source)


CRAZYFLIE = scaled(
    KILOBOT, "crazyflie", 168_000_000, CORTEX_M4_CYCLE_RATIO, 2.0,
    "not measured: the Kilobot's cycles x 1/3 (Cortex-M4 against 8-bit AVR), at 168 MHz")

COST_MODELS: dict[str, CostModel] = {m.platform: m for m in (KILOBOT, CRAZYFLIE)}


def cost_model(platform: str) -> CostModel | None:
    """The cost model of a platform profile, or None when it has none (e.g. m300, pc)."""
    return COST_MODELS.get(platform)
