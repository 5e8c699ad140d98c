"""M300 drones in both VM modes, for the tests of the host functions the compiled swarm step
runs in place (readings, latched stores, drawn results): the same field run once with every
drone in the reference mode (``stress_gc``: every host function called in Python) and once
in the fast mode, compared after every step."""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from pathlib import Path
from typing import Any

from bbzide.vm.robot import Robot
from bbzide.worlds.commands import load_script
from bbzide.worlds.engine import Simulation
from bbzide.worlds.registry import WORLDS

#: targets in a grid over the launch strip, so that cameras see some and miss others
TARGETS = [(x, y) for x in (0.5, 2.5, 4.5) for y in range(1, 12, 3)]
#: a low flight (1.5 m: 15 steps of climb), so that drones arrive within the run
OPTIONS = {"size": 12.0, "targets": TARGETS, "altitude": 1.5}
#: a small heap, which a script can fill in a few steps (the M300's 60 kB would take the
#: reference mode, a collection before every instruction, minutes)
HEAP_SIZE = 6000


def factory(stress: bool) -> Callable[..., Robot]:
    """Robots of HEAP_SIZE bytes in the reference (``stress``) or the fast mode."""
    def build(program: Any, profile: Any, robot_id: int, host_functions: Any) -> Robot:
        return Robot(program, dataclasses.replace(profile, heap_size=HEAP_SIZE), robot_id,
                     host_functions=host_functions, instruction_budget=100_000,
                     stress_gc=stress)

    return build


def compile_script(tmp_path: Path, text: str) -> Any:
    path = tmp_path / "script.bzz"
    path.write_text(text)
    return load_script(path, WORLDS["m300"].host_names, [])


def field(program: Any, robots: int, stress: bool) -> Simulation:
    """The test field with `robots` drones of one mode."""
    return Simulation("m300", program, robots=robots, seed=4, world_options=OPTIONS,
                      robot_factory=factory(stress), watch=())


def run_both(program: Any, steps: int, robots: int,
             world_state: Callable[[Simulation], tuple]) -> list[Simulation]:
    """The field in both modes, stepped together: after every step the same world state
    (`world_state`), and each drone's VM state and failure the same. Returns (reference,
    fast)."""
    sims = [field(program, robots, stress) for stress in (True, False)]
    for step in range(steps):
        for sim in sims:
            sim.step()
        reference, fast = sims
        assert world_state(reference) == world_state(fast), step
        for a, b in zip(reference.robots, fast.robots, strict=True):
            assert Robot.comparable(a.robot.snapshot()) == Robot.comparable(b.robot.snapshot()), \
                (step, a.index)
            assert str(a.robot.failure) == str(b.robot.failure), (step, a.index)
    return sims
