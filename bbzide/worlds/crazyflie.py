"""The Crazyflie lab: nano quadrotors in a 3D room with box obstacles.

Design: a drone is a point with a 46 mm radius (the 92 mm frame) and a simple flight model, the
high-level commander's: each control step the velocity is steered toward the current target
(takeoff height, `goTo` point, the hover point, the floor when landing) by a proportional law,
limited in speed and acceleration, then integrated. Walls and obstacle boxes are solid: a drone
that would enter one is pushed back to its surface and loses the velocity component into it (a
bump, counted in `labels["bumps"]`). Drones do not collide with each other (the paper's drones
keep 0.5 m apart). Everything is numpy over all drones at once.

Sensors: a multi-ranger deck (front/back/left/right in the drone's frame, up to the ceiling; 4 m
maximum, the VL53L1x's) by ray casting against walls and obstacles; a positioning deck
(`position()`, 1 cm Gaussian noise). The radio is BLE-like: the whole room is in range and the
loss grows with the sender's broadcast rate, through the paper's measurements (thesis §4.6.1:
0 % at 2 Hz, 1.55 % at 10 Hz, 1.9 % at 20 Hz, 50 ms control steps).

Host functions (ours; BittyBuzz's Crazyflie firmware registers only `led` and a no-op `delay`,
which we keep as they are): `takeoff(h)`, `land()`, `hover()`, `goTo(x, y, z)` (metres, room
frame, ignored while landed), `ranges()` -> {front, back, left, right, up}, `position()` ->
{x, y, z}, `flying()` -> 0/1, `rand()` -> 0..255, `led(c)` (bits 0/1/2 = red/green/blue).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import TYPE_CHECKING, Any

import numpy as np

from bbzide.worlds.radio import WorldConfigError
from bbzide.worlds.registry import CRAZYFLIE_HOST_NAMES
from bbzide.worlds.world import HostFunction, RadioSettings, World, segment_distances

if TYPE_CHECKING:
    from bbzide.vm.host import HostCall
    from bbzide.worlds.engine import Simulation

CRAZYFLIE_RADIUS = 0.046     # m: half of the 92 mm frame
STEP_SECONDS = 0.05          # s: the paper's control period (20 Hz)
MAX_SPEED = 1.0              # m/s horizontal: the high-level commander's usual cruise limit
MAX_CLIMB = 0.5              # m/s vertical
MAX_ACCELERATION = 2.0       # m/s^2: keeps a 27 g quadrotor well inside its thrust margin
GAIN = 2.0                   # 1/s: proportional steering toward the target (time constant 0.5 s)
RANGER_MAX = 4.0             # m: the multi-ranger's VL53L1x maximum range
POSITION_NOISE = 0.01        # m: positioning-deck noise (a Lighthouse/Loco deck in a lab)
LANDED_HEIGHT = 0.01         # m: below this a landing drone switches its motors off
#: The paper's BLE loss against the broadcast rate of a drone (Hz -> probability).
BLE_LOSS_BY_RATE = ((0.0, 0.0), (2.0, 0.0), (10.0, 0.0155), (20.0, 0.019))
#: Spacing of the initial formations: the paper's drones were 0.5 m apart.
FORMATION_SPACING = 0.5
#: Two 0.4 m square pillars, off the centre, so exploration meets obstacles.
DEFAULT_OBSTACLES = ((1.2, 0.8, 1.6, 1.2), (-1.8, -1.4, -1.4, -1.0))

LANDED, FLYING, LANDING = 0, 1, 2


class CrazyflieLab(World):
    """A room `width` x `depth` x `height` m centred on the origin (floor at z = 0)."""

    name = "crazyflie"
    profile_name = "crazyflie"
    host_names = CRAZYFLIE_HOST_NAMES
    step_seconds = STEP_SECONDS
    robot_radius = CRAZYFLIE_RADIUS
    robot_height = 0.0

    def __init__(
        self,
        width: float = 6.0,
        depth: float = 6.0,
        height: float = 3.0,
        obstacles: Sequence[Sequence[float]] = DEFAULT_OBSTACLES,
        formation: str = "grid",
        spacing: float = FORMATION_SPACING,
        comm_range: float = 10.0,
        loss_by_rate: Sequence[Sequence[float]] = BLE_LOSS_BY_RATE,
        step_seconds: float = STEP_SECONDS,
    ) -> None:
        if min(width, depth, height) <= 4 * CRAZYFLIE_RADIUS:
            raise WorldConfigError(f"a {width} x {depth} x {height} m room is too small")
        if formation not in ("grid", "chain", "circle"):
            raise WorldConfigError(f"unknown formation {formation!r}: grid, chain or circle")
        if step_seconds <= 0:
            raise WorldConfigError("the control period must be positive")
        if spacing < 2 * CRAZYFLIE_RADIUS:
            raise WorldConfigError(f"formation spacing {spacing} m is less than a Crazyflie "
                                   f"({2 * CRAZYFLIE_RADIUS * 1000:.0f} mm)")
        self.step_seconds = step_seconds
        bounds = (-width / 2, -depth / 2, width / 2, depth / 2)
        radio = RadioSettings(
            comm_range=comm_range, loss_by_rate=tuple((float(r), float(p))
                                                      for r, p in loss_by_rate),
            messages_per_step=10, send_queue_cap=10, has_bearing=True, distance_unit=1.0,
        )
        super().__init__(bounds, radio)
        self.ceiling = height
        self.obstacles = np.array(obstacles, dtype=np.float64).reshape(-1, 4)
        if np.any(self.obstacles[:, 2] <= self.obstacles[:, 0]) or np.any(
                self.obstacles[:, 3] <= self.obstacles[:, 1]):
            raise WorldConfigError("an obstacle box must be (xmin, ymin, xmax, ymax)")
        for x0, y0, x1, y1 in self.obstacles:
            self.walls += [((x0, y0), (x1, y0)), ((x1, y0), (x1, y1)),
                           ((x1, y1), (x0, y1)), ((x0, y1), (x0, y0))]
        self.segments = np.array(self.walls, dtype=np.float64).reshape(-1, 2, 2)
        self.formation = formation
        self.spacing = spacing

    # ---- placement ----------------------------------------------------------------------------
    def place(self, count: int, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
        """On the floor: a lattice ("grid"), a line ("chain") or robot 0 in the middle of a
        circle of the others ("circle", all at `spacing` from robot 0), as in the paper."""
        s = self.spacing
        if self.formation == "chain":
            xy = np.column_stack([(np.arange(count) - (count - 1) / 2) * s, np.zeros(count)])
        elif self.formation == "circle":
            angles = 2 * np.pi * np.arange(count - 1) / max(count - 1, 1)
            xy = np.vstack([[0.0, 0.0], np.column_stack([s * np.cos(angles),
                                                          s * np.sin(angles)])])[:count]
        else:
            side = math.ceil(math.sqrt(count))
            ix, iy = np.meshgrid(np.arange(side), np.arange(side))
            xy = (np.column_stack([ix.ravel(), iy.ravel()])[:count] - (side - 1) / 2) * s
        positions = np.column_stack([xy, np.zeros(count)])
        x0, y0, x1, y1 = self.bounds
        inside = ((positions[:, 0] - CRAZYFLIE_RADIUS >= x0) & (positions[:, 0] +
                  CRAZYFLIE_RADIUS <= x1) & (positions[:, 1] - CRAZYFLIE_RADIUS >= y0)
                  & (positions[:, 1] + CRAZYFLIE_RADIUS <= y1))
        if not inside.all() or self._inside_obstacles(positions[:, :2]).any():
            raise WorldConfigError(
                f"{count} drones in a {self.formation} {s} m apart do not fit in the room "
                "(outside it or inside an obstacle)")
        return positions, np.zeros(count)

    def max_robots(self) -> int:
        width, depth = self.size
        per_side = self.spacing
        return max(1, int(width // per_side) * int(depth // per_side))

    def _inside_obstacles(self, xy: np.ndarray) -> np.ndarray:
        if len(self.obstacles) == 0:
            return np.zeros(len(xy), dtype=bool)
        o = self.obstacles[None, :, :]
        r = CRAZYFLIE_RADIUS
        hit = ((xy[:, None, 0] > o[..., 0] - r) & (xy[:, None, 0] < o[..., 2] + r)
               & (xy[:, None, 1] > o[..., 1] - r) & (xy[:, None, 1] < o[..., 3] + r))
        return hit.any(axis=1)

    # ---- bodies -------------------------------------------------------------------------------
    def attach(self, sim: Simulation) -> None:
        count = sim.count
        # A drone in the air when its firmware (re)boots lands: it has no flight command.
        self.mode = np.where(sim.positions[:, 2] > 0, LANDING, LANDED).astype(np.int64)
        self.targets = sim.positions.copy()
        self.targets[:, 2] = 0.0
        self.velocities = np.zeros((count, 3))
        self.ranges = np.full((count, 5), RANGER_MAX)
        self.bumps = np.zeros(count, dtype=np.int64)
        for state in sim.robots:
            state.set_label("flying", False)

    def host_functions(self, sim: Simulation, index: int) -> Mapping[str, HostFunction]:
        rng = sim.robot_rngs[index]
        world = self

        def led(call: HostCall) -> None:
            if not call.expect_args(1):
                return
            color = _number_arg(call, 1)
            if color is not None:
                color = int(color)
                sim.leds[index] = ((color & 1) != 0, (color & 2) != 0, (color & 4) != 0)

        def delay(call: HostCall) -> None:
            call.expect_args(1)   # the Crazyflie firmware's delay does nothing

        def takeoff(call: HostCall) -> None:
            if not call.expect_args(1):
                return
            height = _number_arg(call, 1)
            if height is None:
                return
            world.mode[index] = FLYING
            world.targets[index, 2] = min(max(float(height), 0.1),
                                          world.ceiling - CRAZYFLIE_RADIUS)

        def land(call: HostCall) -> None:
            if world.mode[index] != LANDED:
                world.mode[index] = LANDING
                world.targets[index, 2] = 0.0

        def hover(call: HostCall) -> None:
            if world.mode[index] == FLYING:
                world.targets[index] = sim.positions[index]

        def go_to(call: HostCall) -> None:
            if not call.expect_args(3):
                return
            xyz = [_number_arg(call, i) for i in (1, 2, 3)]
            if any(v is None for v in xyz):
                return
            if world.mode[index] == FLYING:
                world.targets[index] = [float(v) for v in xyz]

        def ranges(call: HostCall) -> None:
            r = world.ranges[index]
            call.ret({"front": float(r[0]), "back": float(r[1]), "left": float(r[2]),
                      "right": float(r[3]), "up": float(r[4])})

        def position(call: HostCall) -> None:
            p = sim.positions[index] + rng.normal(0.0, POSITION_NOISE, 3)
            call.ret({"x": float(p[0]), "y": float(p[1]), "z": float(max(p[2], 0.0))})

        def flying(call: HostCall) -> None:
            call.ret(int(world.mode[index] == FLYING))

        def random_byte(call: HostCall) -> None:
            call.ret(int(rng.integers(0, 256)))

        return {"led": led, "delay": delay, "takeoff": takeoff, "land": land, "hover": hover,
                "goTo": go_to, "ranges": ranges, "position": position, "flying": flying,
                "rand": random_byte}

    # ---- sensors and physics ------------------------------------------------------------------
    def sense(self, sim: Simulation) -> None:
        xy = sim.positions[:, :2]
        yaw = sim.headings
        count = sim.count
        # front, back, left, right in the drone's frame (yaw 0 = +x).
        angles = np.stack([yaw, yaw + np.pi, yaw + np.pi / 2, yaw - np.pi / 2], axis=1)
        directions = np.stack([np.cos(angles), np.sin(angles)], axis=2).reshape(-1, 2)
        origins = np.repeat(xy, 4, axis=0)
        horizontal = segment_distances(origins, directions, self.segments, RANGER_MAX)
        self.ranges[:, :4] = np.maximum(horizontal.reshape(count, 4) - CRAZYFLIE_RADIUS, 0.0)
        self.ranges[:, 4] = np.minimum(self.ceiling - sim.positions[:, 2], RANGER_MAX)

    def advance(self, sim: Simulation, dt: float) -> None:
        positions = sim.positions
        airborne = self.mode != LANDED
        error = self.targets - positions
        desired = GAIN * error
        horizontal = np.hypot(desired[:, 0], desired[:, 1])
        scale = np.minimum(1.0, MAX_SPEED / np.maximum(horizontal, 1e-9))
        desired[:, :2] *= scale[:, None]
        desired[:, 2] = np.clip(desired[:, 2], -MAX_CLIMB, MAX_CLIMB)
        change = desired - self.velocities
        norm = np.linalg.norm(change, axis=1)
        limit = MAX_ACCELERATION * dt
        change *= np.minimum(1.0, limit / np.maximum(norm, 1e-9))[:, None]
        self.velocities = np.where(airborne[:, None], self.velocities + change, 0.0)
        moved = positions + self.velocities * dt
        bumped = self._collide(moved)
        self.bumps += bumped
        positions[:] = np.where(airborne[:, None], moved, positions)
        landed_now = (self.mode == LANDING) & (positions[:, 2] <= LANDED_HEIGHT)
        positions[landed_now, 2] = 0.0
        self.velocities[landed_now] = 0.0
        self.mode[landed_now] = LANDED
        for state in sim.robots:
            i = state.index
            state.set_label("flying", bool(self.mode[i] == FLYING))
            state.set_label("bumps", int(self.bumps[i]))

    def _collide(self, moved: np.ndarray) -> np.ndarray:
        """Push drones out of walls, ceiling and obstacles; zero the velocity into them."""
        r = CRAZYFLIE_RADIUS
        x0, y0, x1, y1 = self.bounds
        bumped = np.zeros(len(moved), dtype=bool)
        for axis, low, high in ((0, x0 + r, x1 - r), (1, y0 + r, y1 - r),
                                (2, 0.0, self.ceiling - r)):
            out = (moved[:, axis] < low) | (moved[:, axis] > high)
            moved[:, axis] = np.clip(moved[:, axis], low, high)
            self.velocities[out, axis] = 0.0
            if axis < 2:
                bumped |= out
        for bx0, by0, bx1, by1 in self.obstacles:
            inside = ((moved[:, 0] > bx0 - r) & (moved[:, 0] < bx1 + r)
                      & (moved[:, 1] > by0 - r) & (moved[:, 1] < by1 + r))
            if not inside.any():
                continue
            # Leave through the nearest face.
            depths = np.stack([moved[:, 0] - (bx0 - r), (bx1 + r) - moved[:, 0],
                               moved[:, 1] - (by0 - r), (by1 + r) - moved[:, 1]], axis=1)
            face = np.argmin(depths, axis=1)
            for i in np.nonzero(inside)[0]:
                axis = 0 if face[i] < 2 else 1
                moved[i, axis] = ((bx0 - r, bx1 + r, by0 - r, by1 + r)[face[i]])
                self.velocities[i, axis] = 0.0
            bumped |= inside
        return bumped

    def overlays(self) -> dict[str, Any]:
        return {"obstacles": self.obstacles.tolist(), "ceiling": self.ceiling}


def _number_arg(call: HostCall, i: int) -> float | int | None:
    value = call.arg(i)
    if isinstance(value, bool) or not isinstance(value, int | float):
        call.fail("TYPE")
        return None
    return value
