"""What a world is: the body and surroundings of every robot, seen by the engine.

Design: the engine (`engine.py`) owns the robots' firmware loops, the radio and the per-robot
arrays (positions, headings, LED colours) so that all worlds share one stepping order; a world
module only says what differs between platforms: its geometry (bounds, walls, robot size, radio
range), where robots start, which host functions (BittyBuzz C closures) a robot gets, what the
sensors read, and how actuator commands move the bodies (physics). Worlds work on the engine's
numpy arrays in place, so a world with 1,000 robots never loops in Python per robot for
geometry. A world keeps its per-robot actuator state (motor commands, flight targets) in its own
arrays, indexed like the engine's.

`World` is an abstract base class rather than a Protocol because most worlds share defaults
(no sensors, straight walls, no overlays) and the UI reads the geometry fields by name.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

if TYPE_CHECKING:
    from bbzide.vm.host import HostCall
    from bbzide.worlds.engine import Simulation

#: A host function as the firmware loop (`bbzide.vm.robot.Robot`) calls it.
HostFunction = Callable[["HostCall"], None]

#: A wall: two (x, y) end points in metres.
Segment = tuple[tuple[float, float], tuple[float, float]]


@dataclass(frozen=True)
class RadioSettings:
    """How a world's radio behaves by default (the engine's `Radio` applies them).

    `loss_by_rate` maps a sender's broadcast rate (messages per second) to a loss probability,
    interpolated piecewise-linearly (the Crazyflie's BLE loss grows with the rate); when empty,
    `loss_probability` is used for every message.
    """

    comm_range: float                    # metres
    loss_probability: float = 0.0        # per message and receiver
    loss_by_rate: tuple[tuple[float, float], ...] = ()
    messages_per_step: int = 10          # bandwidth: transmissions per sender per control step
    send_queue_cap: int = 10             # messages waiting at a sender beyond that; more dropped
    receive_cap_per_step: int | None = None  # messages one robot can take in per step
    latency_steps: int = 1               # sent in step t -> delivered at the start of t + latency
    distance_noise: float = 0.0          # relative standard deviation of the distance estimate
    bearing_noise: float = 0.0           # standard deviation of azimuth/elevation, radians
    has_bearing: bool = True             # False: azimuth and elevation are always 0 (Kilobot IR)
    distance_unit: float = 1.0           # distance handed to the VM = metres * distance_unit


class World(ABC):
    """One world: geometry, placement, host functions, sensors, actuators, physics.

    Geometry fields the UI reads (ARCHITECTURE.md "worlds → ui"): `bounds` (xmin, ymin, xmax,
    ymax in metres), `walls` (segments), `robot_radius`, `robot_height` (z at which to draw a
    robot that has no z of its own), `comm_range`, `step_seconds` (one control step).
    """

    name: str = "world"
    profile_name: str = "pc"
    host_names: tuple[str, ...] = ()
    step_seconds: float = 0.1
    robot_radius: float = 0.05
    robot_height: float = 0.0

    def __init__(self, bounds: tuple[float, float, float, float], radio: RadioSettings) -> None:
        self.bounds = bounds
        self.radio = radio
        self.walls: list[Segment] = self.boundary_walls()

    # ---- geometry --------------------------------------------------------------------------
    @property
    def comm_range(self) -> float:
        return self.radio.comm_range

    @property
    def size(self) -> tuple[float, float]:
        return (self.bounds[2] - self.bounds[0], self.bounds[3] - self.bounds[1])

    def boundary_walls(self) -> list[Segment]:
        x0, y0, x1, y1 = self.bounds
        return [((x0, y0), (x1, y0)), ((x1, y0), (x1, y1)),
                ((x1, y1), (x0, y1)), ((x0, y1), (x0, y0))]

    def max_robots(self) -> int:
        """How many robots fit at all (square packing of discs); more is a user error."""
        width, height = self.size
        per_side = 2 * self.robot_radius
        return int(width // per_side) * int(height // per_side)

    # ---- life cycle ------------------------------------------------------------------------
    @abstractmethod
    def place(self, count: int, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
        """Initial (count, 3) positions and (count,) headings for `count` robots."""

    def attach(self, sim: Simulation) -> None:  # noqa: B027 - optional hook
        """Called once the engine's arrays exist (and after every reset): build bodies."""

    @abstractmethod
    def host_functions(self, sim: Simulation, index: int) -> Mapping[str, HostFunction]:
        """The host functions robot `index` gets (bound to that robot's body)."""

    def sense(self, sim: Simulation) -> None:  # noqa: B027 - optional hook
        """Update sensor readings before the robots run (default: no sensors)."""

    @abstractmethod
    def advance(self, sim: Simulation, dt: float) -> None:
        """Apply actuator commands and move the bodies by `dt` seconds (in sim's arrays)."""

    def is_asleep(self, index: int, step: int) -> bool:
        """True while robot `index` is blocked (e.g. in `delay`) and skips its control step."""
        return False

    def asleep(self, step: int, count: int) -> np.ndarray:
        """bool[count]: `is_asleep(i, step)` of every robot (a world that keeps its sleep in
        an array answers with one numpy expression)."""
        return np.fromiter((self.is_asleep(i, step) for i in range(count)), dtype=bool,
                           count=count)

    def overlays(self) -> dict[str, Any]:
        """Extra things to draw (light field, obstacles, targets): name -> plain data."""
        return {}

    def targets_found(self) -> int | None:
        """How many of the overlays' targets are found, when the world can tell without
        building its overlays (a recorder asks every step while targets remain, so that
        "target found" lands on its step); None: build the overlays to know."""
        return None


@dataclass(frozen=True)
class WorldSpec:
    """A registry entry: what the UI and the CLI need to know before building a world."""

    name: str
    title: str
    example: str                     # repository-relative path of the default script
    profile: str                     # a key of bbzide.vm.profiles.PROFILES
    host_names: tuple[str, ...]      # host function names, in string-table order
    default_robots: int
    factory: Callable[..., World]    # keyword options -> World
    options: Mapping[str, Any] = field(default_factory=dict)  # documented defaults

    def create(self, **options: Any) -> World:
        return self.factory(**options)


def segment_distances(
    origins: np.ndarray, directions: np.ndarray, segments: np.ndarray, max_range: float
) -> np.ndarray:
    """Ray casting in 2D: distance along each ray to the nearest segment (max_range if none).

    origins (n, 2), directions (n, 2) unit vectors, segments (k, 2, 2). Vectorised over rays and
    segments (used by range sensors and tested against hand-made geometry).
    """
    n = len(origins)
    if len(segments) == 0 or n == 0:
        return np.full(n, max_range)
    p = origins[:, None, :]
    r = directions[:, None, :]
    q = segments[None, :, 0, :]
    s = segments[None, :, 1, :] - segments[None, :, 0, :]
    denominator = r[..., 0] * s[..., 1] - r[..., 1] * s[..., 0]
    qp = q - p
    with np.errstate(divide="ignore", invalid="ignore"):
        t = (qp[..., 0] * s[..., 1] - qp[..., 1] * s[..., 0]) / denominator
        u = (qp[..., 0] * r[..., 1] - qp[..., 1] * r[..., 0]) / denominator
    hit = (np.abs(denominator) > 1e-12) & (t >= 0) & (u >= 0) & (u <= 1)
    t = np.where(hit, t, np.inf)
    return np.minimum(t.min(axis=1), max_range)
