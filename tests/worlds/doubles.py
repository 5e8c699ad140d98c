"""Test doubles for the engine without a VM: a scripted firmware loop and a host call.

`ScriptedRobot` follows the engine's `FirmwareLoop` protocol; its behaviour is a Python function
of (robot, step) so engine, radio and physics tests run in milliseconds. `FakeCall` stands for
`bbzide.vm.host.HostCall` when a test calls a world's host function directly.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any


@dataclass
class FakeFailure:
    reason: str
    pc: int = 0
    location: Any = None
    message: str = ""


@dataclass
class FakeCall:
    args: list[Any]
    robot_id: int = 0
    returned: list[Any] = field(default_factory=list)
    failed: str | None = None

    def arg(self, i: int) -> Any:
        return self.args[i - 1] if i <= len(self.args) else None

    def expect_args(self, n: int) -> bool:
        if len(self.args) != n:
            self.failed = "LNUM"
            return False
        return True

    def ret(self, value: Any = None) -> None:
        self.returned.append(value)

    def fail(self, kind: str) -> None:
        self.failed = kind


Behaviour = Callable[["ScriptedRobot", int], list[bytes]]


class ScriptedRobot:
    """A firmware loop whose control step is `behaviour(self, step)`."""

    def __init__(self, behaviour: Behaviour, program: Any, profile: Any, robot_id: int,
                 host_functions: dict[str, Callable[[Any], None]]) -> None:
        self.behaviour = behaviour
        self.program = program
        self.robot_id = robot_id
        self.host = host_functions
        self.failure: FakeFailure | None = None
        self.inbox: list[tuple[bytes, float, float, float]] = []
        self.steps = 0
        self.booted = False

    def boot(self) -> None:
        self.booted = True

    def receive(self, message: bytes, distance: float, azimuth: float, elevation: float) -> None:
        self.inbox.append((message, distance, azimuth, elevation))

    def control_step(self) -> list[bytes]:
        out = self.behaviour(self, self.steps)
        self.steps += 1
        return out

    def call(self, name: str, *args: Any) -> FakeCall:
        call = FakeCall(list(args), self.robot_id)
        self.host[name](call)
        return call


def factory(behaviour: Behaviour) -> Callable[..., ScriptedRobot]:
    def build(program: Any, profile: Any, robot_id: int, host: Any) -> ScriptedRobot:
        return ScriptedRobot(behaviour, program, profile, robot_id, dict(host))

    return build
