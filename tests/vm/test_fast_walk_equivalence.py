"""The compiled neighbour walks (``fasthost.xtreme_walk``/``table_walk``) against the reference.

``neighbors.foreach``/``reduce``/``map``/``filter`` hand their per-neighbour closure calls to
machine code in the fast mode; each must leave every observable byte as the reference mode
does (heap bytes, mark bits, rtobj/ltseg, stack, pc, state, errors, GC runs, instruction
counts) after every control step, on an XTREME build (the ring) and on heap-table builds,
including the cases where the kernel hands back: a heap too full for a neighbour's objects,
a closure calling a host function or another walk, an error inside the closure, a closure
returning nothing, the instruction budget running out.
"""

from __future__ import annotations

import pytest

from bbzide.compiler import bbzfloat, bittybuzz_string_table, compile_source
from bbzide.vm import neighbors
from bbzide.vm.profiles import CRAZYFLIE, KILOBOT, PC, Profile
from bbzide.vm.vm import VM, State

#: control steps per run: enough for the walks to reach a steady heap and for the
#: collections to reuse freed slots
STEPS = 6

SCRIPTS = {
    "foreach": """
seen = 0
far = {}
function step() {
  seen = 0
  neighbors.foreach(function(rid, data) {
    seen = seen + 1
    if (data.distance > 40) { far[rid] = {.d = data.distance} }
  })
}
""",
    "reduce": """
best = 0
function step() {
  best = neighbors.reduce(function(rid, data, acc) {
    if (data.distance < acc) { acc = data.distance }
    return acc
  }, 1000)
}
""",
    "map and filter": """
kept = 0
function step() {
  var near = neighbors.filter(function(rid, data) { return data.distance < 50 })
  var hops = neighbors.map(function(rid, data) { return data.distance / 10 })
  var odd = neighbors.filter(function(rid, data) { return rid % 2 })
  kept = near.count() + odd.count()
}
""",
    "map without return": """
function step() {
  var m = neighbors.map(function(rid, data) { var x = 1 })
}
""",
    "host and nested walk": """
total = 0
function step() {
  total = 0
  neighbors.foreach(function(rid, data) {
    led(rid % 7)
    total = total + neighbors.reduce(function(r2, d2, acc) { return acc + 1 }, 0)
  })
}
""",
    "error inside": """
n = 0
function step() {
  n = 0
  neighbors.foreach(function(rid, data) {
    n = n + 1
    var t = {}
    if (n == 3) { n = n + t }
  })
}
""",
    "reduce without return": """
function step() {
  var x = neighbors.reduce(function(rid, data, acc) { acc = 1 }, 0)
}
""",
    "budget": """
function step() {
  neighbors.foreach(function(rid, data) {
    var i = 0
    while (i < 200) { i = i + 1 }
  })
}
""",
}


def _led(vm: VM) -> None:
    vm.ret0()


def _observe(vm: VM) -> tuple:
    return (vm.state, vm.error, vm.pc, list(vm.stack[:vm.stackptr + 1]), vm.blockptr,
            vm.heap.rtobj, vm.heap.ltseg, bytes(vm.heap.data), list(vm.error_events),
            vm.heap.gc_runs, vm.instructions_executed, vm.heap.peak_used)


def _run(source: str, profile: Profile, stress: bool, count: int, budget: int | None
         ) -> list[tuple]:
    program = compile_source(source, "walk.bzz",
                             string_table=bittybuzz_string_table(["led"])).to_bbo()
    vm = VM(profile, stress_gc=stress)
    if budget is not None:
        vm.instruction_budget = budget
    vm.construct()
    vm.set_bcode(program.bbo)
    vm.function_register(program.strings.index("led"), "led", _led)
    vm.run(max_instructions=100_000)
    states = [_observe(vm)]
    vm.state = State.READY
    for rid in range(1, count + 1):
        values = (10.0 * rid, 3.0 * rid, 0.0)
        if profile.neighbors_floats:
            d, a, e = (bbzfloat.from_float(v) for v in values)
        else:
            d, a, e = (min(255, round(v)) for v in values)
        neighbors.add(vm, neighbors.NeighborEntry(rid, d, a, e))
    states.append(_observe(vm))
    step = program.strings.index("step")
    for _ in range(STEPS):
        vm.push_nil()
        vm.function_call(step, 0)
        states.append(_observe(vm))
        if vm.state == State.ERROR:
            break
        vm.pop()
    return states


@pytest.mark.parametrize("name", sorted(SCRIPTS))
@pytest.mark.parametrize("profile", [KILOBOT, CRAZYFLIE, PC], ids=lambda p: p.name)
def test_walks_identical(name: str, profile: Profile) -> None:
    count = min(15, profile.neighbors_cap)
    budget = 150 if name == "budget" else None
    stress = _run(SCRIPTS[name], profile, True, count, budget)
    fast = _run(SCRIPTS[name], profile, False, count, budget)
    assert len(stress) == len(fast)
    for step, (a, b) in enumerate(zip(stress, fast, strict=True)):
        assert a == b, f"{name} on {profile.name}: differs after step {step - 2}"


@pytest.mark.parametrize("heap_size", [300, 360, 420, 480])
def test_walks_identical_on_a_full_heap(heap_size: int) -> None:
    """A heap with no room for a neighbour's objects: the kernel hands the neighbour back
    (or the reference runs out of memory at the same allocation)."""
    small = Profile(name="small", heap_size=heap_size, ptr_size=2, xtreme=True,
                    neighbors_floats=False, float_ops=False)
    for name in ("foreach", "reduce", "map and filter"):
        stress = _run(SCRIPTS[name], small, True, 15, None)
        fast = _run(SCRIPTS[name], small, False, 15, None)
        assert stress == fast, f"{name} with a {heap_size}-byte heap"
