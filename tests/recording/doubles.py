"""A small firmware loop that behaves like a Robot without a Buzz VM, for recorder tests.

`ToyRobot` keeps its whole state in a real `bbzide.vm.heap.Heap` (so heap figures are real
numbers) plus a few counters, and depends on every kind of outside input the recorder must
capture: received messages with their situated data (folded into a checksum), and the world's
host functions `rand`, `light` (returned values), `led` and `set_motor` (effects on the world),
`abs` with a wrong argument count now and then (an `expect_args` failure). Robot 7 fails at
its 60th step, like a VM error. So a rebuilt toy
equals the live one only if every input was recorded and replayed in order.
"""

from __future__ import annotations

import json
import struct
import zlib
from dataclasses import dataclass
from typing import Any

from bbzide.vm.heap import Heap

#: Robot 7 stops with an error at its 60th control step (an `error` event to jump to).
FAILING_ROBOT, FAILING_STEP = 7, 60


@dataclass
class ToyFailure:
    reason: str
    pc: int = 0
    location: Any = None
    message: str = ""


class ToyCall:
    """The parts of HostCall a world host function uses, with a toy 'VM' behind them."""

    def __init__(self, robot: ToyRobot, args: list[Any]) -> None:
        self.robot = robot
        self.robot_id = robot.robot_id
        self.args = args
        self.returned: Any = "ret0"

    @property
    def arg_count(self) -> int:
        return len(self.args)

    def arg(self, i: int) -> Any:
        return self.args[i - 1] if i <= len(self.args) else None

    def expect_args(self, n: int) -> bool:
        if len(self.args) != n:
            self.robot.errors += 1
            return False
        return True

    def ret(self, value: Any = None) -> None:
        self.returned = value

    def fail(self, kind: str) -> None:
        self.robot.errors += 1


class ToyRobot:
    def __init__(self, program: Any, profile: Any, robot_id: int, host_functions: Any) -> None:
        self.program = program
        self.robot_id = robot_id
        self.host = dict(host_functions)
        self.heap = Heap(profile)
        self.vm = self  # the recorder reads robot.vm.heap
        self.failure: Any = None
        self.checksum = 0
        self.steps = 0
        self.errors = 0
        self.instructions_executed = 0  # as a VM counts them (the recorder shares VM time)
        self.on_phase: Any = None  # told when boot ends, as `Robot` tells it

    @property
    def steps_done(self) -> int:
        """Control steps run (`Robot.steps_done`: the recorder sees who stepped by it)."""
        return self.steps

    def boot(self) -> None:
        self.checksum = self.robot_id
        self.heap.rtobj += self.heap.obj_size * (1 + self.robot_id % 3)
        if self.on_phase is not None:
            self.on_phase("init")

    def receive(self, message: bytes, distance: float, azimuth: float, elevation: float) -> None:
        packed = message + struct.pack("<ddd", distance, azimuth, elevation)
        self.checksum = zlib.crc32(packed, self.checksum)

    def _call(self, name: str, *args: Any) -> Any:
        call = ToyCall(self, list(args))
        self.host[name](call)
        return call.returned

    def control_step(self) -> list[bytes]:
        self.steps += 1
        if self.robot_id == FAILING_ROBOT and self.steps == FAILING_STEP:
            self.failure = ToyFailure("MEM", message="toy out of memory")
            return []
        self.instructions_executed += 40 + self.robot_id
        draw = self._call("rand")
        light = self._call("light")
        self.checksum = zlib.crc32(struct.pack("<qq", int(draw), int(light)), self.checksum)
        self._call("led", self.checksum % 8)
        self._call("set_motor", 0 if draw % 3 == 1 else 255, 0 if draw % 3 == 2 else 255)
        if draw % 5 == 0:
            self._call("abs", 1, 2)  # wrong arity: expect_args fails
        offset = self.heap.rtobj % self.heap.size
        self.heap.data[offset % len(self.heap.data)] = self.checksum & 0xFF
        self.heap.peak_used = max(self.heap.peak_used, self.heap.used_bytes())
        self.heap.gc_runs += 1
        if self.steps % 3 == 0:
            return [bytes([self.robot_id & 0xFF, self.checksum & 0xFF, 1, 2, 3, 4, 5, 6, 7])]
        return []

    def snapshot(self) -> bytes:
        heap = self.heap
        return json.dumps({
            "heap": heap.data.hex(), "rtobj": heap.rtobj, "ltseg": heap.ltseg,
            "peak": heap.peak_used, "gc": heap.gc_runs, "checksum": self.checksum,
            "steps": self.steps, "errors": self.errors}).encode()

    def restore(self, snapshot: bytes) -> None:
        state = json.loads(snapshot)
        self.heap.data[:] = bytes.fromhex(state["heap"])
        self.heap.rtobj, self.heap.ltseg = state["rtobj"], state["ltseg"]
        self.heap.peak_used, self.heap.gc_runs = state["peak"], state["gc"]
        self.checksum, self.steps, self.errors = state["checksum"], state["steps"], state["errors"]
