"""The compiled in-queue loop (``bbzide/vm/compiled/fastinbox.py``) against the reference routines.

A robot in the fast mode processes its received broadcasts in compiled code and hands the
rest back to Python; a robot in the reference mode (``stress_gc=True``) runs the Python
routines only. Both receive the same messages — broadcasts to a bytecode listener, to a
topic nobody listens to, to a listener calling a host function, stigmergy messages between
them, garbage — on a stack filled to every depth near its end (the kernel leaves a call
without room for its pushes to Python) and a heap filled until it is full (no room for the
call's objects: Python again). After each control step every observable must be equal.
"""

from __future__ import annotations

import math
import pickle
import random

import pytest

from bbzide.compiler import bittybuzz_string_table, compile_source
from bbzide.vm import inmsgs
from bbzide.vm.compiled import fastloop
from bbzide.vm.host import HostCall
from bbzide.vm.profiles import KILOBOT, PC
from bbzide.vm.robot import Robot

SOURCE = """
heard = 0
kept = {}
n = 0
function init() {
  v = stigmergy.create(1)
  neighbors.listen("g", function(topic, value, rid) {
    if (value < 100) { heard = heard + value }
  })
  neighbors.listen("h", function(topic, value, rid) {
    log(value, rid)
  })
  neighbors.listen("k", function(topic, value, rid) {
    n = n + 1
    kept[n] = value
  })
}
function step() {
  neighbors.broadcast("g", id)
  neighbors.broadcast("h", id)
  neighbors.broadcast("k", id)
  neighbors.broadcast("z", id)
  if (n == 0) { v.put(1, heard) }   # a few local puts (the Kilobot store is tiny)
  n = n + 1
}
"""


def _observe(robot: Robot) -> tuple:
    vm = robot.vm
    q = vm.queues.inbox
    return (vm.state, vm.error, vm.pc, bytes(vm.stack), vm.stackptr, vm.blockptr, vm.lsyms,
            vm.heap.rtobj, vm.heap.ltseg, bytes(vm.heap.data), list(vm.error_events),
            vm.heap.gc_runs, vm.heap.peak_used, vm.instructions_executed,
            [bytes(r) for r in q.records], q.start, q.end, pickle.dumps(vm.neighbors),
            pickle.dumps(vm.vstig), str(robot.failure))


def _pair(profile, fill: int) -> tuple[list[Robot], list[list]]:
    program = compile_source(SOURCE, "inbox.bzz",
                             string_table=bittybuzz_string_table(["log"])).to_bbo()
    logs: list[list] = [[], []]
    robots = []
    for k, stress in enumerate((True, False)):
        def log(call: HostCall, store: list = logs[k]) -> None:
            store.append(call.args)

        robot = Robot(program, profile, 1, {"log": log}, stress_gc=stress)
        robot.boot()
        for _ in range(fill):  # a stack filled by the firmware's own pushes
            robot.vm.push_nil()
        robots.append(robot)
    return robots, logs


@pytest.mark.parametrize("profile", [KILOBOT, PC], ids=["kilobot", "pc"])
def test_inbox_identical_on_a_filling_stack(profile) -> None:
    for fill in range(profile.stack_size - 12, profile.stack_size - 1):
        (reference, fast), logs = _pair(profile, fill)
        sender = Robot(reference.program, profile, 7, {"log": lambda call: None})
        sender.boot()
        for _ in range(3):
            sent = sender.control_step()
            for robot in (reference, fast):
                for payload in sent + [b"\x00\x07", b"\x09" * 9]:
                    robot.receive(payload, 30.0, 1.0, 0.0)
                robot.control_step()
            assert _observe(reference) == _observe(fast), fill
        assert logs[0] == logs[1]


@pytest.mark.parametrize("profile", [KILOBOT, PC], ids=["kilobot", "pc"])
def test_inbox_identical_until_the_heap_is_full(profile) -> None:
    (reference, fast), logs = _pair(profile, 0)
    senders = [Robot(reference.program, profile, i, {"log": lambda call: None})
               for i in range(2, 6)]
    for sender in senders:
        sender.boot()
    for _ in range(80):
        sent = [m for sender in senders for m in sender.control_step()]
        for robot in (reference, fast):
            for payload in sent:
                robot.receive(payload, 30.0, 1.0, 0.0)
            robot.control_step()
        assert _observe(reference) == _observe(fast)
        if reference.failure is not None:
            break
    assert reference.failure is not None and reference.failure.reason == "MEM"
    assert logs[0] == logs[1]


def test_receive_all_is_receive_after_receive() -> None:
    """``Robot.receive_all`` (compiled for the Kilobot:
    ``bbzide/vm/compiled/fastreceive.py``) against ``receive`` called per message: truncated
    and garbage payloads, duplicates of queued broadcasts, a queue and a neighbor ring that
    overflow, situated values to round (ties to even), clamp, NaN and infinities."""
    rng = random.Random(4)
    (_, batch), _logs = _pair(KILOBOT, 0)
    (_, single), _logs = _pair(KILOBOT, 0)
    odd = [0.5, 1.5, 2.5, -0.5, 254.5, 255.5, 300.0, -7.0, math.nan, math.inf, -math.inf,
           True, 7, 10**400]
    for step in range(40):
        deliveries = []
        for _ in range(rng.randrange(0, 25)):
            kind = rng.choice([0, 0, 0, 1, 2, 3, 9])
            sender = rng.randrange(0, 24)
            body = bytes([kind, sender, 0, rng.randrange(40, 43), 0, 1, rng.randrange(9), 0, 5])
            payload = body[:rng.choice([0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 9, 9, 9, 12])]
            situated = [rng.choice(odd) if rng.random() < 0.2 else rng.uniform(0, 120)
                        for _ in range(3)]
            deliveries.append((sender, payload, *situated))
        batch.receive_all(deliveries)
        for _sender, payload, distance, azimuth, elevation in deliveries:
            single.receive(payload, distance, azimuth, elevation)
        assert _observe(batch) == _observe(single), step
        if step % 3 == 0:
            batch.control_step()
            single.control_step()
            assert _observe(batch) == _observe(single), step


#: A listener that keeps nothing it makes: locals, temporaries, a string, a result.
PLAIN_LISTENER = """
function init() {
  neighbors.listen("q", function(topic, value, rid) {
    var a = value * 2 + rid
    var b = "word"
    return a
  })
}
function step() {
  neighbors.broadcast("q", id)
}
"""


@pytest.mark.parametrize("profile", [KILOBOT, PC], ids=["kilobot", "pc"])
def test_plain_listener_calls_end_without_a_collection(profile) -> None:
    """The compiled in-queue begins such a call on the heap the message's collection left
    (``fastloop.CALL_ON_FIXED_HEAP``) and ends it by returning to that heap
    (``undo_to_fixed_point``), so no collection runs for the messages after the first:
    the ``gc_info`` depths the test shifts beforehand (a collection would rewrite them)
    survive, and every observable is the reference's all the same."""
    program = compile_source(PLAIN_LISTENER, "plain.bzz",
                             string_table=bittybuzz_string_table([])).to_bbo()
    sender = Robot(program, profile, 7, {})
    sender.boot()
    robots = [Robot(program, profile, 1, {}, stress_gc=stress) for stress in (True, False)]
    for robot in robots:
        robot.boot()
    reference, fast = robots
    sender.control_step()  # its broadcast leaves with its next step
    for _ in range(4):
        sent = sender.control_step()
        assert sent
        for robot in robots:
            for payload in sent * 3:
                robot.receive(payload, 30.0, 1.0, 0.0)
            robot.vm.gc()
        info = fast.vm.heap.gc_info
        data = fast.vm.heap.data
        s = fast.vm.heap.obj_size
        shifted = [x for x in range(len(info))
                   if info[x] & fastloop.PERMANENT_PHASE and 2 <= info[x] & 63 < 60
                   and data[x * s] & 7 in (1, 2, 3)]  # leaves: their depth is never read
        for x in shifted:
            info[x] += 1
        expected = info.copy()
        for robot in robots:
            inmsgs.go_on_inmsgs(robot.vm, 0, True)
        assert len(shifted) > 3 and (info[shifted] == expected[shifted]).all()
        assert fast.vm.queues.inbox.empty()
        assert _observe(reference) == _observe(fast)
        for robot in robots:
            robot.control_step()
        assert _observe(reference) == _observe(fast)
