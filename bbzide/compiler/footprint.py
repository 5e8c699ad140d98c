"""Bytecode footprint: sizes of a compiled program and whether it fits each platform's flash.

A BittyBuzz robot stores its `.bbo` in flash next to the firmware and the VM (thesis ch. 4,
§4.6, Figure 4.4), so the question a user asks before flashing is "does my bytecode fit the space
that is left?". The budgets below are the bytes left for the `.bbo`, each explained where it is
defined. Every budget is also capped by the `.bbo` format itself: addresses and `bcode_size` are
16-bit (spec §D.3, §F.1), so no `.bbo` can exceed 65,535 bytes whatever the flash.
"""

from __future__ import annotations

from dataclasses import dataclass

from bbzide.compiler.bytecode import read_bbo, read_bo
from bbzide.compiler.program import BittyBuzzProgram, CompiledProgram

KIB = 1024
#: `.bbo` addresses and `bcode_size` are uint16 (spec §D.3, §F.1): the format's own limit.
BBO_FORMAT_LIMIT = 0xFFFF
#: Smallest BBZVM build reported by the thesis (§4.2: "can be as small as 17.1 KB").
MINIMAL_VM_BYTES = round(17.1 * KIB)
#: Default (all features) BBZVM build on the Crazyflie (thesis §4.6: 19.3 kB).
DEFAULT_VM_BYTES = round(19.3 * KIB)


#: RAM of each platform's microcontroller, which the VM profiles do not carry (the heap is one
#: part of it). Kilobot: ATmega328P, 2 KB SRAM; Zooids: STM32F051C8, 8 KB SRAM; Crazyflie 2.x:
#: STM32F405RG, 192 KB SRAM (128 KB + 64 KB core-coupled). The M300's script runs on a
#: companion computer (no meaningful RAM limit) and `pc` is a desktop: no figure.
RAM_BYTES: dict[str, int] = {"kilobot": 2048, "zooids": 8192, "crazyflie": 196608}


@dataclass(frozen=True, slots=True)
class FlashBudget:
    platform: str
    bytes_for_bytecode: int
    why: str


#: Bytes of flash left for the `.bbo` on each platform.
FLASH_BUDGETS: dict[str, FlashBudget] = {
    "kilobot": FlashBudget(
        "kilobot",
        32 * KIB - 4 * KIB - MINIMAL_VM_BYTES,
        "ATmega328P 32 KB flash (thesis §4.5) - 4 KB boot section (the ATmega328P's "
        "largest, used by the Kilobot IR bootloader) - 17.1 KB smallest BBZVM "
        "(thesis §4.2); an upper bound, kilolib "
        "itself also takes flash",
    ),
    "zooids": FlashBudget(
        "zooids",
        64 * KIB - DEFAULT_VM_BYTES,
        "STM32F051C8 64 KB flash (thesis §4.5) - 19.3 KB default BBZVM (thesis §4.6); an upper "
        "bound, the Zooids firmware also takes flash",
    ),
    "crazyflie": FlashBudget(
        "crazyflie",
        min(740 * KIB, BBO_FORMAT_LIMIT),
        "thesis §4.6: 740.0 KB left after the 240.6 KB firmware and 19.3 KB BBZVM; capped by the "
        "16-bit .bbo addresses (65,535 bytes)",
    ),
    "m300": FlashBudget(
        "m300",
        BBO_FORMAT_LIMIT,
        "runs on the Manifold 2 onboard computer (thesis ch. 5), no flash limit: only the 16-bit "
        ".bbo address limit",
    ),
    "pc": FlashBudget("pc", BBO_FORMAT_LIMIT, "no flash: only the 16-bit .bbo address limit"),
}


@dataclass(frozen=True, slots=True)
class Footprint:
    bo_size: int
    bbo_size: int
    strings: int
    string_bytes: int
    instructions: int

    def fits(self, platform: str) -> bool:
        return self.bbo_size <= FLASH_BUDGETS[platform].bytes_for_bytecode

    def table(self) -> str:
        lines = [
            f".bo size      {self.bo_size:8d} bytes",
            f".bbo size     {self.bbo_size:8d} bytes",
            f"strings       {self.strings:8d} ({self.string_bytes} bytes in the .bo, "
            "ids only in the .bbo)",
            f"instructions  {self.instructions:8d}",
            "",
            f"{'platform':10s} {'budget':>8s}  {'used':>6s}  fits",
        ]
        for name, budget in FLASH_BUDGETS.items():
            used = 100.0 * self.bbo_size / budget.bytes_for_bytecode
            lines.append(
                f"{name:10s} {budget.bytes_for_bytecode:8d}  {used:5.1f}%  "
                f"{'yes' if self.fits(name) else 'NO'}"
            )
        return "\n".join(lines)


def measure(program: CompiledProgram, bbo: BittyBuzzProgram | None = None) -> Footprint:
    """Footprint of a compiled program (the `.bbo` is computed when not given)."""
    bbo = bbo or program.to_bbo()
    decoded = read_bo(program.bo)
    read_bbo(bbo.bbo)
    return Footprint(
        bo_size=len(program.bo),
        bbo_size=len(bbo.bbo),
        strings=len(decoded.strings),
        string_bytes=decoded.code_start - 2,
        instructions=len(decoded.instructions),
    )
