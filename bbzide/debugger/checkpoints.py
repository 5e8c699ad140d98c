"""Checkpoints of a whole Simulation at a control-step boundary, restored in place.

Design: reverse stepping restores the swarm as it was at the start of a control step and
re-executes forward (the engine is deterministic: every random draw comes from generators
that are part of its state). A checkpoint holds

* each robot's `Robot.snapshot()` bytes (the VM room's own exact layout) and its
  `RobotState` bookkeeping (failure, failure step, labels);
* a deep copy of the rest of the engine's state and the world's (`Simulation.__dict__` and
  `World.__dict__` minus the robots, their firmware loops and the programs).

Restoring must keep every object identity that a host function closed over (a world's
host functions capture arrays such as `sim.leds` or the world's motor table, and each robot's
random generator), so a checkpoint is restored **in place**: arrays get their values copied
back, generators their bit-generator state, lists, dicts and plain objects their items and
attributes, recursively; only objects that cannot be refilled (a pymunk space and its
bodies, immutable values) are replaced, all from one fresh deep copy so the replaced objects
keep pointing at one another.
"""

from __future__ import annotations

import copy
from dataclasses import dataclass
from typing import Any

import numpy as np

#: Simulation attributes a checkpoint leaves alone: the robots (their VMs are snapshotted on
#: their own), the world (captured on its own), the groups and programs (never change during
#: a run), the robot factory, and the timings (wall-clock measurements, not state).
_ENGINE_SKIPPED = frozenset({"robots", "_steppers", "world", "groups", "_factory", "timings",
                             "turn_observer", "watch"})


class CheckpointError(RuntimeError):
    """A simulation whose robots cannot be snapshotted (a custom firmware loop)."""


@dataclass(frozen=True)
class Checkpoint:
    """The state of a Simulation at the start of control step `step`."""

    step: int
    robots: tuple[bytes | None, ...]
    robot_states: tuple[tuple[Any, Any, dict[str, Any]], ...]
    engine: dict[str, Any]
    world: dict[str, Any]


def capture(sim: Any) -> Checkpoint:
    """The simulation's state now (between two control steps)."""
    keep = _identities(sim)
    robots: list[bytes | None] = []
    for state in sim.robots:
        robot = state.robot
        if robot is None:
            robots.append(None)
        elif hasattr(robot, "snapshot"):
            robots.append(robot.snapshot())
        else:
            raise CheckpointError(f"robot {state.robot_id}'s firmware loop has no snapshot()")
    memo: dict[int, Any] = {id(obj): obj for obj in keep}
    engine_copy = _copy_attributes(sim, memo, _ENGINE_SKIPPED)
    world_copy = _copy_attributes(sim.world, memo, frozenset())
    states = tuple((s.failure, s.failure_step, dict(s._labels)) for s in sim.robots)
    return Checkpoint(sim.step_count, tuple(robots), states, engine_copy, world_copy)


def restore(sim: Any, checkpoint: Checkpoint) -> None:
    """Put `sim` back in the checkpoint's state (see the module doc: in place)."""
    keep = _identities(sim)
    memo = {id(obj): obj for obj in keep}
    engine, world = copy.deepcopy((checkpoint.engine, checkpoint.world), memo)
    skip = {id(obj) for obj in keep}
    _refill_attributes(sim, engine, skip, _ENGINE_SKIPPED)
    _refill_attributes(sim.world, world, skip, frozenset())
    for state, saved, (failure, failure_step, labels) in zip(
            sim.robots, checkpoint.robots, checkpoint.robot_states, strict=True):
        if saved is not None and state.robot is not None:
            state.robot.restore(saved)
        state.failure = failure
        state.failure_step = failure_step
        state._labels.clear()
        state._labels.update(labels)


def _copy_attributes(obj: Any, memo: dict[int, Any], left_alone: frozenset[str]
                     ) -> dict[str, Any]:
    """A deep copy of `obj`'s attributes (one memo: shared objects stay shared). An
    attribute that cannot be copied (a pymunk batch buffer: scratch memory the world refills
    before reading it, no state) is left out, and a restore leaves it as it is."""
    copied: dict[str, Any] = {}
    for name, value in vars(obj).items():
        if name in left_alone:
            continue
        try:
            copied[name] = copy.deepcopy(value, memo)
        except (TypeError, copy.Error):
            continue
    return copied


def _identities(sim: Any) -> list[Any]:
    """Objects a checkpoint never copies: the engine, the world, robots and programs."""
    keep: list[Any] = [sim, sim.world, sim.robots, sim._steppers, sim.groups]
    for state in sim.robots:
        keep.extend((state, state.robot, state.program, state.profile, state.group))
    keep.extend(s for s in sim._steppers if s is not None)
    return [obj for obj in keep if obj is not None]


def _refill_attributes(live: Any, saved: dict[str, Any], skip: set[int],
                       left_alone: frozenset[str]) -> None:
    current = vars(live)
    for name, value in saved.items():
        current[name] = _refill(current.get(name), value, skip)


def _refill(live: Any, saved: Any, skip: set[int]) -> Any:
    """`saved` put into `live` where `live` can take it (the same object is returned);
    otherwise `saved` itself (the caller stores it in `live`'s place)."""
    if live is saved or id(live) in skip:
        return live
    if type(live) is not type(saved):
        return saved
    if isinstance(live, np.ndarray):
        if live.shape == saved.shape and live.dtype == saved.dtype and live.flags.writeable:
            live[...] = saved
            return live
        return saved
    if isinstance(live, np.random.Generator):
        live.bit_generator.state = saved.bit_generator.state
        return live
    if isinstance(live, list):
        if len(live) == len(saved):
            for index, item in enumerate(saved):
                live[index] = _refill(live[index], item, skip)
        else:
            live[:] = saved
        return live
    if isinstance(live, dict):
        for key in [k for k in live if k not in saved]:
            del live[key]
        for key, item in saved.items():
            live[key] = _refill(live.get(key), item, skip)
        return live
    if type(live).__module__.split(".")[0] == "bbzide" and hasattr(live, "__dict__") \
            and not _frozen(live):
        _refill_attributes(live, vars(saved), skip, frozenset())
        return live
    return saved


def _frozen(obj: Any) -> bool:
    params = getattr(type(obj), "__dataclass_params__", None)
    return bool(params is not None and params.frozen)
