"""What the IDE needs from a running world, as two small interfaces.

The IDE never touches the worlds room's classes directly outside `world_adapter.py`; everything
else (run controller, scene, inspector) works with `WorldBackend` / `SimulationHandle` and the
plain-array `SwarmFrame`. This keeps one place to follow the engine's API and lets the browser
tests of the UI *mechanics* use a small double where a real swarm is not the point.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Protocol

import numpy as np

from bbzide.ui.inspection import RobotInspection


@dataclass
class SwarmFrame:
    """Everything the scene draws for one simulation step, as arrays indexed by robot."""

    step: int
    positions: np.ndarray  # (N, 2) float, metres, world frame (x right, y up)
    headings: np.ndarray  # (N,) float, radians, 0 = +x, counter-clockwise
    led_colors: np.ndarray  # (N, 3) float in 0..1
    failed: np.ndarray  # (N,) bool: the robot's VM stopped with an error
    links: np.ndarray = field(default_factory=lambda: np.zeros((0, 2), dtype=np.int32))  # (M, 2)
    robot_ids: list[int] = field(default_factory=list)  # Buzz `id` of each robot
    roles: list[str] = field(default_factory=list)  # each robot's role, where the world has some

    @property
    def count(self) -> int:
        return int(self.positions.shape[0])


@dataclass(frozen=True)
class WorldGeometry:
    """Static facts for drawing a world: robot size, radio range and the lines of its overlay."""

    robot_radius: float  # metres (Kilobot: 0.0165)
    comm_range: float  # metres
    bounds: tuple[float, float, float, float]  # xmin, ymin, xmax, ymax
    overlay_segments: np.ndarray  # (K, 2, 2) walls, zones, ... in metres
    height: float = 0.0  # z of the robots (drones fly)


class SimulationHandle(Protocol):
    """One running swarm. Called only from the run controller's thread (or under its lock)."""

    def step(self) -> None: ...
    def frame(self) -> SwarmFrame: ...
    def geometry(self) -> WorldGeometry: ...
    def robot(self, index: int) -> Any: ...  # a bbzide.vm.robot.Robot
    def inspect(self, index: int) -> RobotInspection: ...  # memory and state of one robot
    def load_program(self, program: Any, keep_state: bool) -> None: ...
    @property
    def step_count(self) -> int: ...


class WorldBackend(Protocol):
    """The worlds the IDE can open, and how to start a swarm in one."""

    def world_names(self) -> list[str]: ...
    def default_world(self) -> str: ...
    def default_robots(self, world: str) -> int: ...
    def example_path(self, world: str) -> Path | None: ...
    def compile(self, text: str, path: Path, world: str) -> tuple[Any, Any]: ...
    def platform(self, world: str) -> Any: ...  # a bbzide.vm.profiles.Profile
    def create(self, world: str, program: Any, robots: int, seed: int) -> SimulationHandle: ...
    # optional keyword `scenario`: a bbzide.worlds.scenario.Scenario pinning world options,
    # positions and labels (WorldsBackend takes it; the run controller passes it only when set)
