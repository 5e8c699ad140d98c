"""Whole swarms in the fast VM mode against the reference mode: identical robots, step by step.

The fast mode processes a robot's in-queue in compiled code
(``bbzide/vm/compiled/fastinbox.py``) and hands back to the Python routines whenever anything
unusual happens: a stigmergy message, a listener that calls a host function or runs an
instruction the kernel does not cover, an error or the budget inside a listener, a full stack
or heap. Each scenario below runs the same swarm twice — robots built with ``stress_gc=True``
(the reference: Python routines, a collection before every instruction) and with the default
fast mode — and compares every robot's observable state after every step: heap bytes, ROP/LSP,
stack, registers, error events, collection count, queues and neighbor records, failure.
"""

from __future__ import annotations

import pickle
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from bbzide.vm import inmsgs
from bbzide.vm.robot import Robot
from bbzide.worlds.commands import load_script
from bbzide.worlds.engine import Simulation
from bbzide.worlds.registry import WORLDS

REPO = Path(__file__).resolve().parents[2]


def _factory(stress: bool, budget: int, loop: str):
    def build(program, profile, robot_id, host_functions):
        return Robot(program, profile, robot_id, host_functions=host_functions,
                     instruction_budget=budget, stress_gc=stress, loop=loop)

    return build


def _observe(robot: Robot) -> tuple:
    vm = robot.vm
    q = vm.queues
    return (vm.state, vm.error, vm.pc, bytes(vm.stack), vm.stackptr, vm.blockptr, vm.lsyms,
            vm.heap.rtobj, vm.heap.ltseg, bytes(vm.heap.data), list(vm.error_events),
            vm.heap.gc_runs, vm.heap.peak_used, vm.instructions_executed,
            [bytes(r) for r in q.inbox.records], q.inbox.start, q.inbox.end,
            [bytes(r) for r in q.outbox.records], q.outbox.start, q.outbox.end,
            pickle.dumps(vm.neighbors), pickle.dumps(vm.vstig), str(robot.failure))


def _run_both(program, world: str, robots: int, steps: int, budget: int = 100_000,
              options: dict | None = None, loop: str = "pop") -> list[int]:
    sims = [Simulation(world, program, robots=robots, seed=3, world_options=options or {},
                       robot_factory=_factory(stress, budget, loop), watch=())
            for stress in (True, False)]
    received = []
    for step in range(steps):
        for sim in sims:
            sim.step()
        reference, fast = sims
        received.append(reference.stats.total_received)
        for a, b in zip(reference.robots, fast.robots, strict=True):
            assert _observe(a.robot) == _observe(b.robot), (step, a.index)
    return received


def _compile(tmp_path: Path, text: str, world: str = "kilobot"):
    path = tmp_path / "script.bzz"
    path.write_text(text)
    return load_script(path, WORLDS[world].host_names, [])


def test_gradient_swarm_identical() -> None:
    program = load_script(REPO / "examples/kilobot/gradient.bzz",
                          WORLDS["kilobot"].host_names, [])
    received = _run_both(program, "kilobot", 25, 12, options={"width": 0.4, "height": 0.4})
    assert sum(received) > 100  # the listeners did run


@pytest.mark.parametrize("example", ["leader.bzz", "firefly.bzz", "aggregation.bzz"])
def test_kilobot_examples_identical(example: str) -> None:
    program = load_script(REPO / "examples/kilobot" / example,
                          WORLDS["kilobot"].host_names, [])
    _run_both(program, "kilobot", 12, 10, options={"width": 0.3, "height": 0.3})


def test_crazyflie_consensus_identical() -> None:
    program = load_script(REPO / "examples/crazyflie/consensus.bzz",
                          WORLDS["crazyflie"].host_names, [])
    _run_both(program, "crazyflie", 6, 8)


LISTENERS = """
var heard = 0
var calls = 0
var big = {}
function init() {
  neighbors.listen("a", function(vid, value, rid) {
    heard = heard + value
    led(value % 7 + 1)                      # a host function inside the listener
  })
  neighbors.listen("b", function(vid, value, rid) {
    calls = calls + 1
    big[calls % 40] = {.x = calls, .y = rid}  # tables: instructions the kernel leaves to Python
  })
  neighbors.listen("c", function(vid, value, rid) {
    if (id % 3 == 0) {
      var t = value.nothing                 # a TYPE error inside a listener
    }
  })
  neighbors.listen("d", function(vid, value, rid) {
    if (id % 4 == 1) {
      while (1) { }                         # the budget inside a listener
    }
  })
}
function step() {
  neighbors.broadcast("a", id)
  neighbors.broadcast("b", calls)
  neighbors.broadcast("c", 1)
  neighbors.broadcast("d", 2)
  neighbors.broadcast("e", 3)               # nobody listens to "e"
  if (id % 2 == 0) {
    stigmergy_one.put(id % 5, heard)        # stigmergy messages between broadcasts
  }
}
"""


def test_unusual_listeners_identical(tmp_path: Path) -> None:
    text = LISTENERS.replace("stigmergy_one", "v").replace(
        "function init() {", "var v\nfunction init() {\n  v = stigmergy.create(1)", 1)
    program = _compile(tmp_path, text)
    _run_both(program, "kilobot", 16, 12, budget=3000, options={"width": 0.3, "height": 0.3})


#: Listeners that keep what they hear until the Kilobot heap is full (MEM).
HEAP_FILLING = """
var kept = {}
var n = 0
function init() {
  neighbors.listen("k", function(vid, value, rid) {
    n = n + 1
    kept[n] = value
  })
}
function step() {
  neighbors.broadcast("k", n)
}
"""


def test_heap_filling_listener_identical(tmp_path: Path) -> None:
    """A listener that keeps what it hears until the Kilobot heap is full (MEM)."""
    program = _compile(tmp_path, HEAP_FILLING)
    _run_both(program, "kilobot", 10, 25, options={"width": 0.25, "height": 0.25})


def test_growing_stack_identical() -> None:
    """The firmware loop (``loop="robot"``) leaves each step's result on the stack: the
    listeners meet a stack with less and less room, down to the STACK error."""
    program = load_script(REPO / "examples/kilobot/gradient.bzz",
                          WORLDS["kilobot"].host_names, [])
    _run_both(program, "kilobot", 3, 96, options={"width": 0.2, "height": 0.2}, loop="robot")


# ---- swarm_batch.control_steps: the compiled path against the reference --------------------
# The engine hands a whole control step to `swarm_batch.control_steps`; its compiled path
# (swarm_batch_fast, fastbatch) must leave every robot as the reference implementation does.
# The two swarms below are driven by `control_steps` directly with deliveries from a plain
# in-range radio (no loss), so the test does not depend on the engine's radio: the reference
# swarm's robots are in the stress mode on the reference path, the other's in the fast mode
# on the compiled path. Outboxes, failures and LEDs are compared after every step, each
# robot's whole state after every step or every third one (a snapshot unpacks the packed
# queues: the steps in between run on queues that stay packed, the path a swarm nobody
# inspects takes).

def _batch_swarms(program, world: str, robots: int, budget: int, loop: str,
                  options: dict) -> list[Simulation]:
    return [Simulation(world, program, robots=robots, seed=5, world_options=options,
                       robot_factory=_factory(stress, budget, loop), watch=())
            for stress in (True, False)]


def _deliveries(outbox, sim: Simulation, comm_range: float, unit: float):
    """Every outbox row to every robot within `comm_range` of its sender, by receiver."""
    from bbzide.vm.swarm_batch import PackedMessages

    rows = []
    positions = sim.positions
    for k in range(len(outbox)):
        sender = int(outbox.robots[k])
        for receiver in range(sim.count):
            gap = float(np.linalg.norm(positions[receiver] - positions[sender]))
            if receiver != sender and gap <= comm_range:
                rows.append((receiver, sender, outbox.payload(k), gap * unit,
                             0.7 * (receiver - sender), 0.1 * sender))
    rows.sort(key=lambda r: r[0])
    return PackedMessages.from_rows(rows)


def _run_batches(program, world: str, robots: int, steps: int, budget: int = 100_000,
                 loop: str = "pop", options: dict | None = None, comm_range: float = 0.12,
                 unit: float = 1000.0, every: int = 3) -> dict[str, Any]:
    from bbzide.vm.swarm_batch import PackedMessages, control_steps

    sims = _batch_swarms(program, world, robots, budget, loop, options or {})
    reference, fast = ([s.robot for s in sim.robots] for sim in sims)
    outboxes = [PackedMessages.empty(), PackedMessages.empty()]
    seen = {"messages": 0, "failed": 0}
    for step in range(steps):
        stepping = np.array([(i + step) % 5 != 0 for i in range(robots)])
        results = [control_steps(team, _deliveries(box, sim, comm_range, unit), stepping,
                                 reference=ref)
                   for team, box, sim, ref in zip((reference, fast), outboxes, sims,
                                                  (True, False), strict=True)]
        a, b = results
        for column in ("robots", "payloads", "lengths"):
            assert (getattr(a.outbox, column) == getattr(b.outbox, column)).all(), step
        assert (a.failed == b.failed).all(), step
        assert (sims[0].leds == sims[1].leds).all(), step
        if step % every == every - 1 or step == steps - 1:
            for i, (x, y) in enumerate(zip(reference, fast, strict=True)):
                assert Robot.comparable(x.snapshot()) == Robot.comparable(y.snapshot()), \
                    (step, i)
                assert str(x.failure) == str(y.failure), (step, i)
        outboxes = [a.outbox, b.outbox]
        seen["messages"] += len(a.outbox)
        seen["failed"] = int(sum(r.failure is not None for r in reference))
    seen["fast"] = fast
    return seen


def test_batch_gradient_identical_and_without_hand_over(monkeypatch) -> None:  # noqa: ANN001
    """The gradient example runs wholly in the compiled step (no hand-over to Python:
    `neighbors.broadcast` and the latched `led` run in machine code) and stays identical."""
    handed: list[int] = []
    finish = Robot.finish_compiled_step

    def counted(robot, phase, regs, io):  # noqa: ANN001, ANN202
        handed.append(phase)
        return finish(robot, phase, regs, io)

    monkeypatch.setattr(Robot, "finish_compiled_step", counted)
    program = load_script(REPO / "examples/kilobot/gradient.bzz",
                          WORLDS["kilobot"].host_names, [])
    seen = _run_batches(program, "kilobot", 20, 14, options={"width": 0.35, "height": 0.35})
    assert seen["messages"] > 150 and handed == []


def test_batch_latching_switched_off_identical(monkeypatch) -> None:  # noqa: ANN001
    """`Robot.latch_host_calls = False` (a recorder logging every host call) sends the
    latched `led` to Python — a hand-over every step — with the same robots and LEDs."""
    handed: list[int] = []
    finish = Robot.finish_compiled_step

    def counted(robot, phase, regs, io):  # noqa: ANN001, ANN202
        handed.append(phase)
        return finish(robot, phase, regs, io)

    monkeypatch.setattr(Robot, "finish_compiled_step", counted)
    build = _batch_swarms

    def swarms(*args):  # noqa: ANN002, ANN202
        sims = build(*args)
        for state in sims[1].robots:
            state.robot.latch_host_calls = False
        return sims

    monkeypatch.setattr(sys.modules[__name__], "_batch_swarms", swarms)
    program = load_script(REPO / "examples/kilobot/gradient.bzz",
                          WORLDS["kilobot"].host_names, [])
    seen = _run_batches(program, "kilobot", 12, 6, options={"width": 0.3, "height": 0.3})
    assert seen["messages"] > 40 and len(handed) >= 12 * 4


BATCH_HAND_OVERS = """
var heard = 0
var calls = 0
var steps = 0
var big = {}
var v
function init() {
  v = stigmergy.create(1)
  neighbors.listen("a", function(vid, value, rid) {
    heard = heard + value
    led(value % 7 + 1)                      # a latched host function inside a listener
  })
  neighbors.listen("b", function(vid, value, rid) {
    calls = calls + 1
    big[calls % 3] = {.x = calls, .y = rid}   # tables: instructions the kernel leaves to Python
  })
  neighbors.listen("c", function(vid, value, rid) {
    if (id == 3 and calls > 20) {
      var t = value.nothing                 # a TYPE error inside a listener
    }
  })
  neighbors.listen("d", function(vid, value, rid) {
    if (id == 5 and calls > 15) {
      while (1) { }                         # the budget inside a listener
    }
  })
}
function step() {
  led(id % 7)
  neighbors.broadcast("a", id)
  neighbors.broadcast("b", calls)
  neighbors.broadcast("c", 1)
  neighbors.broadcast("d", 2)
  neighbors.broadcast("e", 3)               # nobody listens to "e"
  if (id % 2 == 0) {
    v.put(1, heard)                         # stigmergy messages between broadcasts
  }
  steps = steps + 1
  if (steps > 12 and id == 7) {
    led(heard % 3, 1)                       # LNUM: the latched function's Python path
  }
  if (steps > 9 and id == 9) {
    led(nil)                                # TYPE, after a latched call of the same step
  }
  if (steps > 15 and id == 11) {
    neighbors.broadcast("a")                # LNUM in the compiled broadcast's place
  }
}
"""


@pytest.mark.parametrize("loop", ["pop", "robot"])
def test_batch_hand_overs_identical(tmp_path: Path, loop: str) -> None:
    """Kilobots that hit every hand-over of the compiled step: host functions it does not
    run (stigmergy), tables, errors and the budget inside listeners, a full in-queue (five
    topics from every neighbor) and out-queue, unknown topics, a latched function called
    with a wrong argument count or type after a latched call, the data GC of the neighbor
    ring (every 11th step), robots that only receive (not stepping), and with the firmware
    loop a stack that grows until the STACK error."""
    program = _compile(tmp_path, BATCH_HAND_OVERS)
    # states compared after every step in one mode (each step then starts from unpacked
    # queues), every third in the other (the queues stay packed over two steps)
    seen = _run_batches(program, "kilobot", 14, 24, budget=3000, loop=loop,
                        options={"width": 0.3, "height": 0.3},
                        every=1 if loop == "pop" else 3)
    assert seen["messages"] > 300 and 0 < seen["failed"] < 14, seen


#: Listener calls and host calls of every shape the compiled step may end without a
#: collection (fastloop.CALL_ON_FIXED_HEAP, undo_to_fixed_point, end_host_frame) and of
#: shapes it must not: locals, temporaries, strings and results that die with the call;
#: arguments kept in a global (some steps only); a lambda capturing a leaf or a table; a
#: listener returning a table; host calls given fresh temporaries, globals' values, strings
#: and locals.
CALL_SHORTCUTS = """
var heard = 0
var last = 0
var kept = {}
var steps = 0
function listeners(tag, box) {
  neighbors.listen("a", function(vid, value, rid) {
    var twice = value * 2
    var label = "seen"
    var sum = twice + rid + tag
    return sum % 5
  })
  neighbors.listen("b", function(vid, value, rid) {
    if (value % 3 == 0) {
      last = value                  # some steps keep the argument
    }
    var x = box.n + value           # a captured table
    return x
  })
  neighbors.listen("c", function(vid, value, rid) {
    heard = heard + 1
    return {}                       # a table result, popped by the in-queue
  })
}
function init() {
  var box = {.n = 1}
  listeners(id % 4, box)
}
function step() {
  steps = steps + 1
  neighbors.broadcast("a", steps * 3 + id)      # a fresh temporary
  neighbors.broadcast("b", last)                # a global's value
  if (steps % 4 == 1) {
    neighbors.broadcast("c", heard)
  }
  led(steps % 7)
  led(heard)
  var twin = steps + 1
  led(twin)                                     # a local
  if (steps > 5) {
    kept[steps % 3] = steps                     # old values dropped by a table
  }
}
"""


def test_batch_call_shortcuts_identical(tmp_path: Path) -> None:
    """Listener and host calls ended without a collection when the heap allows it, with a
    collection when it does not: the same robots as the reference after every step, on the
    Kilobot (tiny heap: freed slots reused at once) and on the M300 profile."""
    program = _compile(tmp_path, CALL_SHORTCUTS)
    seen = _run_batches(program, "kilobot", 10, 30, options={"width": 0.25, "height": 0.25},
                        every=1)
    assert seen["messages"] > 300 and seen["failed"] == 0, seen
    text = CALL_SHORTCUTS.replace("led(", "ledx(").replace(
        "var steps = 0\n", "var steps = 0\nfunction ledx(a) { return a }\n", 1)
    seen = _run_batches(_compile(tmp_path, text, "m300"), "m300", 8, 20, comm_range=30.0,
                        unit=1.0, every=1)
    assert seen["messages"] > 200 and seen["failed"] == 0, seen


def test_batch_heap_filling_identical(tmp_path: Path) -> None:
    """Listeners keep what they hear until the Kilobot heap is full (MEM); the LED, a
    latched host function, is set every step."""
    program = _compile(tmp_path, HEAP_FILLING.replace(
        '  neighbors.broadcast("k", n)\n', '  neighbors.broadcast("k", n)\n  led(n % 8)\n'))
    seen = _run_batches(program, "kilobot", 10, 25, options={"width": 0.25, "height": 0.25})
    assert seen["failed"] > 0


@pytest.mark.parametrize("world", ["crazyflie", "m300"])
def test_batch_other_profiles_identical(tmp_path: Path, world: str) -> None:
    """Profiles with neighbor data in the heap (the compiled step writes it,
    fastreceive.neighbors_add_heap): Crazyflie and M300, with hand-overs (stigmergy,
    tables, errors)."""
    text = BATCH_HAND_OVERS.replace("led(", "ledx(").replace(
        "var v\n", "var v\nfunction ledx(a) { return a }\n", 1)
    program = _compile(tmp_path, text, world)
    seen = _run_batches(program, world, 8, 14, budget=3000, comm_range=30.0, unit=1.0)
    assert seen["messages"] > 100



def _count_python_receives(monkeypatch) -> list[int]:  # noqa: ANN001
    """Robot ids of the fast mode's robots, not failed, whose deliveries went through
    `Robot.receive_all` (not the compiled receive)."""
    seen: list[int] = []
    receive_all = Robot.receive_all

    def counted(robot, deliveries):  # noqa: ANN001, ANN202
        if not robot.vm.stress_gc and robot.failure is None:
            seen.append(robot.vm.robot)
        return receive_all(robot, deliveries)

    monkeypatch.setattr(Robot, "receive_all", counted)
    return seen


def test_batch_heap_profile_filling_identical(monkeypatch, tmp_path: Path) -> None:  # noqa: ANN001
    """Crazyflies whose listeners keep what they hear until the heap is full: the compiled
    receive writes the neighbor data into the heap while it has room, then hands the rest
    of a robot's messages to Python (which meets the MEM error)."""
    python_receives = _count_python_receives(monkeypatch)
    program = _compile(tmp_path, HEAP_FILLING, "crazyflie")
    seen = _run_batches(program, "crazyflie", 12, 30, comm_range=30.0, unit=1.0)
    assert seen["failed"] > 0 and python_receives


#: Robots that fall silent one group after another: the neighbor-data GC (every 11th
#: step) deletes some entries of a data segment (the compiled GC) or all of them (Python's:
#: `foreach` then goes on through segment 0, a quirk the kernel leaves to the model).
FALLING_SILENT = """
var n = 0
var t = 0
function init() {
  neighbors.listen("k", function(vid, value, rid) {
    n = n + value % 3
  })
}
function step() {
  t = t + 1
  if (id < 2 or t < 12 or (id % 3 != 0 and t < 26) or (id % 3 == 1 and t < 40)) {
    neighbors.broadcast("k", t)
  }
  if (t % 7 == 0) {
    n = n + neighbors.count()
  }
}
"""


@pytest.mark.parametrize("world", ["crazyflie", "m300"])
def test_batch_heap_neighbors_falling_silent_identical(monkeypatch, tmp_path: Path,
                                                      world: str) -> None:  # noqa: ANN001
    """The heap profiles' neighbor-data GC run by the compiled step where it can tell
    every entry's fate, handed to Python where a data segment empties: identical robots."""
    handed: list[int] = []
    finish = Robot.finish_compiled_step

    def counted(robot, phase, regs, io):  # noqa: ANN001, ANN202
        handed.append(phase)
        return finish(robot, phase, regs, io)

    monkeypatch.setattr(Robot, "finish_compiled_step", counted)
    program = _compile(tmp_path, FALLING_SILENT, world)
    seen = _run_batches(program, world, 11, 56, comm_range=30.0, unit=1.0, every=1)
    from bbzide.vm.compiled.fastbatch import P_OUTMSGS

    python_gcs = handed.count(P_OUTMSGS)
    # 11 robots, ~4 data GCs each in 56 steps (a robot steps 4 times in 5): some by Python
    assert seen["messages"] > 300 and 0 < python_gcs < 11 * 4


def test_situated_values_as_the_model_converts() -> None:
    """The compiled receive stores a distance or an angle as `Robot.neighbor_entry` does:
    bbzfloat bits (float32 rounding, overflow to infinity, NaN's low bits) or a u8."""
    from bbzide.vm import robot as robot_module
    from bbzide.vm.compiled.fastreceive import situated_value

    scratch = np.empty(1, np.float32)
    rng = np.random.default_rng(7)
    values = [0.0, -0.0, 0.5, 1.5, 2.5, -3.25, 255.5, 256.0, 1e-30, 1e-45, 3.4e38, 3.5e38,
              -1e39, float("inf"), -float("inf"), float("nan"), 2.0 ** -96, 2.0 ** -97,
              2.0 ** 31, 2.0 ** 32, 12345.678]
    values += (rng.standard_normal(300) * 10.0 ** rng.integers(-12, 12, 300)).tolist()
    for x in values:
        assert situated_value(x, True, scratch) == robot_module._to_bbzfloat(x), x
        assert situated_value(x, False, scratch) == robot_module._to_u8(x), x

def test_batch_threads_identical(monkeypatch, tmp_path: Path) -> None:  # noqa: ANN001
    """The kernel part split over threads (contiguous robot ranges) leaves the same robots,
    outboxes and LEDs as the reference, hand-overs included."""
    from bbzide.vm import swarm_batch
    from bbzide.vm.compiled import swarm_batch_fast

    monkeypatch.setattr(swarm_batch_fast, "MIN_ROBOTS_PER_THREAD", 4)
    swarm_batch.set_threads(3)
    try:
        assert len(swarm_batch_fast._chunks(np.arange(14))) == 3
        program = _compile(tmp_path, BATCH_HAND_OVERS)
        seen = _run_batches(program, "kilobot", 14, 12, budget=3000,
                            options={"width": 0.3, "height": 0.3})
        assert swarm_batch_fast._pool()._max_workers == 2  # this thread and two of the pool
    finally:
        swarm_batch.set_threads(1)
    assert seen["messages"] > 200


def test_batch_mixed_swarm_identical(tmp_path: Path) -> None:
    """A swarm the compiled path takes only in part: empty slots (None), robots in the
    stress mode among fast ones (they take the reference calls inside the compiled
    `control_steps`), and a robot restored from its snapshot between steps (the cached
    per-swarm tables are rebuilt; the run goes on identically)."""
    from bbzide.vm.swarm_batch import PackedMessages, control_steps

    program = _compile(tmp_path, BATCH_HAND_OVERS)
    options = {"width": 0.3, "height": 0.3}
    reference_sim = Simulation("kilobot", program, robots=10, seed=5, world_options=options,
                               robot_factory=_factory(True, 3000, "pop"), watch=())
    mixed_sim = Simulation("kilobot", program, robots=10, seed=5, world_options=options,
                           robot_factory=lambda p, prof, rid, hosts: Robot(
                               p, prof, rid, host_functions=hosts, instruction_budget=3000,
                               stress_gc=rid % 3 == 1), watch=())
    teams = [[s.robot for s in sim.robots] for sim in (reference_sim, mixed_sim)]
    for team in teams:
        team[4] = None
    boxes = [PackedMessages.empty(), PackedMessages.empty()]
    for step in range(10):
        if step == 5:
            for team in teams:
                team[2].restore(team[2].snapshot())
        stepping = np.array([(i + step) % 4 != 0 for i in range(10)])
        a, b = (control_steps(team, _deliveries(box, sim, 0.12, 1000.0), stepping,
                              reference=ref)
                for team, box, sim, ref in zip(teams, boxes, (reference_sim, mixed_sim),
                                               (True, False), strict=True))
        for column in ("robots", "payloads", "lengths"):
            assert (getattr(a.outbox, column) == getattr(b.outbox, column)).all(), step
        assert (a.failed == b.failed).all(), step
        assert (reference_sim.leds == mixed_sim.leds).all(), step
        boxes = [a.outbox, b.outbox]
        assert 4 not in a.outbox.robots.tolist()
    for x, y in zip(*teams, strict=True):
        if x is not None:
            assert Robot.comparable(x.snapshot()) == Robot.comparable(y.snapshot())


def test_batch_robot_leaving_stress_mode_is_taken_identically(tmp_path: Path) -> None:
    """A robot switched from the stress mode to the fast mode between two steps (no new VM,
    so nothing tells the cached tables) is taken by the compiled step and stays exact."""
    from bbzide.vm.swarm_batch import PackedMessages, control_steps

    program = load_script(REPO / "examples/kilobot/gradient.bzz",
                          WORLDS["kilobot"].host_names, [])
    options = {"width": 0.25, "height": 0.25}
    sims = [Simulation("kilobot", program, robots=6, seed=2, world_options=options,
                       robot_factory=_factory(True, 100_000, "pop"), watch=())
            for _ in range(2)]
    teams = [[s.robot for s in sim.robots] for sim in sims]
    teams[1][0].vm.stress_gc = False  # the compiled step takes robot 0 from the start
    boxes = [PackedMessages.empty(), PackedMessages.empty()]
    for step in range(6):
        if step == 3:
            teams[1][1].vm.stress_gc = False
        results = [control_steps(team, _deliveries(box, sim, 0.12, 1000.0),
                                 np.ones(6, dtype=bool), reference=ref)
                   for team, box, sim, ref in zip(teams, boxes, sims, (True, False),
                                                  strict=True)]
        boxes = [r.outbox for r in results]
        assert (boxes[0].payloads == boxes[1].payloads).all()
    assert teams[1][1].vm._packed_live  # the compiled step took it
    for x, y in zip(*teams, strict=True):
        assert Robot.comparable(x.snapshot()) == Robot.comparable(y.snapshot())


#: The stigmergy loop inside the compiled step (fastbatch: fastvstig on the packed entries):
#: equal timestamps from other robots (conflicts, with a handler: the kernel hands those
#: messages to Python), new keys learnt, repeats; a heap that fills up.
STIGMERGY_BATCH = """
var v
var conflicts = 0
var got
var tick = 0
var kept = {}
var keys = {}
function init() {
  keys[0] = "k0"
  keys[1] = "k1"
  keys[2] = "k2"
  keys[3] = "k3"
  keys[4] = "k4"
  keys[5] = "k5"
  keys[6] = "k6"
  keys[7] = "k7"
  v = stigmergy.create(1)
  v.onconflict(function(key, local, remote) {
    conflicts = conflicts + 1               # a Buzz call: the kernel hands these to Python
    return remote
  })
}
function step() {
  tick = tick + 1
  # gets before the puts (a put is Python's, and so is the rest of that step): a held key;
  # late, a key nobody put and a key that is not a string (their queries teach the others
  # new keys: the stigmergy fills up)
  got = v.get(keys[(tick + 1) % 3])
  if (id == 6 and tick > 24) {
    if (v.get("nobody") != nil or v.get(tick) != nil) { got = nil }
  }
  # (fresh ints: an entry adopted later frees the object put, as BittyBuzz does)
  v.put("shared", tick + 0)                 # the same key everywhere: conflicts
  v.put(keys[tick % 3], tick * 2)           # puts and learnt entries, repeats
  if (id == 4 and tick > 6) {
    var i = 0
    while (i < 4) {                         # this robot's heap fills up
      kept[tick * 4 + i] = {.a = i, .b = {.c = 1}}
      i = i + 1
    }
  }
  neighbors.broadcast("x", tick)
}
"""


@pytest.mark.parametrize("world", ["kilobot", "crazyflie"])
def test_batch_stigmergy_identical(monkeypatch, tmp_path: Path, world: str) -> None:  # noqa: ANN001
    program = _compile(tmp_path, STIGMERGY_BATCH, world)
    handed: list[int] = []
    kernel = inmsgs._process_vstig_compiled

    def counted(vm, *args):  # noqa: ANN001, ANN002, ANN202
        handed.append(vm.robot)
        return kernel(vm, *args)

    monkeypatch.setattr(inmsgs, "_process_vstig_compiled", counted)
    seen = (_run_batches(program, world, 7, 30, options={"width": 0.3, "height": 0.3})
            if world == "kilobot" else
            _run_batches(program, world, 7, 30, comm_range=30.0, unit=1.0))
    robots = seen["fast"]
    assert seen["messages"] > 100
    assert max(len(r.vm.vstig.entries) for r in robots) >= 4
    assert robots[4].failure is not None and "MEM" in str(robots[4].failure)
    assert len(handed) > 0  # the handler's conflicts: Python's
