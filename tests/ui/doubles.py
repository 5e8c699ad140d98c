"""A small in-test world for the UI *mechanics* tests (controls, editor round trips, threads).

It is not a Buzz implementation: `FakeBackend.compile` accepts any text whose braces balance and
that has no line containing `@@` (reported as a CompileError at that line and column), and the
"robots" drive in circles with an LED colour chosen by the program text. The real-stack tests
use the real compiler, VM and worlds instead.
"""

from __future__ import annotations

import math
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from bbzide.diagnostics import CompileError, SourceLocation
from bbzide.ui.inspection import HeapBlock, RobotInspection
from bbzide.ui.world_backend import SwarmFrame, WorldGeometry

#: the longest a released stuck step waits for its event: a test that forgets it fails, not hangs
STUCK_LIMIT_SECONDS = 30.0


@dataclass
class FakeProgram:
    text: str
    bbo: bytes
    strings: list[str] = field(default_factory=list)
    warnings: list[str] = field(default_factory=list)
    #: when set, a "while(1)" step lasts until the test sets this event (instead of 1.5 s)
    release: threading.Event | None = None


@dataclass
class FakeCompiled:
    bo: bytes
    basm: str
    warnings: list[str] = field(default_factory=list)


@dataclass(frozen=True)
class FakePlatform:
    name: str = "fakebot"
    flash_budget: int = 4096


class FakeSimulation:
    def __init__(self, program: FakeProgram, robots: int, seed: int) -> None:
        self.program = program
        self.count = robots
        rng = np.random.default_rng(seed)
        self.positions = rng.uniform(-0.4, 0.4, size=(robots, 2))
        self.headings = rng.uniform(-math.pi, math.pi, size=robots)
        self.step_count = 0

    def step(self) -> None:
        if "while(1)" in self.program.text.replace(" ", ""):
            if self.program.release is not None:
                self.program.release.wait(STUCK_LIMIT_SECONDS)
            else:
                time.sleep(1.5)  # what a script stuck in a loop feels like to the run thread
        self.headings += 0.05
        self.positions += 0.002 * np.stack([np.cos(self.headings), np.sin(self.headings)], axis=1)
        self.step_count += 1

    def frame(self) -> SwarmFrame:
        red = 1.0 if "red" in self.program.text else 0.0
        colors = np.tile([red, 0.0 if red else 0.8, 0.2], (self.count, 1))
        links = np.array([[i, i + 1] for i in range(self.count - 1)], dtype=np.int32).reshape(-1, 2)
        return SwarmFrame(
            self.step_count,
            self.positions.copy(),
            self.headings.copy(),
            colors,
            np.zeros(self.count, dtype=bool),
            links,
            list(range(self.count)),
        )

    def geometry(self) -> WorldGeometry:
        walls = np.array(
            [
                [[-0.5, -0.5], [0.5, -0.5]],
                [[0.5, -0.5], [0.5, 0.5]],
                [[0.5, 0.5], [-0.5, 0.5]],
                [[-0.5, 0.5], [-0.5, -0.5]],
            ]
        )
        return WorldGeometry(0.0165, 0.1, (-0.5, -0.5, 0.5, 0.5), walls)

    def robot(self, index: int) -> object:
        return None

    def load_program(self, program: FakeProgram, keep_state: bool) -> None:
        self.program = program

    def inspect(self, index: int) -> RobotInspection:
        size, rop, lsp = 1088, 300 + index * 3, 900
        blocks = [
            HeapBlock(0, 84, "actrec"),
            HeapBlock(84, rop - 84, "object", "int"),
            HeapBlock(rop, lsp - rop, "free"),
            HeapBlock(lsp, size - lsp, "segment"),
        ]
        return RobotInspection(
            index,
            index,
            self.step_count,
            "running",
            12,
            size,
            rop,
            lsp,
            84,
            blocks,
            used_bytes=size - (lsp - rop),
            free_bytes=lsp - rop,
            peak_bytes=None,
            gc_runs=None,
            ram_bytes=2048,
        )


class FakeBackend:
    def __init__(self) -> None:
        self.created: list[FakeSimulation] = []

    def world_names(self) -> list[str]:
        return ["fake-table", "fake-lab"]

    def default_world(self) -> str:
        return "fake-table"

    def default_robots(self, world: str) -> int:
        return 25

    def example_path(self, world: str) -> Path | None:
        return None

    def platform(self, world: str) -> FakePlatform:
        return FakePlatform()

    def compile(self, text: str, path: Path, world: str) -> tuple[FakeCompiled, FakeProgram]:
        depth = 0
        for number, line in enumerate(text.splitlines(), start=1):
            if "@@" in line:
                raise CompileError(
                    "unexpected '@@'", SourceLocation(str(path), number, line.index("@@"))
                )
            depth += line.count("{") - line.count("}")
        if depth != 0:
            raise CompileError("unbalanced braces", SourceLocation(str(path), 0, 1))
        body = text.encode()
        basm = "".join(f"\tnop\t|{n},0,{path}\n" for n in range(1, text.count("\n") + 2))
        return FakeCompiled(bo=body + b"\0" * 8, basm=basm), FakeProgram(text, bbo=body)

    def create(self, world: str, program: FakeProgram, robots: int, seed: int) -> FakeSimulation:
        sim = FakeSimulation(program, robots, seed)
        sim.world = world
        self.created.append(sim)
        return sim


class FrontEndBackend(FakeBackend):
    """The double world, but the text goes through the real Buzz compiler front end, so the
    editor shows the real compiler's errors without running a VM."""

    def compile(self, text: str, path: Path, world: str) -> tuple[FakeCompiled, FakeProgram]:
        from bbzide.compiler.frontend import compile_to_basm

        result = compile_to_basm(path, source=text)
        body = text.encode()
        return FakeCompiled(bo=body, basm=result.basm, warnings=list(result.warnings)), FakeProgram(
            text, bbo=body
        )
