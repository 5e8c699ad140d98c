"""The compiled path of `swarm_batch.control_steps`: one machine-code call per robot-step.

`swarm_batch` is the contract and its reference implementation (each robot's
``receive_all``, then ``control_step``). This is the same step with the Python around the VM
removed for the robots the compiled kernel covers — a plain `Robot` in the fast mode
(not ``stress_gc``), booted, not failed, READY: for each of them one call of
:func:`fastbatch.robot_step` receives its rows of the deliveries (XTREME/u8 profiles; the
others receive through ``receive_all`` first), runs its in-queue, ``step`` and out-queue on
its packed queues (:mod:`packed_queues`: they stay packed between steps) and writes what it
sent straight into the outbox columns. Every other robot (a recorder's wrapper, the stress
mode, a failed or unbooted robot) takes the reference calls.

Hand-overs: when the kernel stops in a phase it does not cover (``fastbatch.P_*``), the
reference routines finish that robot's control step from exactly there (its in-queue
loop resumed, ``VM._loop`` resumed inside a call, ``step``'s pop, the out-queue), under
the same ``_guard`` as ``Robot.control_step``: a Python exception becomes the robot's HOST
failure. Robots are stepped in index order, so host functions that touch the world run in
the reference's order; a robot's receive before its own step is equivalent to all
receives first (a receive touches only its own robot: see `swarm_batch`).

Latched host functions (``host.LatchedHostFunction``) the kernel ran are applied once per
call, grouped by their ``apply``, after every robot has stepped — and a robot's latch
before any Python code of its own runs (its hand-over), so each store happens in call
order.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from bbzide.vm import fastbatch, fastinbox, fastloop, messages, neighbors
from bbzide.vm.fastbatch import (
    F_POP,
    F_RECEIVE,
    F_STEP,
    IO_COLLECTED,
    IO_COUNT,
    IO_INNER,
    IO_ROWS,
    IO_SLOTS,
    IO_STATUS,
    LATCHED,
    P_INMSGS,
    P_STEP,
)
from bbzide.vm.host import LatchedHostFunction
from bbzide.vm.messages import PAYLOAD_SIZE
from bbzide.vm.robot import STR_STEP, Robot
from bbzide.vm.swarm_batch import PackedMessages, StepResult
from bbzide.vm.vm import State

#: outbox rows reserved per robot before the kernel's drain (grown when a robot may need
#: more: its out-queue capacity, 10 on every profile, is what one drain can send)
_ROWS_PER_ROBOT = 12


def covered(robot: Any) -> bool:
    """Does the compiled step take this robot now? (See the module comment.)"""
    return type(robot) is Robot and robot.failure is None and robot.booted \
        and not robot.vm.stress_gc and robot.vm.state == State.READY


def _receives_compiled(robot: Robot) -> bool:
    p = robot.profile
    return p.xtreme and not p.neighbors_floats


class _Outbox:
    """The outbox columns being filled (rows in robot order)."""

    def __init__(self, rows: int) -> None:
        self.payloads = np.zeros((rows, PAYLOAD_SIZE), np.uint8)
        self.lengths = np.zeros(rows, np.int64)
        self.robots = np.zeros(rows, np.int64)
        self.io = np.zeros(IO_SLOTS, np.int64)

    def room(self, rows: int) -> None:
        """At least ``rows`` free rows after the cursor."""
        used = int(self.io[IO_ROWS])
        if used + rows <= len(self.lengths):
            return
        grown = max(2 * len(self.lengths), used + rows)
        for name in ("payloads", "lengths", "robots"):
            old = getattr(self, name)
            new = np.zeros((grown, *old.shape[1:]), old.dtype)
            new[:used] = old[:used]
            setattr(self, name, new)

    def add(self, index: int, sent: list[bytes]) -> None:
        """Payloads a robot sent through Python."""
        self.room(len(sent))
        row = int(self.io[IO_ROWS])
        for payload in sent:
            head = payload[:PAYLOAD_SIZE]
            self.payloads[row, :len(head)] = np.frombuffer(bytes(head), np.uint8)
            self.lengths[row] = len(payload)
            self.robots[row] = index
            row += 1
        self.io[IO_ROWS] = row

    def packed(self) -> PackedMessages:
        n = int(self.io[IO_ROWS])
        robots = self.robots[:n].copy()
        zeros = np.zeros(n, np.float64)
        return PackedMessages(robots, self.payloads[:n].copy(), self.lengths[:n].copy(),
                              robots, zeros, zeros, zeros)


def control_steps(robots: Sequence[Any], deliveries: PackedMessages,
                  stepping: np.ndarray) -> StepResult:
    """`swarm_batch.control_steps`, compiled where covered (see the module comment)."""
    count = len(robots)
    before = np.fromiter((r is not None and r.failure is not None for r in robots),
                         dtype=bool, count=count)
    bounds = deliveries.bounds(count)
    deferred = np.zeros(count, dtype=bool)  # receives the compiled step will make
    starts = bounds.tolist()
    for index in np.flatnonzero(np.diff(bounds)).tolist():
        robot = robots[index]
        if robot is None:
            continue
        if covered(robot) and _receives_compiled(robot):
            deferred[index] = True
        else:
            robot.receive_all(deliveries.tuples_of(starts[index], starts[index + 1]))
    outbox = _Outbox(_ROWS_PER_ROBOT * count)
    latched: list[int] = []
    payloads, lengths = deliveries.payloads, deliveries.lengths
    distances, azimuths, elevations = (deliveries.distances, deliveries.azimuths,
                                       deliveries.elevations)
    rules = fastloop.RULES
    robot_step = fastbatch.robot_step
    io = outbox.io
    for index in np.flatnonzero(stepping | deferred).tolist():
        robot = robots[index]
        if robot is None:
            continue
        steps = bool(stepping[index])
        if not covered(robot):
            if steps:
                outbox.add(index, robot.control_step())
            continue
        vm = robot.vm
        flags = (F_RECEIVE if deferred[index] else 0) | (F_STEP if steps else 0) | \
            (F_POP if robot.loop == "pop" else 0)
        if steps:
            outbox.room(robot.profile.out_queue_cap + 1)
        packed = vm.packed()
        hosts, _slots = robot.compiled_hosts()
        regs = vm.kernel_registers(None, vm.instruction_budget)
        h = vm.heap
        phase = robot_step(h.view, vm._stack_view, vm._bcode_view, regs, h.gc_info,
                           h.gc_traversed, rules, h.obj_size, h.elems, h.reserved,
                           packed.inq, packed.outq, packed.ring, packed.ctl, packed.latch,
                           hosts, payloads, lengths, distances, azimuths, elevations,
                           starts[index], starts[index + 1], flags, index,
                           outbox.payloads, outbox.lengths, outbox.robots, io)
        vm.take_kernel_registers(regs)
        if phase & LATCHED:
            latched.append(index)
            phase ^= LATCHED
        if not steps:
            continue
        if phase:
            if latched and latched[-1] == index:
                _apply_latches([robot])
                latched.pop()
            outbox.add(index, _finish(robot, phase, regs, io))
        else:
            robot.steps_done += 1
    if latched:
        _apply_latches([robots[i] for i in latched])
    after = np.fromiter((r is not None and r.failure is not None for r in robots),
                        dtype=bool, count=count)
    return StepResult(outbox.packed(), after & ~before)


def _apply_latches(robots: list[Robot]) -> None:
    """Each robot's written latch slots, cleared, given to their ``apply`` (grouped)."""
    groups: dict[Any, tuple[list[int], list[list[int]]]] = {}
    for robot in robots:
        latch = robot.vm.packed().latch
        _hosts, slots = robot.compiled_hosts()
        for slot in np.flatnonzero(latch[:, 0]).tolist():
            fn: LatchedHostFunction | None = slots[slot] if slot < len(slots) else None
            latch[slot, 0] = 0
            if fn is None:
                continue
            targets, values = groups.setdefault(fn.apply, ([], []))
            targets.append(fn.target)
            values.append(latch[slot, 1:1 + fn.argc].tolist())
    for apply, (targets, values) in groups.items():
        apply(np.array(targets, np.int64), np.array(values, np.int64).reshape(len(targets), -1))


def _finish(robot: Robot, phase: int, regs: np.ndarray, io: np.ndarray) -> list[bytes]:
    """The rest of a control step the kernel stopped in ``phase``, by the reference
    routines (``Robot.control_step``'s, from that point; its ``_guard`` too)."""
    vm = robot.vm
    sent: list[bytes] = []
    try:
        io_status = int(io[IO_STATUS])
        saved, budget = int(regs[fastloop.R_SAVED]), vm.instruction_budget
        if phase == P_INMSGS:
            count = int(io[IO_COUNT])
            if io_status == fastinbox.IN_CALL:
                vm._loop(saved, budget, resume=(int(io[IO_INNER]), regs))
                vm.pop()
                vm.gc()
                messages.process_inmsgs(vm, count, True)
            else:  # PYTHON_MESSAGE: message `count` collected, its extraction is next
                messages.process_inmsgs(vm, count, bool(io[IO_COLLECTED]), taken=True)
            if vm.state != State.ERROR:
                robot.call_global(STR_STEP)
        elif phase == P_STEP:
            if io_status == fastinbox.PYTHON_MESSAGE:
                robot.call_global(STR_STEP)
            else:
                if io_status >= fastinbox.CALL_UNDER_WAY:
                    vm._loop(saved, budget,
                             resume=(io_status - fastinbox.CALL_UNDER_WAY, regs))
                if io_status != fastinbox.NOT_DEFINED and robot.loop == "pop" \
                        and vm.state == State.READY:
                    vm.pop()
        # P_OUTMSGS (and after the above): the countdown is still to do
        neighbors.process_outmsgs(vm)
        sent = messages.drain_outbox(vm.queues)
        robot.steps_done += 1
        robot._check()
    except Exception as exc:  # noqa: BLE001 - the robot must never raise (contract)
        robot._fail_host(exc)
    return sent
