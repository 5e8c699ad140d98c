"""Whole swarms in the fast VM mode against the reference mode: identical robots, step by step.

The fast mode processes a robot's in-queue in compiled code (``bbzide/vm/fastinbox.py``) and
hands back to the Python routines whenever anything unusual happens: a stigmergy message, a
listener that calls a host function or runs an instruction the kernel does not cover, an
error or the budget inside a listener, a full stack or heap. Each scenario below runs the
same swarm twice — robots built with ``stress_gc=True`` (the reference: Python routines, a
collection before every instruction) and with the default fast mode — and compares every
robot's observable state after every step: heap bytes, ROP/LSP, stack, registers, error
events, collection count, queues and neighbor records, failure.
"""

from __future__ import annotations

import pickle
from pathlib import Path

import pytest

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


def test_heap_filling_listener_identical(tmp_path: Path) -> None:
    """A listener that keeps what it hears until the Kilobot heap is full (MEM)."""
    program = _compile(tmp_path, """
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
""")
    _run_both(program, "kilobot", 10, 25, options={"width": 0.25, "height": 0.25})


def test_growing_stack_identical() -> None:
    """The firmware loop (``loop="robot"``) leaves each step's result on the stack: the
    listeners meet a stack with less and less room, down to the STACK error."""
    program = load_script(REPO / "examples/kilobot/gradient.bzz",
                          WORLDS["kilobot"].host_names, [])
    _run_both(program, "kilobot", 3, 96, options={"width": 0.2, "height": 0.2}, loop="robot")
