"""The Kilobot table: 33 mm vibration-driven discs on a walled table (pymunk 2D).

Design: every Kilobot is a pymunk dynamic disc; each control step sets its velocity from the two
vibration motors (both on: forward; left only: turn clockwise; right only: counter-clockwise,
as a Kilobot pivots about the leg whose motor is off) plus a little heading noise (the real
robots wander), and pymunk resolves the collisions with the other discs and the table walls.
The engine's position/heading arrays are copied from the bodies after each step.

Facts used (K-Team Kilobot, BittyBuzz `src/kilobot`): diameter 33 mm; about 1 cm/s forward and
about 45°/s turning; RGB LED with 2 bits per channel (`RGB(r,g,b)` in 0..3) and BittyBuzz's
`led(c)` lighting red/green/blue at full intensity for bits 0/1/2 of c; IR messages of 9 payload
bytes within about 10 cm, each with a distance estimate in millimetres and no bearing; a 10-bit
ambient light sensor; `delay(ms)` blocks the main loop. The host functions `led`, `set_motor`,
`delay`, `abs` are the BittyBuzz Kilobot firmware's; `rand` (kilolib `rand_soft`, 0..255),
`light` (ambient light, 0..1023) and `motion` (0 stop, 1 forward, 2 left, 3 right, kilolib's
names) are ours.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from typing import TYPE_CHECKING, Any

import numpy as np
import pymunk
import pymunk.batch

from bbzide.vm.host import LatchedHostFunction
from bbzide.worlds.radio import WorldConfigError
from bbzide.worlds.registry import KILOBOT_HOST_NAMES
from bbzide.worlds.world import HostFunction, RadioSettings, World

if TYPE_CHECKING:
    from bbzide.vm.host import HostCall
    from bbzide.worlds.engine import Simulation

KILOBOT_RADIUS = 0.0165          # m: the 33 mm disc
FORWARD_SPEED = 0.01             # m/s: a calibrated Kilobot walks about 1 cm/s
TURN_RATE = math.pi / 4          # rad/s: about 45 degrees per second when pivoting
IR_RANGE = 0.10                  # m: IR messages reach about 10 cm (centre to centre)
LIGHT_MAX = 1023                 # the 10-bit ADC of the ambient light sensor
#: Default spacing of the initial lattice: 5 cm, half the IR range, so each robot hears its
#: 4-8 lattice neighbours and the swarm is connected.
LATTICE_SPACING = 0.05
#: Control period. Kilobot's kilolib main loop and message slots run at a few Hz; 0.1 s keeps
#: one message per robot per step (the IR channel's bandwidth, see `RadioSettings`).
STEP_SECONDS = 0.1
#: Heading noise of the vibration drive, rad per sqrt(s): enough to make straight runs curve
#: over tens of centimetres, as real Kilobots do.
MOTION_NOISE = 0.05
#: Physics sub-steps per control step: 0.1 s / 4 = 25 ms, so a 1 cm/s robot moves 0.25 mm per
#: sub-step, far below the 16.5 mm radius (no tunnelling).
SUBSTEPS = 4

#: Overlap pymunk tolerates between touching discs, m: 0.1 mm, a fraction of a percent of the
#: 33 mm disc (pymunk's default, 0.1, is meant for pixels).
COLLISION_SLOP = 1e-4

#: The body fields `advance` writes (velocities) and reads back (poses), each body's values in
#: this order in pymunk.batch's buffers: (vx, vy, angular velocity), (x, y, angle).
VELOCITY_FIELDS = pymunk.batch.BodyFields.VELOCITY | pymunk.batch.BodyFields.ANGULAR_VELOCITY
POSE_FIELDS = pymunk.batch.BodyFields.POSITION | pymunk.batch.BodyFields.ANGLE

#: Motors (left on, right on) of each `motion` code (kilolib: STOP, FORWARD, LEFT, RIGHT).
MOTION_MOTORS = {0: (0, 0), 1: (1, 1), 2: (0, 1), 3: (1, 0)}

LightField = Callable[[np.ndarray, np.ndarray], np.ndarray]


def light_field(kind: str | LightField, bounds: tuple[float, float, float, float]) -> LightField:
    """Ambient light (0..1023) as a function of x, y arrays.

    "gradient": dark at the left wall, bright at the right; "spot": a lamp over the centre
    (Gaussian, sigma a quarter of the table width); "uniform": half brightness everywhere.
    """
    if callable(kind):
        return kind
    x0, y0, x1, y1 = bounds
    if kind == "gradient":
        return lambda x, y: LIGHT_MAX * np.clip((x - x0) / (x1 - x0), 0.0, 1.0)
    if kind == "spot":
        cx, cy, sigma = (x0 + x1) / 2, (y0 + y1) / 2, (x1 - x0) / 4
        return lambda x, y: LIGHT_MAX * np.exp(-((x - cx) ** 2 + (y - cy) ** 2) / (2 * sigma**2))
    if kind == "uniform":
        return lambda x, y: np.full(np.shape(x), LIGHT_MAX / 2)
    raise WorldConfigError(f"unknown light field {kind!r}; choose gradient, spot or uniform")


class KilobotTable(World):
    """A rectangular table with walls, centred on the origin."""

    name = "kilobot"
    profile_name = "kilobot"
    host_names = KILOBOT_HOST_NAMES
    step_seconds = STEP_SECONDS
    robot_radius = KILOBOT_RADIUS
    robot_height = 0.0

    def __init__(
        self,
        width: float = 1.0,
        height: float = 1.0,
        light: str | LightField = "gradient",
        comm_range: float = IR_RANGE,
        loss: float = 0.05,
        distance_noise: float = 0.03,
        motion_noise: float = MOTION_NOISE,
        spacing: float = LATTICE_SPACING,
        layout: str = "lattice",
    ) -> None:
        if width <= 2 * KILOBOT_RADIUS or height <= 2 * KILOBOT_RADIUS:
            raise WorldConfigError(f"a {width} m x {height} m table cannot hold a Kilobot")
        if spacing < 2 * KILOBOT_RADIUS:
            raise WorldConfigError(f"lattice spacing {spacing} m is less than a Kilobot (33 mm)")
        bounds = (-width / 2, -height / 2, width / 2, height / 2)
        # Kilobot IR: 1 payload per transmission slot, distance in mm, no bearing; the
        # ~5 % loss is a calm table (BittyBuzz's authors saw far more under saturation).
        radio = RadioSettings(
            comm_range=comm_range, loss_probability=loss, messages_per_step=1,
            send_queue_cap=10, distance_noise=distance_noise, has_bearing=False,
            distance_unit=1000.0,
        )
        super().__init__(bounds, radio)
        self.light_kind = light
        self.light = light_field(light, bounds)
        self.motion_noise = motion_noise
        self.spacing = spacing
        if layout not in ("lattice", "random"):
            raise WorldConfigError(f"unknown layout {layout!r}: lattice or random")
        self.layout = layout

    # ---- geometry and placement ---------------------------------------------------------------
    def place(self, count: int, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
        """A square lattice around the centre (spacing shrunk if needed), jittered, shuffled;
        or ("random" layout) scattered uniformly over the table without overlaps."""
        if self.layout == "random":
            return self._scatter(count, rng)
        width, height = self.size
        margin = 2 * KILOBOT_RADIUS
        side = math.ceil(math.sqrt(count))
        spacing = self.spacing
        usable = min(width, height) - margin
        if (side - 1) * spacing > usable:
            spacing = max(2 * KILOBOT_RADIUS * 1.05, usable / max(side - 1, 1))
        columns = max(1, min(side, int((width - margin) // spacing) + 1))
        rows = math.ceil(count / columns)
        ix, iy = np.meshgrid(np.arange(columns), np.arange(rows))
        cells = np.column_stack([ix.ravel(), iy.ravel()])[:count].astype(np.float64)
        cx, cy = (self.bounds[0] + self.bounds[2]) / 2, (self.bounds[1] + self.bounds[3]) / 2
        xy = (cells - [(columns - 1) / 2, (rows - 1) / 2]) * spacing + [cx, cy]
        jitter = (spacing - 2 * KILOBOT_RADIUS) * 0.25
        xy += rng.uniform(-jitter, jitter, xy.shape)
        xy = xy[rng.permutation(count)]
        positions = np.column_stack([xy, np.zeros(count)])
        headings = rng.uniform(-math.pi, math.pi, count)
        return positions, headings

    def _scatter(self, count: int, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
        x0, y0, x1, y1 = self.bounds
        margin = KILOBOT_RADIUS * 1.1
        placed = np.empty((0, 2))
        # Rejection sampling in batches; 200 rounds is far more than a table at half the
        # packing density needs (denser requests fall back to the lattice).
        for _ in range(200):
            if len(placed) >= count:
                break
            batch = rng.uniform([x0 + margin, y0 + margin], [x1 - margin, y1 - margin],
                                (count, 2))
            for point in batch:
                if len(placed) >= count:
                    break
                if len(placed) == 0 or np.min(np.hypot(*(placed - point).T)) > 2.1 * KILOBOT_RADIUS:
                    placed = np.vstack([placed, point])
        if len(placed) < count:
            raise WorldConfigError(f"{count} Kilobots are too many to scatter on this table; "
                                   "use the lattice layout")
        positions = np.column_stack([placed, np.zeros(count)])
        return positions, rng.uniform(-math.pi, math.pi, count)

    def max_robots(self) -> int:
        # Square packing with 5 % slack between discs (the physics needs a little room).
        pitch = 2 * KILOBOT_RADIUS * 1.05
        width, height = self.size
        return int((width - 2 * KILOBOT_RADIUS) // pitch + 1) * int(
            (height - 2 * KILOBOT_RADIUS) // pitch + 1)

    # ---- bodies -------------------------------------------------------------------------------
    def attach(self, sim: Simulation) -> None:
        count = sim.count
        self.motors = np.zeros((count, 2), dtype=np.int64)       # duty of left, right (0..255)
        self.sleep_until = np.full(count, -1, dtype=np.int64)    # last step spent in `delay`
        self.light_readings = np.zeros(count, dtype=np.int64)
        self.space = pymunk.Space()
        self.space.gravity = (0.0, 0.0)
        # pymunk's defaults assume pixels: 0.1 of allowed overlap would be 10 cm here.
        self.space.collision_slop = COLLISION_SLOP
        for (a, b) in self.walls:
            wall = pymunk.Segment(self.space.static_body, a, b, 0.002)
            wall.friction = 0.0
            wall.elasticity = 0.0
            self.space.add(wall)
        self.bodies: list[pymunk.Body] = []
        # Mass 16.5 g (a Kilobot's), moment of a uniform disc.
        mass = 0.0165
        moment = pymunk.moment_for_circle(mass, 0, KILOBOT_RADIUS)
        for i in range(count):
            body = pymunk.Body(mass, moment)
            body.position = (float(sim.positions[i, 0]), float(sim.positions[i, 1]))
            body.angle = float(sim.headings[i])
            shape = pymunk.Circle(body, KILOBOT_RADIUS)
            shape.friction = 0.0
            shape.elasticity = 0.0
            self.space.add(body, shape)
            self.bodies.append(body)
        self._batch_bodies()

    def _batch_bodies(self) -> None:
        """Set up `advance`'s batched access to the bodies (pymunk.batch: one call writes
        every velocity, one reads every pose, instead of a Python attribute access per body
        and step — 1,000 Kilobots: ~5 ms a step). pymunk visits the space's bodies in its
        own order: the dynamic ones in the order they were added (ours, robot by robot),
        then the static body of the walls; checked here by body id, and without that order
        `advance` goes body by body."""
        found = pymunk.batch.Buffer()
        pymunk.batch.get_space_bodies(self.space, pymunk.batch.BodyFields.BODY_ID, found)
        ids = np.frombuffer(found.int_buf(), dtype=np.uintp)
        count = len(self.bodies)
        ours = np.array([body.id for body in self.bodies], dtype=np.uintp)
        self._batched = len(ids) >= count and np.array_equal(ids[:count], ours)
        #: (visited bodies, 3) float64 written to pymunk: our bodies' rows first, then the
        #: rows of the static bodies after them, left at zero (they do not move)
        self._velocities = np.zeros((len(ids), 3), dtype=np.float64)
        self._velocity_buffer = pymunk.batch.Buffer()
        self._velocity_buffer.set_float_buf(self._velocities.reshape(-1))
        self._pose_buffer = pymunk.batch.Buffer()

    # ---- host functions -----------------------------------------------------------------------
    def host_functions(self, sim: Simulation, index: int) -> Mapping[str, HostFunction]:
        rng = sim.robot_rngs[index]
        leds = sim.leds
        self._leds = leds  # where _apply_led_latches writes (the same array for every robot)
        motors = self.motors
        world = self

        def led(call: HostCall) -> None:
            if not call.expect_args(1):
                return
            color = _int_arg(call, 1)
            if color is None:
                return
            leds[index] = ((color & 1) != 0, (color & 2) != 0, (color & 4) != 0)

        def set_motor(call: HostCall) -> None:
            if not call.expect_args(2):
                return
            left, right = _int_arg(call, 1), _int_arg(call, 2)
            if left is None or right is None:
                return
            motors[index] = (max(0, min(255, left)), max(0, min(255, right)))

        def motion(call: HostCall) -> None:
            if not call.expect_args(1):
                return
            kind = _int_arg(call, 1)
            if kind is None:
                return
            if kind not in MOTION_MOTORS:
                call.fail("OUTOFRANGE")
                return
            motors[index] = [255 * m for m in MOTION_MOTORS[kind]]

        def delay(call: HostCall) -> None:
            if not call.expect_args(1):
                return
            ms = _int_arg(call, 1)
            if ms is None:
                return
            skipped = (ms & 0xFFFF) // round(world.step_seconds * 1000)
            world.sleep_until[index] = sim.step_count + skipped

        def absolute(call: HostCall) -> None:
            if not call.expect_args(1):
                return
            value = _int_arg(call, 1)
            if value is None:
                return
            call.ret(value if value == -32768 else abs(value))   # int16: abs(-32768) wraps

        def random_byte(call: HostCall) -> None:
            call.ret(int(rng.integers(0, 256)))

        def ambient_light(call: HostCall) -> None:
            call.ret(int(world.light_readings[index]))

        # led's only effect is this robot's LED colour: a latched host function, which a
        # compiled swarm step runs without leaving machine code (vm/host.py)
        return {"led": LatchedHostFunction(led, 1, index, self._apply_led_latches),
                "set_motor": set_motor, "delay": delay, "abs": absolute,
                "rand": random_byte, "light": ambient_light, "motion": motion}

    def _apply_led_latches(self, targets: np.ndarray, values: np.ndarray) -> None:
        """``led(color)`` of robots ``targets`` (their last call's int argument each), as
        the host function stores it."""
        color = values[:, 0]
        self._leds[targets] = np.stack(((color & 1) != 0, (color & 2) != 0,
                                        (color & 4) != 0), axis=1)

    def is_asleep(self, index: int, step: int) -> bool:
        return step <= self.sleep_until[index]

    def asleep(self, step: int, count: int) -> np.ndarray:
        return step <= self.sleep_until

    # ---- sensors and physics ------------------------------------------------------------------
    def sense(self, sim: Simulation) -> None:
        x, y = sim.positions[:, 0], sim.positions[:, 1]
        # ±4 counts of sensor noise (a few LSB of the 10-bit ADC).
        noise = sim.rng["world"].integers(-4, 5, sim.count)
        self.light_readings = np.clip(np.round(self.light(x, y)) + noise, 0, LIGHT_MAX).astype(
            np.int64)

    def advance(self, sim: Simulation, dt: float) -> None:
        left = self.motors[:, 0] > 0
        right = self.motors[:, 1] > 0
        forward = np.where(left & right, FORWARD_SPEED, 0.0)
        turn = np.where(left & ~right, -TURN_RATE, np.where(right & ~left, TURN_RATE, 0.0))
        moving = left | right
        noise = sim.rng["world"].normal(0.0, self.motion_noise / math.sqrt(dt), sim.count)
        turn = turn + np.where(moving, noise, 0.0)
        headings = sim.headings
        vx = forward * np.cos(headings)
        vy = forward * np.sin(headings)
        if not self._batched:
            self._advance_body_by_body(sim, dt, vx, vy, turn)
            return
        count = sim.count
        velocities = self._velocities
        velocities[:count, 0] = vx
        velocities[:count, 1] = vy
        velocities[:count, 2] = turn
        pymunk.batch.set_space_bodies(self.space, VELOCITY_FIELDS, self._velocity_buffer)
        sub = dt / SUBSTEPS
        for _ in range(SUBSTEPS):
            self.space.step(sub)
        poses = self._pose_buffer
        poses.clear()
        pymunk.batch.get_space_bodies(self.space, POSE_FIELDS, poses)
        rows = np.frombuffer(poses.float_buf(), dtype=np.float64).reshape(-1, 3)[:count]
        sim.positions[:, :2] = rows[:, :2]
        np.copyto(headings, np.pi - np.mod(np.pi - rows[:, 2], 2 * np.pi))

    def _advance_body_by_body(self, sim: Simulation, dt: float, vx: np.ndarray,
                              vy: np.ndarray, turn: np.ndarray) -> None:
        """`advance` through each body's attributes (when pymunk's batch order is not ours)."""
        for i, body in enumerate(self.bodies):
            body.velocity = (float(vx[i]), float(vy[i]))
            body.angular_velocity = float(turn[i])
        sub = dt / SUBSTEPS
        for _ in range(SUBSTEPS):
            self.space.step(sub)
        positions, headings = sim.positions, sim.headings
        for i, body in enumerate(self.bodies):
            px, py = body.position
            positions[i, 0] = px
            positions[i, 1] = py
            headings[i] = body.angle
        np.copyto(headings, np.pi - np.mod(np.pi - headings, 2 * np.pi))

    def overlays(self) -> dict[str, Any]:
        """The light field sampled on a 32 x 32 raster (enough to draw a smooth gradient)."""
        x0, y0, x1, y1 = self.bounds
        xs, ys = np.meshgrid(np.linspace(x0, x1, 32), np.linspace(y0, y1, 32))
        return {"light": {"bounds": self.bounds, "values": self.light(xs, ys) / LIGHT_MAX}}


def _int_arg(call: HostCall, i: int) -> int | None:
    """Argument i as an int; anything else is a TYPE error (the firmware reads `i.value`)."""
    value = call.arg(i)
    if isinstance(value, bool) or not isinstance(value, int):
        call.fail("TYPE")
        return None
    return value
