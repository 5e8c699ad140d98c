"""A recording's swarm from a recorded step on, as a stand-in `Simulation` that a debugger drives.

Design: the debugger room's `SwarmDebugger` drives a `Simulation` through a few members:
`robots` (states with `robot`, `program`, `robot_id`, `index`, `failure`), `step()`,
`step_count`, `turn_observer`, `state_of`, and checkpoints (`debugger/checkpoints.py` snapshots
each robot and copies the other attributes of the engine and of its `world`). `RecordedSwarm`
has those members. Its world is the recording: a step hands every robot the messages it
received in that recorded step, then gives each robot its turn in index order (the engine's
lockstep order), its host calls answered as recorded, and calls `turn_observer` after each
turn. So its VMs go through the live swarm's states byte for byte, and a debugger's stops in
it are the live ones; nothing moves (positions are the recording's to draw).

The robots are scratch copies handed over by a rebuilder of their own: the recording is only
read. What a checkpoint must not copy (the recording, the replaying host functions) is reached
through plain functions, which a deep copy shares. Limits: the swarm ends at the recording's
last step; a robot that boots another program inside the span (a reboot, a reload) stops it
there with a `RecordingError`; an asynchronous run's turn order (random phases) is not in a
recording, so turns are taken in index order.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from bbzide.recording.input_log import ReplayDivergence, replay_control_step, replay_receive
from bbzide.recording.reader import Recording
from bbzide.recording.rebuild import RobotRebuilder
from bbzide.recording.recorder import RecordingError


@dataclass(eq=False)
class RecordedRobotState:
    """One robot of a `RecordedSwarm`, with the members of the engine's `RobotState` that a
    debugger and a checkpoint read."""

    index: int
    robot_id: int
    robot: Any  # the rebuilt firmware loop; None for a passive body
    program: Any
    profile: Any = None
    group: Any = None
    failure: Any = None
    failure_step: int | None = None
    _labels: dict[str, Any] = field(default_factory=dict)


class RecordedWorld:
    """The world a checkpoint copies: a recording's world has no state of its own."""

    def __init__(self, name: str) -> None:
        self.name = name


class RecordedSwarm:
    """Robot states of `recording` at recorded `step` (after it), stepped through the
    recorded steps after it."""

    asynchronous = False

    def __init__(self, recording: Recording, step: int,
                 program_for: Callable[[int, Any], Any] | None = None) -> None:
        """`program_for(program id, recorded program)`: the program a debugger maps lines
        with (e.g. the recorded source compiled again, with its call sites)."""
        recording.row(step)  # a RecordingError for a step outside the recording
        rebuilder = RobotRebuilder(recording)
        ids = [int(i) for i in recording.meta["robot_ids"]]
        hosts: dict[int, Any] = {}
        self.robots: list[RecordedRobotState] = []
        for index, robot_id in enumerate(ids):
            if not rebuilder.has_vm(index):
                self.robots.append(RecordedRobotState(index, robot_id, None, None))
                continue
            robot, hosts[index] = rebuilder.scratch_robot(index, step)
            program = rebuilder.program_at(index, step)
            if program_for is not None:
                program = program_for(rebuilder.keyframe(index, step).program, program)
            state = RecordedRobotState(index, robot_id, robot, program)
            if getattr(robot, "failure", None) is not None:
                state.failure = robot.failure
            self.robots.append(state)
        self.world = RecordedWorld(str(recording.meta.get("world", "")))
        self._steppers: list[Any] = []
        self.groups: list[Any] = []
        self.count = len(self.robots)
        self.step_count = step
        self.last_step = recording.last_step
        self.turn_observer: Callable[[int], None] | None = None
        # reached through functions, which a checkpoint's deep copy shares, not copies
        self._inputs: Callable[[int, int], Any] = \
            lambda at, index: rebuilder.inputs(at, index)
        self._host: Callable[[int], Any] = lambda index: hosts[index]
        self._program_id: Callable[[int, int], int] = \
            lambda index, at: rebuilder.keyframe(index, at).program
        self._started_with = {index: self._program_id(index, step) for index in hosts}

    def state_of(self, robot_id: int) -> RecordedRobotState:
        for state in self.robots:
            if state.robot_id == robot_id:
                return state
        raise KeyError(robot_id)

    def step(self) -> None:
        """The next recorded step: every robot's messages, then every robot's turn."""
        before = self.step_count
        recorded = before + 1
        if recorded > self.last_step:
            raise RecordingError(f"the recording ends at step {self.last_step}")
        inputs = {}
        for state in self.robots:
            if state.robot is None:
                continue
            if self._program_id(state.index, recorded) != self._started_with[state.index]:
                raise RecordingError(f"robot {state.robot_id} runs another program from "
                                     f"recorded step {recorded} on: stepping stops there")
            inputs[state.index] = self._inputs(recorded, state.index)
        for index, given in inputs.items():
            if given is not None:
                replay_receive(self.robots[index].robot, given)
        for index, given in inputs.items():
            state = self.robots[index]
            if given is not None:
                try:
                    replay_control_step(state.robot, given, self._host(index))
                except ReplayDivergence as error:
                    raise RecordingError(f"robot {state.robot_id} at recorded step "
                                         f"{recorded}: {error}") from None
            failure = getattr(state.robot, "failure", None)
            if failure is not None and state.failure is None:
                state.failure, state.failure_step = failure, before
            if self.turn_observer is not None:
                self.turn_observer(index)
        self.step_count = recorded
