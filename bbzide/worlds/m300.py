"""The M300 field: DJI Matrice 300 drones over an outdoor field (thesis §5.3.3, §5.5).

Design: a drone is a point flying a kinematic model, the way the M300's flight controller is
driven through the OSDK in the paper: `takeoff()` climbs to the mission altitude, `goto(x, y)`
flies straight at the cruise speed, `land()` descends; there is no acceleration model (the
flight controller hides it at these speeds and 0.1 s control steps) and no collision model (the
paper's drones ran the M300's own obstacle avoidance). The field is a square of `size` metres
with its south-west corner at the origin (a local GPS frame: x east, y north, metres); the
rendezvous point (meeting point, base station) is fixed in the middle of the west edge and the
drones start on the ground in a launch strip along that edge (thesis Fig. 5.4).

Sensors: GPS-like positions (`position()`, no noise by default: RTK), a downward camera whose
footprint is a disc of radius altitude * tan(fov / 2) under the drone, which detects the static
targets inside it. The radio is a Wi-Fi ad-hoc mesh (batman-adv in the paper): a hard range
(10 m by default, thesis §5.4.2), no loss by default, and enough bandwidth for a BittyBuzz
out-queue per step.

A prior belief map (the authorities' knowledge of where the targets are, thesis §5.3.2) is a
`cells` x `cells` raster over the field with values in [0, 1]; it is either given (an array or
a .npy/.csv file) or generated from the run seed as a few Gaussian hot spots. By default
(`targets_where=uniform`) the targets are spread evenly over the field whatever the prior
says, as the simulation study describes them (§5.4.1: "randomly spawned"; §5.4.2: "randomly
assigning ... the targets' positions and the belief map", two separate draws). Two other
placements draw them from the prior in proportion to the belief: `targets_where=likely` only
in cells the prior puts at or above the search threshold (the premise of §5.1: a prior "from
the authorities, such as the last known locations of the targets", where red cells mean "a
probability close to 0"; our generator's 5 % floor is ours), `targets_where=anywhere` in every
cell, floor included. The same seed gives the same map and targets whatever the search method
(the pairs of the experiments).

Host functions (Buzz names). Positions and distances a script sees are integer DECIMETRES in
the field frame: BittyBuzz compares floats by their raw 16-bit payloads (a wrong order for
mixed signs and for int/float pairs, see bbzide/ui/pitfalls.py), so a script must decide on
ints; 1 dm is finer than the drones' GPS needs and an int16 holds 3.2 km.
  takeoff()            climb to the mission altitude
  land()               descend and stop the motors
  goto(x, y)           fly to (x, y) dm at the mission altitude (clipped to the field)
  position()           {x, y, z, cell}: where the drone is and the index of the belief cell under it
  arrived()            1 when flying and within 0.3 m of the last goto point, else 0
  flying()             1 when airborne and not landing
  camera()             nil, or {x, y}: the ground position of the nearest target in the camera
                       footprint (the detection geolocated from the drone's GPS and altitude)
  random_goal()        {x, y, cell}: a uniform random point of the field (the drone's own stream)
  prior(cell)          the prior belief of a cell as an int 0..100 (percent)
  distance(x1, y1, x2, y2)   Euclidean distance, dm (int, rounded)
  mission()            {search, steps, size, rx, ry, range, cells, threshold}: the mission
                       (search 1 = belief map, 0 = random walk)
  set_role(code)       the drone's role for the UI (codes: ROLE_NAMES); also sets its LED colour
  know_target(x, y)    the drone knows a target at (x, y) dm (drawn by the UI)
  relay_link(parent)   the drone relays for robot `parent` (-1: none); drawn as the relay tree
  missed(dm)           percent (0..100) of a belief cell's value left after the camera swept
                       dm decimetres of flight over the cell without a sighting: 100 x
                       exp(-swath x length / cell area), Koopman's random-search law (the
                       chance of having missed a target there); see `miss_percent`
  rand()               0..255
  clock()              the world's control step number (a GPS time stamp)
  doze(n)              skip up to n control steps while the flight controller flies on: woken
                       early when the drone arrives, enters another belief cell or starts
                       seeing a target
                       (the onboard code of the paper's drones; messages wait in the in-queue)

Sightings are the world's: a target counts as found (`found_step`) the first step a flying
drone has it in its camera footprint, whatever the script does with it. `role_steps` counts, per
drone and role, the steps spent in each role (the relay formation time is the root's auctioneer
steps, thesis §5.4.2). The world also counts, per drone, what the search pattern of §5.3 is
made of, from the roles the script sets and the drones' positions: `rendezvous_returns` (a
searcher's run ended and it turned back to the meeting point: searcher -> rendezvous),
`rendezvous_arrivals` (a drone in the rendezvous role reached the meeting point; a returning
drone that a call for bids recruits on the way, in range of the root, never arrives),
`root_elections` (a root candidate became the root) and `auctions` (the root opened an
auction: root -> auctioneer).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from bbzide.vm.host import (
    DrawnHostFunction,
    LatchedHostFunction,
    LookupHostFunction,
    ReadingHostFunction,
    RoundedDistanceHostFunction,
)
from bbzide.worlds.radio import WorldConfigError
from bbzide.worlds.registry import M300_HOST_NAMES
from bbzide.worlds.world import HostFunction, RadioSettings, World

if TYPE_CHECKING:
    from bbzide.vm.host import HostCall
    from bbzide.worlds.engine import Simulation

M300_RADIUS = 0.45           # m: half of the M300's 895 mm diagonal wheelbase
STEP_SECONDS = 0.1           # s: Buzz's default control period (thesis §5.4.2)
DEFAULT_SIZE = 36.0          # m: the football field of the paper's field tests (§5.5)
DEFAULT_SPEED = 2.0          # m/s: a deliberately low field speed (§5.5: "relatively low value")
CLIMB_SPEED = 1.0            # m/s: vertical speed for takeoff and landing
DEFAULT_ALTITUDE = 5.0       # m: low enough that the camera resolves a person on the ground
CAMERA_FOV = math.radians(45.0)  # full field of view of the downward camera
ARRIVAL_TOLERANCE = 0.3      # m: goto counts as reached within this distance
DM = 10.0                    # decimetres per metre: the unit of the Buzz interface
INT16_MAX = 32767            # BittyBuzz ints: the largest position a script can hold, in dm
DEFAULT_COMM_RANGE = 10.0    # m: thesis §5.4.2
DEFAULT_CELLS = 10           # belief raster cells per side (the SAR script's key table matches)
#: The most belief cells per side: BittyBuzz's virtual stigmergy keys are strings and it cannot
#: build one at run time, so the SAR script (examples/sar/belief_keys.bzz) names each cell's key
#: in a table of 10 x 10 entries; past it, cells would share the key of a missing entry (nil)
#: and the belief map would be silently wrong. tests/worlds/test_m300_world.py keeps the two equal.
MAX_CELLS = 10
LAUNCH_STRIP = 4.0           # m: drones start within this distance of the west edge
HOT_SPOTS = 3                # Gaussian bumps of a generated belief map
BELIEF_FLOOR = 0.05          # generated maps never say "impossible" (priors can be wrong)
TARGET_SEPARATION = 4.0      # m: generated targets at least this far apart (distinct finds)
#: Search steps per search run between two rendezvous (thesis §5.4.2: 20). A search step is
#: one wake of a flying searcher, 1 s (examples/sar/sar.bzz SEARCH_STEP): a run lasts 20 s.
DEFAULT_SEARCH_STEPS = 20
DEFAULT_THRESHOLD = 20       # percent: goals believed below this are rejected
#: Where generated targets lie: "uniform" (the default, thesis §5.4.1-5.4.2: targets
#: "randomly spawned" anywhere in the search area, whatever the prior says), "likely" (in
#: proportion to the prior, only in cells it puts at or above the search threshold: the
#: authorities' prior is right) or "anywhere" (in proportion to the prior, floor included:
#: ~21 % of a generated map's mass is under the threshold).
TARGETS_WHERE = ("uniform", "likely", "anywhere")

#: random_goal()'s record: a point of the field (dm) and its belief cell
GOAL_KEYS = ("x", "y", "cell")
#: Role codes of `set_role` -> names the UI shows; LED colours per role.
ROLE_NAMES = ("searcher", "root_candidate", "root", "auctioneer", "networker_bidder",
              "networker", "rendezvous", "landed")
ROLE_COLOURS = {
    "searcher": (0.2, 0.5, 1.0), "root_candidate": (1.0, 0.6, 0.0), "root": (1.0, 0.0, 0.0),
    "auctioneer": (1.0, 0.0, 1.0), "networker_bidder": (0.6, 1.0, 0.6),
    "networker": (0.0, 0.8, 0.0), "rendezvous": (1.0, 1.0, 0.0), "landed": (0.4, 0.4, 0.4),
}

LANDED, FLYING, LANDING = 0, 1, 2


def generate_belief_map(cells: int, rng: np.random.Generator,
                        hot_spots: int = HOT_SPOTS) -> np.ndarray:
    """A (cells, cells) prior in [BELIEF_FLOOR, 1]: a few Gaussian hot spots, max 1.

    Row index = y cell, column = x cell. Hot spots keep off the west launch strip's first
    column so the prior points away from the base, as a real search area would.
    """
    ys, xs = np.mgrid[0:cells, 0:cells] + 0.5
    belief = np.zeros((cells, cells))
    for _ in range(hot_spots):
        cx = rng.uniform(0.25 * cells, cells)
        cy = rng.uniform(0, cells)
        sigma = rng.uniform(0.08, 0.18) * cells
        belief += np.exp(-((xs - cx) ** 2 + (ys - cy) ** 2) / (2 * sigma ** 2))
    belief /= belief.max()
    return np.maximum(belief, BELIEF_FLOOR)


def load_belief_map(source: Any) -> np.ndarray:
    """A belief map from an array-like or a .npy / .csv file (square, values in [0, 1])."""
    if isinstance(source, str | Path):
        path = Path(source)
        try:
            data = (np.load(path) if path.suffix == ".npy"
                    else np.loadtxt(path, delimiter=",", ndmin=2))
        except (OSError, ValueError) as error:
            raise WorldConfigError(f"cannot read the belief map {path}: {error}") from None
    else:
        data = np.asarray(source, dtype=np.float64)
    if data.ndim != 2 or data.shape[0] != data.shape[1] or data.shape[0] < 1:
        raise WorldConfigError(f"a belief map must be a square raster, got shape {data.shape}")
    if not np.all(np.isfinite(data)) or data.min() < 0 or data.max() > 1:
        raise WorldConfigError("belief map values must be within [0, 1]")
    return data.astype(np.float64)


def draw_targets(belief: np.ndarray, size: float, count: int, rng: np.random.Generator,
                 keep_out: float, floor: float = 0.0) -> np.ndarray:
    """`count` target positions drawn cell-wise in proportion to the belief, uniform within the
    cell, east of x = keep_out and TARGET_SEPARATION apart (rejection sampling). With `floor`
    > 0 only cells believed at least `floor` can hold a target (a prior that is never wrong)."""
    cells = belief.shape[0]
    cell = size / cells
    weights = belief.ravel() * (belief.ravel() >= floor)
    if weights.sum() <= 0:
        raise WorldConfigError(f"no belief cell reaches {100 * floor:g} % (the search "
                               "threshold): nowhere to put a target")
    weights = weights / weights.sum()
    targets: list[tuple[float, float]] = []
    for _ in range(10_000):          # far more tries than any sane field needs
        if len(targets) == count:
            break
        k = int(rng.choice(cells * cells, p=weights))
        x = (k % cells + rng.uniform()) * cell
        y = (k // cells + rng.uniform()) * cell
        if x < keep_out or any(math.hypot(x - a, y - b) < TARGET_SEPARATION
                               for a, b in targets):
            continue
        targets.append((x, y))
    if len(targets) < count:
        raise WorldConfigError(f"cannot place {count} targets {TARGET_SEPARATION} m apart "
                               f"in a {size:g} m field")
    return np.array(targets, dtype=np.float64).reshape(-1, 2)


def parse_targets(text: str) -> int | list[tuple[float, float]]:
    """Targets as command-line text: a count (`3`) or positions in metres (`26:24,10:5`)."""
    text = text.strip()
    if text.isdigit():
        return int(text)
    targets = []
    for item in text.split(","):
        x, sep, y = item.partition(":")
        try:
            if not sep:
                raise ValueError(item)
            targets.append((float(x), float(y)))
        except ValueError:
            raise WorldConfigError(
                f"targets {text!r}: give a count (targets=3) or x:y positions in metres "
                "separated by commas (targets=26:24,10:5)") from None
    return targets


class M300Field(World):
    """A `size` x `size` m field, origin at its south-west corner."""

    name = "m300"
    profile_name = "m300"
    host_names = M300_HOST_NAMES
    step_seconds = STEP_SECONDS
    robot_radius = M300_RADIUS
    robot_height = 0.0

    def __init__(
        self,
        size: float = DEFAULT_SIZE,
        comm_range: float = DEFAULT_COMM_RANGE,
        speed: float = DEFAULT_SPEED,
        altitude: float = DEFAULT_ALTITUDE,
        targets: int | str | Sequence[Sequence[float]] = 3,
        belief_map: Any = None,
        cells: int = DEFAULT_CELLS,
        search: str = "belief",
        search_steps: int = DEFAULT_SEARCH_STEPS,
        threshold: int = DEFAULT_THRESHOLD,
        targets_where: str = "uniform",
        loss: float = 0.0,
        map_seed: int | None = None,
    ) -> None:
        if not size > 0:
            raise WorldConfigError(f"the field size must be positive, got {size}")
        if comm_range < 0:
            raise WorldConfigError(f"communication range must be >= 0, got {comm_range}")
        if size < comm_range:
            raise WorldConfigError(
                f"a {size:g} m field is smaller than the {comm_range:g} m communication range: "
                "every drone would always hear every other and there is nothing to search for")
        if size * DM > INT16_MAX:
            raise WorldConfigError(
                f"a {size:g} m field is too large: positions reach scripts as int16 decimetres "
                f"(at most {INT16_MAX / DM:g} m)")
        if speed <= 0 or altitude <= 0:
            raise WorldConfigError("speed and altitude must be positive")
        if search not in ("belief", "random"):
            raise WorldConfigError(f"unknown search {search!r}: belief or random")
        if targets_where not in TARGETS_WHERE:
            raise WorldConfigError(f"targets_where {targets_where!r}: "
                                   f"choose from {', '.join(TARGETS_WHERE)}")
        if search_steps < 1:
            raise WorldConfigError("a search run needs at least 1 search step")
        if not 0 <= loss <= 1:
            raise WorldConfigError(f"loss probability must be within [0, 1], got {loss}")
        if not 0 <= threshold <= 100:
            raise WorldConfigError(f"the search threshold is a percentage of belief: within "
                                   f"0..100, got {threshold}")
        if map_seed is not None and map_seed < 0:
            raise WorldConfigError(f"map_seed must be >= 0, got {map_seed}")
        radio = RadioSettings(comm_range=comm_range, loss_probability=loss,
                              messages_per_step=10, send_queue_cap=10, has_bearing=True)
        super().__init__((0.0, 0.0, float(size), float(size)), radio)
        self.field_size = float(size)
        self.speed = float(speed)
        self.altitude = float(altitude)
        self.camera_radius = self.altitude * math.tan(CAMERA_FOV / 2)
        self.search = search
        self.search_steps = int(search_steps)
        self.threshold = int(threshold)
        self.targets_where = targets_where
        self.rendezvous = (min(2.0, size / 2), size / 2)
        self.map_seed = map_seed
        self._given_map = None if belief_map is None else load_belief_map(belief_map)
        self.cells = self._given_map.shape[0] if self._given_map is not None else int(cells)
        if self.cells < 1:
            raise WorldConfigError("the belief map needs at least 1 cell")
        if self.cells > MAX_CELLS:
            raise WorldConfigError(
                f"the belief map has at most {MAX_CELLS} x {MAX_CELLS} cells, got {self.cells} "
                f"per side: the SAR script names one stigmergy key per cell "
                f"(examples/sar/belief_keys.bzz holds {MAX_CELLS * MAX_CELLS})")
        if isinstance(targets, str):          # `--set targets=26:24,10:5` (x:y metres)
            targets = parse_targets(targets)
        if isinstance(targets, int):
            if targets < 0:
                raise WorldConfigError("the number of targets must be >= 0")
            self._target_count, self._given_targets = targets, None
        else:
            given = np.asarray(targets, dtype=np.float64).reshape(-1, 2)
            if np.any(given < 0) or np.any(given > size):
                raise WorldConfigError("every target must lie inside the field")
            self._target_count, self._given_targets = len(given), given
        self.belief = np.ones((self.cells, self.cells))
        self.targets = np.zeros((self._target_count, 2))

    # ---- placement ----------------------------------------------------------------------------
    def place(self, count: int, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
        """On the ground, uniformly in the launch strip along the west edge."""
        strip = min(LAUNCH_STRIP, self.field_size)
        x = rng.uniform(M300_RADIUS, strip - M300_RADIUS, count)
        y = rng.uniform(M300_RADIUS, self.field_size - M300_RADIUS, count)
        return np.column_stack([x, y, np.zeros(count)]), np.zeros(count)

    def max_robots(self) -> int:
        """Drones that fit in the launch strip, 1 m apart (a safe spacing on the ground)."""
        return max(1, int(min(LAUNCH_STRIP, self.field_size)) * int(self.field_size))

    # ---- bodies -------------------------------------------------------------------------------
    def attach(self, sim: Simulation) -> None:
        count = sim.count
        self._sim = sim  # for latched host functions: doze's step, set_role's robot
        if self.field_size < self.comm_range:     # again: `--comm-range` overrides the radio
            raise WorldConfigError(
                f"a {self.field_size:g} m field is smaller than the {self.comm_range:g} m "
                "communication range: every drone would always hear every other")
        # Map and targets from their own stream of the run seed: the same for both searches of
        # an experiment pair and unchanged by a reboot (attach runs again on load_program).
        seed = sim.seed if self.map_seed is None else self.map_seed
        rng = np.random.default_rng([int(seed), 0x300])
        self.belief = (self._given_map if self._given_map is not None
                       else generate_belief_map(self.cells, rng))
        self.targets = (self._given_targets if self._given_targets is not None
                        else draw_targets(np.ones_like(self.belief)
                                          if self.targets_where == "uniform" else self.belief,
                                          self.field_size, self._target_count, rng,
                                          keep_out=LAUNCH_STRIP + 1.0,
                                          floor=(self.threshold / 100
                                                 if self.targets_where == "likely" else 0.0)))
        # the tables of prior(cell) and missed(flown) (LookupHostFunction, vm/host.py)
        self.prior_values = np.array([int(round(100 * b)) for b in self.belief.ravel().tolist()],
                                     dtype=np.int64)
        self.missed_values = self._missed_table()
        self.mode = np.full(count, LANDED, dtype=np.int64)
        self.goals = sim.positions.copy()
        self.found_step = np.full(len(self.targets), -1, dtype=np.int64)
        self.roles = ["landed"] * count
        self.role_codes = np.full(count, ROLE_NAMES.index("landed"), dtype=np.int64)
        self.known_targets: list[list[tuple[float, float]]] = [[] for _ in range(count)]
        self.parents = np.full(count, -1, dtype=np.int64)
        self.role_steps = np.zeros((count, len(ROLE_NAMES)), dtype=np.int64)
        self.rendezvous_returns = np.zeros(count, dtype=np.int64)
        self.rendezvous_arrivals = np.zeros(count, dtype=np.int64)
        self.root_elections = np.zeros(count, dtype=np.int64)
        self.auctions = np.zeros(count, dtype=np.int64)
        self.at_rendezvous = np.zeros(count, dtype=bool)
        self.asleep_until = np.zeros(count, dtype=np.int64)
        self.cells_now = np.array([self.cell_of(x, y) for x, y, _ in sim.positions])
        self.was_seeing = np.zeros(count, dtype=bool)
        self.was_arrived = np.ones(count, dtype=bool)
        self.step = 0
        for state in sim.robots:
            state.set_label("role", "landed")
            sim.leds[state.index] = ROLE_COLOURS["landed"]

    def cell_of(self, x: float, y: float) -> int:
        """Index (row-major, row = y) of the belief cell containing (x, y)."""
        n = self.cells
        cx = min(max(int(x / self.field_size * n), 0), n - 1)
        cy = min(max(int(y / self.field_size * n), 0), n - 1)
        return cy * n + cx

    def _missed_table(self) -> np.ndarray:
        """`miss_percent` of flown = 0, 1, 2, ... up to its first 0 (it only falls as the
        flight grows, and a negative flight counts as none), or over every int16 flight."""
        values = []
        for flown in range(INT16_MAX + 1):
            values.append(self.miss_percent(flown))
            if values[-1] == 0:
                break
        return np.array(values, dtype=np.int64)

    def miss_percent(self, flown_dm: float) -> int:
        """Percent of a cell's belief left after `flown_dm` dm of flight over it without a
        sighting: exp(-W L / A) with W the camera swath (2 x footprint radius), L the length
        flown and A the cell's area (Koopman's random-search law: the probability that a sensor
        of sweep width W moving L within A misses a target in it). A straight pass through the
        middle of a cell leaves 13 % in a 20 m field (2 m cells, 4.1 m swath), 36 % in a 40 m
        one (4 m cells). Computed here because BittyBuzz ints are 16 bits and it has no exp;
        it is the camera's detection model, the belief update itself is the script's."""
        cell = self.field_size / self.cells
        swept = 2 * self.camera_radius * max(float(flown_dm), 0.0) / DM
        return int(round(100 * math.exp(-swept / cell ** 2)))

    def host_functions(self, sim: Simulation, index: int) -> Mapping[str, HostFunction]:
        rng = sim.robot_rngs[index]
        world = self
        size = self.field_size

        def takeoff(call: HostCall) -> None:
            if not call.expect_args(0):
                return
            world.mode[index] = FLYING
            world.goals[index, :2] = sim.positions[index, :2]
            world.goals[index, 2] = world.altitude

        def land(call: HostCall) -> None:
            if call.expect_args(0) and world.mode[index] != LANDED:
                world.mode[index] = LANDING
                world.goals[index] = (*sim.positions[index, :2], 0.0)

        def goto(call: HostCall) -> None:
            if not call.expect_args(2):
                return
            x, y = _number_arg(call, 1), _number_arg(call, 2)
            if x is None or y is None:
                return
            world.go_to(index, x, y)

        # Readings (vm/host.py): what they read changes only in `advance` and in this
        # robot's takeoff and land, never in a step before its first Python call, and in
        # its goto (latched: `arrived` is stale after it).
        def position() -> tuple[int, int, int, int]:
            x, y, z = sim.positions[index].tolist()
            return _dm(x), _dm(y), _dm(z), world.cell_of(x, y)

        def arrived() -> int:
            gap = float(np.linalg.norm(world.goals[index] - sim.positions[index]))
            return int(world.mode[index] == FLYING and gap <= ARRIVAL_TOLERANCE)

        def flying() -> int:
            return int(world.mode[index] == FLYING)

        def camera() -> tuple[int, int] | None:
            seen = world.seen_target(sim, index)
            if seen < 0:
                return None
            x, y = world.targets[seen].tolist()
            return _dm(x), _dm(y)

        def goal_of(x: float, y: float) -> tuple[int, int, int]:
            return _dm(x), _dm(y), world.cell_of(x, y)

        def random_goal(call: HostCall) -> None:
            x, y = rng.uniform(0.0, size, 2)
            call.ret(dict(zip(GOAL_KEYS, goal_of(x, y), strict=True)))

        # random_goal's next results for the compiled swarm step (DrawnHostFunction), kept
        # with the stream's state they were drawn from until the stream moves
        ahead_of: list[Any] = [None, ()]

        def goals_ahead(count: int) -> tuple[tuple[int, int, int], ...]:
            state = rng.bit_generator.state
            if ahead_of[0] != state or len(ahead_of[1]) != count:
                drawn = rng.uniform(0.0, size, 2 * count).tolist()  # `count` calls' draws
                rng.bit_generator.state = state
                ahead_of[:] = state, tuple(goal_of(drawn[2 * k], drawn[2 * k + 1])
                                           for k in range(count))
            return ahead_of[1]

        def skip_goals(count: int) -> None:
            rng.uniform(0.0, size, 2 * count)

        def prior(call: HostCall) -> None:
            if not call.expect_args(1):
                return
            cell = _number_arg(call, 1)
            if cell is None:
                return
            call.ret(int(world.prior_values[min(max(int(cell), 0),
                                                len(world.prior_values) - 1)]))

        def distance(call: HostCall) -> None:
            if not call.expect_args(4):
                return
            v = [_number_arg(call, i) for i in (1, 2, 3, 4)]
            if any(a is None for a in v):
                return
            call.ret(int(round(math.hypot(v[0] - v[2], v[1] - v[3]))))  # type: ignore[operator]

        def mission(call: HostCall) -> None:
            call.ret({"search": int(world.search == "belief"), "steps": world.search_steps,
                      "size": _dm(world.field_size),
                      "rx": _dm(world.rendezvous[0]), "ry": _dm(world.rendezvous[1]),
                      "range": _dm(world.comm_range), "cells": world.cells,
                      "threshold": world.threshold})

        def set_role(call: HostCall) -> None:
            if not call.expect_args(1):
                return
            code = _number_arg(call, 1)
            if code is None:
                return
            code = int(code)
            if not 0 <= code < len(ROLE_NAMES):
                call.fail("TYPE")
                return
            world.take_role(index, code)

        def know_target(call: HostCall) -> None:
            if not call.expect_args(2):
                return
            x, y = _number_arg(call, 1), _number_arg(call, 2)
            if x is not None and y is not None:
                world.learn_target(index, x, y)

        def relay_link(call: HostCall) -> None:
            if not call.expect_args(1):
                return
            parent = _number_arg(call, 1)
            if parent is not None:
                world.parents[index] = int(parent)

        def missed(call: HostCall) -> None:
            if not call.expect_args(1):
                return
            flown = _number_arg(call, 1)
            if flown is not None:
                call.ret(world.miss_percent(flown))

        def random_byte(call: HostCall) -> None:
            call.ret(int(rng.integers(0, 256)))

        def clock() -> int:
            return int(sim.step_count)

        def doze(call: HostCall) -> None:
            if not call.expect_args(1):
                return
            steps = _number_arg(call, 1)
            if steps is not None:
                world.asleep_until[index] = sim.step_count + 1 + max(int(steps), 0)

        return {"takeoff": takeoff, "land": land,
                "goto": LatchedHostFunction(goto, 2, index, self._apply_goto_latches),
                "position": ReadingHostFunction(position, ("x", "y", "z", "cell")),
                "arrived": ReadingHostFunction(arrived, stale_after=("goto",)),
                "flying": ReadingHostFunction(flying),
                "camera": ReadingHostFunction(camera, ("x", "y")),
                "random_goal": DrawnHostFunction(random_goal, GOAL_KEYS, goals_ahead, skip_goals),
                "prior": LookupHostFunction(prior, self.prior_values),
                "distance": RoundedDistanceHostFunction(distance),
                "mission": mission,
                # stores of this drone's state that no host function reads but `arrived`
                # (goto's goal): latched; each role change and target learnt counts, so
                # set_role and know_target are latched once a step
                "set_role": LatchedHostFunction(set_role, 1, index, self._apply_role_latches,
                                                below=len(ROLE_NAMES), once=True),
                "know_target": LatchedHostFunction(know_target, 2, index,
                                                   self._apply_target_latches, once=True),
                "relay_link": relay_link,
                "missed": LookupHostFunction(missed, self.missed_values), "rand": random_byte,
                "clock": ReadingHostFunction(clock),
                # doze's only effect is this robot's wake-up step, which the engine reads
                # between steps: a latched host function
                "doze": LatchedHostFunction(doze, 1, index, self._apply_doze_latches)}

    def _apply_doze_latches(self, targets: np.ndarray, values: np.ndarray) -> None:
        """``doze(steps)`` of robots ``targets`` (their last call's int argument each), as
        the host function stores it."""
        self.asleep_until[targets] = self._sim.step_count + 1 + np.maximum(values[:, 0], 0)

    def go_to(self, index: int, x: float, y: float) -> None:
        """``goto(x, y)`` (dm) of drone `index`: its goal, inside the field, if it flies."""
        if self.mode[index] == FLYING:
            self.goals[index, 0] = min(max(float(x) / DM, 0.0), self.field_size)
            self.goals[index, 1] = min(max(float(y) / DM, 0.0), self.field_size)

    def take_role(self, index: int, code: int) -> None:
        """``set_role(code)`` of drone `index` (`code` an index of ROLE_NAMES): the change
        counted, the role, its label and LED set."""
        name = ROLE_NAMES[code]
        self.count_transition(index, self.roles[index], name)
        self.roles[index] = name
        self.role_codes[index] = code
        self._sim.robots[index].set_label("role", name)
        self._sim.leds[index] = ROLE_COLOURS[name]

    def learn_target(self, index: int, x: float, y: float) -> None:
        """``know_target(x, y)`` (dm) of drone `index`: kept unless within half a metre of
        one it knows."""
        x, y = x / DM, y / DM
        known = self.known_targets[index]
        if all(math.hypot(x - a, y - b) > 0.5 for a, b in known):
            known.append((float(x), float(y)))

    def _apply_goto_latches(self, targets: np.ndarray, values: np.ndarray) -> None:
        """``goto(x, y)`` of drones ``targets`` (their last call's ints), as the host
        function stores it."""
        for index, (x, y) in zip(targets.tolist(), values.tolist(), strict=True):
            self.go_to(index, x, y)

    def _apply_role_latches(self, targets: np.ndarray, values: np.ndarray) -> None:
        """``set_role(code)`` of drones ``targets`` (one call each, its code in range)."""
        for index, code in zip(targets.tolist(), values[:, 0].tolist(), strict=True):
            self.take_role(index, code)

    def _apply_target_latches(self, targets: np.ndarray, values: np.ndarray) -> None:
        """``know_target(x, y)`` of drones ``targets`` (one call each, ints)."""
        for index, (x, y) in zip(targets.tolist(), values.tolist(), strict=True):
            self.learn_target(index, x, y)

    def count_transition(self, index: int, before: str, after: str) -> None:
        """Count the role changes that are events of the search pattern (§5.3.1)."""
        if before == "searcher" and after == "rendezvous":
            self.rendezvous_returns[index] += 1
        elif before == "root_candidate" and after == "root":
            self.root_elections[index] += 1
        elif before == "root" and after == "auctioneer":
            self.auctions[index] += 1

    # ---- sensors and physics ------------------------------------------------------------------
    def seen_target(self, sim: Simulation, index: int) -> int:
        """The nearest target inside robot `index`'s camera footprint (-1: none)."""
        if self.mode[index] != FLYING or len(self.targets) == 0:
            return -1
        gaps = np.hypot(self.targets[:, 0] - sim.positions[index, 0],
                        self.targets[:, 1] - sim.positions[index, 1])
        nearest = int(np.argmin(gaps))
        return -1 if gaps[nearest] > self.camera_radius else nearest

    def is_asleep(self, index: int, step: int) -> bool:
        return bool(self.asleep_until[index] > step)

    def asleep(self, step: int, count: int) -> np.ndarray:
        return self.asleep_until > step

    def _footprints(self, sim: Simulation) -> np.ndarray:
        """(drones, targets) bool: target inside the drone's camera footprint, drone flying."""
        if len(self.targets) == 0:
            return np.zeros((sim.count, 0), dtype=bool)
        dx = sim.positions[:, None, 0] - self.targets[None, :, 0]
        dy = sim.positions[:, None, 1] - self.targets[None, :, 1]
        return (np.hypot(dx, dy) <= self.camera_radius) & (self.mode == FLYING)[:, None]

    def advance(self, sim: Simulation, dt: float) -> None:
        positions = sim.positions
        airborne = self.mode != LANDED
        error = self.goals - positions
        horizontal = np.hypot(error[:, 0], error[:, 1])
        h_scale = np.minimum(1.0, self.speed * dt / np.maximum(horizontal, 1e-9))
        step = error.copy()
        step[:, :2] *= h_scale[:, None]
        step[:, 2] = np.clip(step[:, 2], -CLIMB_SPEED * dt, CLIMB_SPEED * dt)
        positions[:] = np.where(airborne[:, None], positions + step, positions)
        moving = horizontal > 1e-9
        sim.headings[:] = np.where(moving & airborne, np.arctan2(error[:, 1], error[:, 0]),
                                   sim.headings)
        landed_now = (self.mode == LANDING) & (positions[:, 2] <= 1e-6)
        positions[landed_now, 2] = 0.0
        self.mode[landed_now] = LANDED
        now = sim.step_count + 1
        self.step = now
        self.role_steps[np.arange(sim.count), self.role_codes] += 1
        seen = self._footprints(sim)
        first = seen.any(axis=0) & (self.found_step < 0)
        self.found_step[first] = now
        # Wake dozing drones that arrived, changed cell or see a target.
        cells = (np.clip((positions[:, 1] / self.field_size * self.cells).astype(np.int64), 0,
                         self.cells - 1) * self.cells
                 + np.clip((positions[:, 0] / self.field_size * self.cells).astype(np.int64), 0,
                           self.cells - 1))
        arrived = np.linalg.norm(self.goals - positions, axis=1) <= ARRIVAL_TOLERANCE
        sees = seen.any(axis=1)
        wake = ((cells != self.cells_now) | (sees & ~self.was_seeing)
                | (arrived & ~self.was_arrived))
        self.cells_now, self.was_seeing, self.was_arrived = cells, sees, arrived
        # An arrival: a drone in the rendezvous role comes within the arrival tolerance of the
        # meeting point (counted once per stay).
        near = np.hypot(positions[:, 0] - self.rendezvous[0],
                        positions[:, 1] - self.rendezvous[1]) <= ARRIVAL_TOLERANCE
        returning = self.role_codes == ROLE_NAMES.index("rendezvous")
        self.rendezvous_arrivals[returning & near & ~self.at_rendezvous] += 1
        self.at_rendezvous = returning & near
        self.asleep_until[wake] = 0

    # ---- what the UI and the experiments read -------------------------------------------------
    def relay_links(self) -> list[tuple[int, int]]:
        """(child index, parent index) of every drone that relays for another."""
        return [(i, int(p)) for i, p in enumerate(self.parents) if p >= 0]

    def relay_complete(self, sim: Simulation) -> bool:
        """True when every target has a networker over it (within the camera footprint) whose
        chain of relay links reaches the root, every networker on it flying and every link no
        longer than the communication range (the tree connects the base to each target)."""
        if len(self.targets) == 0:
            return True
        positions = sim.positions[:, :2]
        count = len(positions)
        roots = {i for i, r in enumerate(self.roles) if r in ("root", "auctioneer")}

        def reaches_root(child: int) -> bool:
            for _ in range(count):                 # a chain longer than the swarm is a cycle
                if child in roots:
                    return True
                parent = int(self.parents[child])
                if (self.roles[child] != "networker" or self.mode[child] != FLYING
                        or not 0 <= parent < count or np.hypot(
                            *(positions[child] - positions[parent])) > self.comm_range + 1e-6):
                    return False
                child = parent
            return False

        for t in self.targets:
            gaps = np.hypot(positions[:, 0] - t[0], positions[:, 1] - t[1])
            over = [i for i in np.nonzero(gaps <= self.camera_radius)[0]
                    if self.roles[i] == "networker"]
            if not any(reaches_root(int(i)) for i in over):
                return False
        return True

    def targets_found(self) -> int | None:
        return int(np.count_nonzero(self.found_step >= 0))  # building the overlays: ~50 us

    def overlays(self) -> dict[str, Any]:
        return {
            "targets": self.targets.tolist(),
            "targets_found": (self.found_step >= 0).tolist(),
            "belief_map": {"origin": [0.0, 0.0], "cell": self.field_size / self.cells,
                           "values": self.belief.tolist()},
            "rendezvous": list(self.rendezvous),
            "camera_radius": self.camera_radius,
            "relay_links": self.relay_links(),
            "roles": list(self.roles),
            "known_targets": [list(map(list, k)) for k in self.known_targets],
        }


def _dm(metres: float) -> int:
    return int(round(float(metres) * DM))


def _number_arg(call: HostCall, i: int) -> float | int | None:
    value = call.arg(i)
    if isinstance(value, bool) or not isinstance(value, int | float):
        call.fail("TYPE")
        return None
    return value
