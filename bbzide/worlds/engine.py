"""The swarm engine: many BittyBuzz firmware loops stepped together in one world.

Design: one `Simulation` owns the per-robot arrays (positions, headings, LED colours), one
`Robot` (bbzide.vm.robot, the firmware loop around a VM) per robot that has a program, the
`Radio` and a `World` (geometry, host functions, sensors, physics). Every control step runs the
same fixed order, whatever the world:

    1. world.sense           sensor readings for this step
    2. deliver               the radio's deliveries due now, one `PackedMessages` table (rows
                             sorted by receiver; dead receivers' rows dropped and counted)
    3. control               `swarm_batch.control_steps(robots, deliveries, stepping)`: every
                             receiver's `receive_all`, then each live, awake robot's
                             control_step, in one call (the VM room may compile it); a robot
                             whose VM fails is marked (reason, pc, source line), sends
                             nothing more and stops
    4. radio                 the outbox -> send queues -> range, loss, bandwidth -> in flight
                             for latency steps
    5. world.advance         actuator commands and physics over one control period

Steps 2-4 handle a step's messages as columns (`PackedMessages`, bbzide/vm/swarm_batch.py),
never a Python object per message or a Python loop over robots: counters come from
`np.bincount`, who steps from the world's `asleep` array, and `links` (a list of id pairs)
is built from `link_indexes` only when someone reads it. `step_deliveries` keeps the table
handed to the robots (a recorder captures its inputs from it).

Randomness comes from one `numpy.random.Generator` per purpose (placement, radio loss, radio
noise, world, one per robot for its `rand` host function), all spawned from the run seed, so the
same seed gives the same trajectories and heaps, and adding a noise source does not change the
others' draws.

`asynchronous=True` gives each robot a random phase within the control period (real robots
are not synchronised): robots then run in phase order, each transmits right after its own
control step, and a message reaches a robot whose phase is later within the same step (the
others at the next step). Sensing and physics stay once per step.

Robots may differ (`RobotGroup`: program, profile, labels); a group without a program is a
passive body (a target) that the radio and the physics still see.

The UI reads `robots` (`RobotState`: pose, heading, led, failure, robot, robot_id, labels),
`links`, `step_count`, `world` (bounds, walls, robot_radius, comm_range) and `stats`; the names
are fixed in ARCHITECTURE.md ("worlds → ui").
"""

from __future__ import annotations

import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any, Protocol

import numpy as np

from bbzide.diagnostics import UserError
from bbzide.worlds.radio import Radio, TrafficCounters, WorldConfigError, take_rows
from bbzide.worlds.registry import WORLDS, create_world
from bbzide.worlds.world import HostFunction, RadioSettings, World

__all__ = [
    "WORLDS", "RobotGroup", "RobotState", "Simulation", "StepStats", "WorldConfigError",
]


class FirmwareLoop(Protocol):
    """What the engine needs of a robot's firmware (bbzide.vm.robot.Robot has all of it)."""

    failure: Any

    def boot(self) -> None: ...
    def receive(self, message: bytes, distance: float, azimuth: float,
                elevation: float) -> None: ...
    def control_step(self) -> list[bytes]: ...
    # optional: receive_all(deliveries) = receive(...) of each (sender, message, distance,
    # azimuth, elevation) in turn; used when present (bbzide.vm.robot.Robot has it)


#: Builds a firmware loop: (program, profile, robot_id, host_functions) -> FirmwareLoop.
RobotFactory = Callable[[Any, Any, int, Mapping[str, HostFunction]], FirmwareLoop]


@dataclass
class RobotGroup:
    """Robots that share a program and a profile (None program: a passive body)."""

    count: int
    program: Any = None                  # BittyBuzzProgram, CompiledProgram or None
    profile: Any = None                  # Profile or profile name; None: the world's
    labels: dict[str, Any] = field(default_factory=dict)   # e.g. {"role": "target"}


@dataclass
class StepStats:
    """Radio traffic of one control step, per robot (arrays indexed like `robots`) and total."""

    step: int
    sent: np.ndarray
    received: np.ndarray
    dropped: np.ndarray
    bytes_sent: np.ndarray
    bytes_received: np.ndarray

    @property
    def total_sent(self) -> int:
        return int(self.sent.sum())

    @property
    def total_received(self) -> int:
        return int(self.received.sum())

    @property
    def total_dropped(self) -> int:
        return int(self.dropped.sum())

    @property
    def total_bytes(self) -> int:
        return int(self.bytes_sent.sum())

    def as_dict(self) -> dict[str, int]:
        return {"step": self.step, "sent": self.total_sent, "received": self.total_received,
                "dropped": self.total_dropped, "bytes": self.total_bytes}


class RobotState:
    """One robot as the UI sees it: a view on the engine's arrays plus its firmware loop."""

    __slots__ = ("_sim", "index", "robot_id", "robot", "program", "profile", "_labels",
                 "failure", "failure_step", "group")

    def __init__(self, sim: Simulation, index: int, robot_id: int, group: RobotGroup,
                 profile: Any) -> None:
        self._sim = sim
        self.index = index
        self.robot_id = robot_id
        self.group = group
        self.program = group.program
        self.profile = profile
        self.robot: FirmwareLoop | None = None
        self._labels: dict[str, Any] = dict(group.labels)
        self.failure: Any = None
        self.failure_step: int | None = None

    @property
    def pose(self) -> tuple[float, float, float]:
        x, y, z = self._sim.positions[self.index]
        return (float(x), float(y), float(z))

    @property
    def heading(self) -> float:
        return float(self._sim.headings[self.index])

    @property
    def led(self) -> tuple[float, float, float]:
        r, g, b = self._sim.leds[self.index]
        return (float(r), float(g), float(b))

    @property
    def alive(self) -> bool:
        return self.robot is not None and self.failure is None

    @property
    def labels(self) -> dict[str, Any]:
        """Group and world labels, plus the watched script globals (read now, from the heap)."""
        labels = dict(self._labels)
        for name in self._sim.watch:
            if self.robot is not None:
                value = self.global_value(name)
                if value is not None:
                    labels[name] = value
        return labels

    def set_label(self, name: str, value: Any) -> None:
        """A label set by the world (e.g. "flying") or the engine."""
        self._labels[name] = value

    def global_value(self, name: str) -> Any:
        """The script global `name` decoded (int, float, string, None; tables/closures by
        kind), read from the VM heap; None when the robot has no VM or no such global."""
        robot = self.robot
        vm = getattr(robot, "vm", None)
        if vm is None:
            return None
        return read_global(vm, _bbo_program(self.program).strings, name)

    def __repr__(self) -> str:
        return f"RobotState(id={self.robot_id}, pose={self.pose}, failure={self.failure})"


def _bbo_program(program: Any) -> Any:
    """A CompiledProgram becomes its BittyBuzzProgram; anything else is taken as it is."""
    to_bbo = getattr(program, "to_bbo", None)
    return to_bbo() if callable(to_bbo) and not hasattr(program, "bbo") else program


def _default_robot_factory(instruction_budget: int | None, loop: str) -> RobotFactory:
    def build(program: Any, profile: Any, robot_id: int,
              host_functions: Mapping[str, HostFunction]) -> FirmwareLoop:
        from bbzide.vm.robot import Robot  # the VM room; imported late (bbzide --help stays fast)

        kwargs: dict[str, Any] = {"host_functions": host_functions, "loop": loop}
        if instruction_budget is not None:
            kwargs["instruction_budget"] = instruction_budget
        return Robot(program, profile, robot_id, **kwargs)

    return build


class Simulation:
    """A swarm in a world. `Simulation("kilobot", program, robots=25, seed=1).step()`."""

    def __init__(
        self,
        world: str | World,
        program: Any = None,
        robots: int | None = None,
        seed: int = 0,
        *,
        groups: Sequence[RobotGroup] | None = None,
        positions: np.ndarray | None = None,
        headings: np.ndarray | None = None,
        world_options: Mapping[str, Any] | None = None,
        radio: RadioSettings | Mapping[str, Any] | None = None,
        robot_factory: RobotFactory | None = None,
        instruction_budget: int | None = None,
        loop: str = "pop",
        watch: Sequence[str] = ("role",),
        asynchronous: bool = False,
    ) -> None:
        self.world: World = (create_world(world, **dict(world_options or {}))
                             if isinstance(world, str) else world)
        if isinstance(radio, RadioSettings):
            self.world.radio = radio
        elif radio:
            self.world.radio = _with_overrides(self.world.radio, radio)
        if groups is None:
            count = robots if robots is not None else _default_robots(self.world)
            groups = [RobotGroup(count=count, program=program)]
        self.groups = list(groups)
        self.count = sum(g.count for g in self.groups)
        self._check_count()
        self.seed = seed
        #: Script globals shown as labels (read only when `labels` is read).
        self.watch = tuple(watch)
        self.asynchronous = asynchronous
        self._initial_positions = None if positions is None else np.asarray(positions, float)
        self._initial_headings = None if headings is None else np.asarray(headings, float)
        self._factory = robot_factory or _default_robot_factory(instruction_budget, loop)
        self.timings: dict[str, float] = {"sense": 0.0, "vm": 0.0, "radio": 0.0, "physics": 0.0}
        #: None: the control phase is one `swarm_batch.control_steps` call (the fast path).
        #: Set (by bbzide/debugger): the robots take their turns one by one through their
        #: own methods (`swarm_batch`'s reference path, the same results), and the observer
        #: is called with the robot's index right after each robot's control step, on the
        #: thread running `step` (in lockstep and asynchronous runs alike).
        self.turn_observer: Callable[[int], None] | None = None
        self._reset_world()
        self._boot_all()

    # ---- set-up -----------------------------------------------------------------------------
    def _check_count(self) -> None:
        if self.count < 1 or any(g.count < 0 for g in self.groups):
            raise WorldConfigError(f"a swarm needs at least 1 robot, got {self.count}")
        fit = self.world.max_robots()
        if self.count > fit:
            width, height = self.world.size
            raise WorldConfigError(
                f"{self.count} robots do not fit in the {self.world.name} world "
                f"({width:g} m x {height:g} m holds at most {fit})")

    def _reset_world(self) -> None:
        streams = np.random.SeedSequence(self.seed).spawn(6)
        self.rng: dict[str, np.random.Generator] = {
            name: np.random.default_rng(s)
            for name, s in zip(("placement", "loss", "noise", "world"), streams[:4], strict=True)
        }
        self.robot_rngs = [np.random.default_rng(s) for s in streams[4].spawn(self.count)]
        #: Phase of each robot within a control step (0 in lockstep): its control step runs
        #: at time step_count + phase (in steps).
        self.phases = (np.random.default_rng(streams[5]).random(self.count)
                       if self.asynchronous else np.zeros(self.count))
        placed, turned = self.world.place(self.count, self.rng["placement"])
        if self._initial_positions is not None:
            placed = _checked_array(self._initial_positions, (self.count, 3), "positions")
        if self._initial_headings is not None:
            turned = _checked_array(self._initial_headings, (self.count,), "headings")
        self.positions = np.array(placed, dtype=np.float64)
        self.headings = np.array(turned, dtype=np.float64)
        self.leds = np.zeros((self.count, 3), dtype=np.float64)
        self.step_count = 0
        self._set_links(np.empty((0, 2), dtype=np.int64))
        self.stats = StepStats(0, *(np.zeros(self.count, dtype=np.int64) for _ in range(5)))
        self.totals = {"sent": 0, "received": 0, "dropped": 0, "bytes": 0}
        self.radio = Radio(self.world.radio, self.count, self.world.step_seconds,
                           self.rng["loss"], self.rng["noise"])
        #: The deliveries handed to the robots in the last step (receivers alive), as
        #: `swarm_batch.control_steps` got them (a recorder captures its inputs from them).
        self.step_deliveries = self.radio.due(-1)
        #: What the robots sent in the last step (rows by sender, out-queue order; a robot
        #: that failed during its step sends nothing): the inspector's "table being sent".
        self.step_outbox = self.step_deliveries
        #: alive[i]: robot i has a firmware loop that has not failed (`RobotState.alive`)
        self._alive = np.zeros(self.count, dtype=bool)
        #: What `control_steps` steps: each robot's firmware loop (an adapter when it has no
        #: `receive_all`), None for a passive body
        self._steppers: list[Any] = [None] * self.count
        self.robots: list[RobotState] = []
        index = 0
        for group in self.groups:
            profile = _profile(group.profile or self.world.profile_name)
            for _ in range(group.count):
                self.robots.append(RobotState(self, index, index, group, profile))
                index += 1
        self._ids = np.array([s.robot_id for s in self.robots], dtype=np.int64)
        self.world.attach(self)

    def _boot_all(self) -> None:
        started = time.perf_counter()
        for state in self.robots:
            self._boot(state)
        self.timings["vm"] += time.perf_counter() - started

    def _boot(self, state: RobotState) -> None:
        state.failure = None
        state.failure_step = None
        state.robot = None
        self._steppers[state.index] = None
        self._alive[state.index] = False
        if state.program is None:
            return
        program = _bbo_program(state.program)
        state.program = program          # converted once (global_value reads its strings)
        functions = self.world.host_functions(self, state.index)
        robot = self._factory(program, state.profile, state.robot_id, functions)
        state.robot = robot
        self._steppers[state.index] = (robot if hasattr(robot, "receive_all")
                                       else _ReceiveOneByOne(robot))
        self._alive[state.index] = True
        robot.boot()
        self._check_failure(state)

    def _check_failure(self, state: RobotState) -> None:
        robot = state.robot
        if robot is not None and robot.failure is not None and state.failure is None:
            state.failure = robot.failure
            state.failure_step = self.step_count
            self._alive[state.index] = False

    # ---- running ----------------------------------------------------------------------------
    def step(self) -> StepStats:
        """One control step of every robot, the radio and the physics."""
        if self.asynchronous:
            return self._step_asynchronous()
        from bbzide.vm import swarm_batch  # the VM room (late: `bbzide --help` stays fast)

        step = self.step_count
        count = self.count
        counters = TrafficCounters.zeros(count)
        clock = time.perf_counter
        world, radio = self.world, self.radio
        t0 = clock()
        world.sense(self)
        t1 = clock()
        deliveries = radio.due(step)
        alive = self._alive
        if len(deliveries):
            to_alive = alive[deliveries.robots]
            if not to_alive.all():      # dead receivers and passive bodies: dropped
                counters.dropped += np.bincount(deliveries.robots[~to_alive], minlength=count)
                deliveries = take_rows(deliveries, to_alive)
            counters.received += np.bincount(deliveries.robots, minlength=count)
            counters.bytes_received += np.bincount(
                deliveries.robots, weights=deliveries.lengths, minlength=count).astype(np.int64)
        self.step_deliveries = deliveries
        stepping = alive & ~world.asleep(step, count)
        t2 = clock()
        observer = self.turn_observer
        if observer is None:
            result = swarm_batch.control_steps(self._steppers, deliveries, stepping)
        else:
            result = swarm_batch.control_steps_reference(
                [None if s is None else _ObservedTurn(s, i, observer)
                 for i, s in enumerate(self._steppers)], deliveries, stepping)
        t3 = clock()
        outbox = result.outbox
        failed = result.failed
        if failed.any():
            robots = self.robots
            for index in np.flatnonzero(failed).tolist():
                self._check_failure(robots[index])
            if len(outbox):             # a robot that failed in its step sends nothing
                outbox = take_rows(outbox, ~failed[outbox.robots])
        self.step_outbox = outbox
        radio.queue_outbox(outbox, counters)
        self._set_links(radio.transmit(step, self.positions, self.headings, self._alive,
                                       counters))
        t4 = clock()
        world.advance(self, world.step_seconds)
        t5 = clock()
        timings = self.timings
        timings["sense"] += t1 - t0
        timings["vm"] += t3 - t2
        timings["radio"] += (t2 - t1) + (t4 - t3)
        timings["physics"] += t5 - t4
        return self._finish_step(step, counters)

    @property
    def links(self) -> list[tuple[int, int]]:
        """(sender id, receiver id) of each link that carried a message in the last step,
        sorted; built from `link_indexes` when read (the engine itself never needs it)."""
        if self._links is None:
            pairs = self.link_indexes
            ids = self._ids
            self._links = list(zip(ids[pairs[:, 0]].tolist(), ids[pairs[:, 1]].tolist(),
                                   strict=True))
        return self._links

    def _set_links(self, pairs: np.ndarray) -> None:
        #: (M, 2) int64: (sender index, receiver index) of the last step's links, sorted
        self.link_indexes = pairs
        self._links: list[tuple[int, int]] | None = None

    def _step_asynchronous(self) -> StepStats:
        """One control step with robots in phase order (see the module docstring)."""
        step = self.step_count
        counters = TrafficCounters.zeros(self.count)
        clock = time.perf_counter
        world, radio, robots = self.world, self.radio, self.robots
        t0 = clock()
        world.sense(self)
        t1 = clock()
        radio.begin_step(step, self.positions, self.headings, self._alive.copy())
        vm_time = 0.0
        sent: list[tuple[int, int, bytes, float, float, float]] = []
        for index in np.argsort(self.phases, kind="stable").tolist():
            state = robots[index]
            now = step + float(self.phases[index])
            deliveries = radio.take_due(index, now)
            started = clock()
            if deliveries:
                if state.alive:
                    for _, message, distance, azimuth, elevation in deliveries:
                        state.robot.receive(message, distance, azimuth, elevation)
                        counters.bytes_received[index] += len(message)
                    counters.received[index] += len(deliveries)
                else:
                    counters.dropped[index] += len(deliveries)
            if state.alive and not world.is_asleep(index, step):
                outgoing = state.robot.control_step()
                if self.turn_observer is not None:
                    self.turn_observer(index)
                if state.robot.failure is not None:
                    self._check_failure(state)
                elif outgoing:
                    radio.enqueue(index, outgoing, counters)
                    sent.extend((index, index, message, 0.0, 0.0, 0.0) for message in outgoing)
            vm_time += clock() - started
            radio.send_from(index, now, counters)
        self._set_links(radio.step_links())
        from bbzide.vm.swarm_batch import PackedMessages  # the VM room (late, as above)
        sent.sort(key=lambda row: row[0])  # stable: each robot's messages keep their order
        self.step_outbox = PackedMessages.from_rows(sent)
        t2 = clock()
        world.advance(self, world.step_seconds)
        t3 = clock()
        timings = self.timings
        timings["sense"] += t1 - t0
        timings["vm"] += vm_time
        timings["radio"] += (t2 - t1) - vm_time
        timings["physics"] += t3 - t2
        return self._finish_step(step, counters)

    def _finish_step(self, step: int, counters: TrafficCounters) -> StepStats:
        self.stats = StepStats(step, counters.sent, counters.received, counters.dropped,
                               counters.bytes_sent, counters.bytes_received)
        self.totals["sent"] += self.stats.total_sent
        self.totals["received"] += self.stats.total_received
        self.totals["dropped"] += self.stats.total_dropped
        self.totals["bytes"] += self.stats.total_bytes
        self.step_count = step + 1
        return self.stats

    def run(self, steps: int) -> None:
        for _ in range(steps):
            self.step()

    # ---- programs and queries ---------------------------------------------------------------
    def load_program(self, program: Any, keep_state: bool = True) -> None:
        """Reboot every programmed robot on `program`; keep the world as it is or reset it."""
        for group in self.groups:
            if group.program is not None:
                group.program = program
        for state in self.robots:
            state.program = state.group.program
        if not keep_state:
            self._reset_world()
        else:
            # Rebooted robots: messages in the air are lost, LEDs go dark, the world rebuilds
            # its per-robot actuator state from where the bodies are now.
            self.radio = Radio(self.world.radio, self.count, self.world.step_seconds,
                               self.rng["loss"], self.rng["noise"])
            self.leds[:] = 0.0
            self.world.attach(self)
        self._boot_all()

    @property
    def time(self) -> float:
        """Simulated seconds since the start."""
        return self.step_count * self.world.step_seconds

    @property
    def failures(self) -> list[RobotState]:
        return [s for s in self.robots if s.failure is not None]

    def state_of(self, robot_id: int) -> RobotState:
        for state in self.robots:
            if state.robot_id == robot_id:
                return state
        raise KeyError(robot_id)


class _ReceiveOneByOne:
    """A firmware loop without `receive_all` seen through one (what `control_steps` calls):
    its `receive` for each delivery in turn, the rest passed through."""

    __slots__ = ("robot",)

    def __init__(self, robot: FirmwareLoop) -> None:
        self.robot = robot

    @property
    def failure(self) -> Any:
        return self.robot.failure

    def receive_all(self, deliveries: Sequence[tuple[Any, bytes, float, float, float]]
                    ) -> None:
        receive = self.robot.receive
        for _, message, distance, azimuth, elevation in deliveries:
            receive(message, distance, azimuth, elevation)

    def control_step(self) -> list[bytes]:
        return self.robot.control_step()


class _ObservedTurn:
    """A stepper whose control step is followed by the engine's `turn_observer` (the
    debugger's view of "this robot's turn is over"); receiving is passed through."""

    __slots__ = ("stepper", "index", "observer")

    def __init__(self, stepper: Any, index: int, observer: Callable[[int], None]) -> None:
        self.stepper = stepper
        self.index = index
        self.observer = observer

    @property
    def failure(self) -> Any:
        return self.stepper.failure

    def receive_all(self, deliveries: Sequence[tuple[Any, bytes, float, float, float]]
                    ) -> None:
        self.stepper.receive_all(deliveries)

    def control_step(self) -> list[bytes]:
        sent = self.stepper.control_step()
        self.observer(self.index)
        return sent


def read_global(vm: Any, strings: list[str], name: str) -> Any:
    """A global of a VM, decoded from its heap (see `RobotState.global_value`)."""
    from bbzide.compiler import bbzfloat
    from bbzide.vm import heap
    from bbzide.vm.inspector import globals_by_name

    index = globals_by_name(vm, strings).get(name)
    if index is None:
        return None
    h = vm.heap
    kind = h.obj_type(index)
    if kind == heap.INT:
        return h.int_value(index)
    if kind == heap.FLOAT:
        return bbzfloat.to_float(h.u16(index))
    if kind == heap.STRING:
        sid = h.u16(index)
        return strings[sid] if sid < len(strings) else sid
    if kind == heap.TABLE:
        return "table"
    if kind == heap.CLOSURE:
        return "closure"
    return None


def _profile(profile: Any) -> Any:
    if not isinstance(profile, str):
        return profile
    from bbzide.vm.profiles import PROFILES

    try:
        return PROFILES[profile]
    except KeyError:
        raise UserError(f"unknown platform profile {profile!r}; "
                        f"choose one of {', '.join(sorted(PROFILES))}") from None


def _default_robots(world: World) -> int:
    spec = WORLDS.get(world.name)
    return spec.default_robots if spec else 1


def _with_overrides(settings: RadioSettings, overrides: Mapping[str, Any]) -> RadioSettings:
    import dataclasses

    known = {f.name for f in dataclasses.fields(RadioSettings)}
    unknown = sorted(set(overrides) - known)
    if unknown:
        raise WorldConfigError(f"unknown radio setting(s) {', '.join(unknown)}; "
                               f"known: {', '.join(sorted(known))}")
    return dataclasses.replace(settings, **overrides)


def _checked_array(values: np.ndarray, shape: tuple[int, ...], what: str) -> np.ndarray:
    if values.shape != shape:
        raise WorldConfigError(f"{what} must have shape {shape}, got {values.shape}")
    return values
