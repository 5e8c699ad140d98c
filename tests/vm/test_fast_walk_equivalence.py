"""The compiled walks (``fasthost.xtreme_walk``/``table_walk``) against the reference.

``neighbors.foreach``/``reduce``/``map``/``filter`` and the table library's ``foreach``,
``map``, ``filter`` and ``reduce`` hand their per-element closure calls to machine code in
the fast mode; each must leave every observable byte as the reference mode does (heap
bytes, mark bits, rtobj/ltseg, stack, pc, state, errors, GC runs, instruction counts) after
every control step, on an XTREME build (the ring) and on heap-table builds, including the
cases where the kernel hands back: a heap too full for a neighbour's objects, a closure
calling a host function or another walk, an error inside the closure, a closure returning
nothing, the instruction budget running out. A ``distance`` host function the kernel
computes in place (``host.RoundedDistanceHostFunction``) runs inside the walks, with its own
hand-backs: a float argument, a result beyond an int16, a wrong argument count.
"""

from __future__ import annotations

import math

import pytest

from bbzide.compiler import bbzfloat, bittybuzz_string_table, compile_source
from bbzide.vm import neighbors
from bbzide.vm.host import HostCall
from bbzide.vm.kernels import fasthost
from bbzide.vm.profiles import CRAZYFLIE, KILOBOT, PC, Profile
from bbzide.vm.vm import VM, State
from tests.vm.chunked_runs import assert_same_runs, observe, observe_steps

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
    "table foreach": """
pos = {}
total = 0
function step() {
  pos[1] = 30
  pos[2] = 12
  pos[3] = 1.5
  pos[4] = -7
  pos[5] = 30000
  pos[6] = nil
  total = 0
  foreach(pos, function(k, v) {
    total = total + distance(k, v, -k, 4)
    if (k == 2) { pos[6] = 8
                  pos[1] = nil }
  })
}
""",
    "table foreach with neighbours": """
far = 0
function step() {
  var kept = {}
  neighbors.foreach(function(rid, data) { kept[rid] = rid * 3 })
  far = 0
  foreach(kept, function(rid, v) {
    if (distance(rid, v, 0, 0) > 20) { far = far + 1 }
    neighbors.foreach(function(r2, d2) { far = far + distance(r2, 0, rid, 0) })
  })
}
""",
    "table map filter reduce": """
kept = 0
sum = 0
function step() {
  var t = {}
  var i = 0
  while (i < 12) { t[i] = i * 7 - 20
                   i = i + 1 }
  t.name = 9
  var halves = map(t, function(k, v) { if (k == 3) { return nil } return v / 2 })
  var odd = filter(t, function(k, v) { if (k == 5) { return "yes" } return v % 2 })
  var big = filter(t, function(k, v) { return distance(v, 0, 0, 0) > 30 })
  sum = reduce(t, function(k, v, acc) { if (k == 7) { t[20] = 1 } return acc + v }, 0)
  var longest = reduce(halves, function(k, v, acc) { return {.k = k, .prev = acc} }, nil)
  kept = size(halves) + size(odd) + size(big)
}
""",
    "table reduce without return": """
function step() {
  var x = reduce({.a = 1, .b = 2}, function(k, v, acc) { acc = 1 }, 0)
}
""",
    "table foreach errors": """
n = 0
function step() {
  n = n + 1
  var t = {.a = 1, .b = 2, .c = 3}
  foreach(t, function(k, v) {
    if (n == 2) { var x = distance(1, 2, 3) }
    if (n == 3 and v == 2) { var y = distance(1, 2, 3, "far") }
    if (n == 4 and v == 3) { v = v + t }
  })
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


def _distance(vm: VM) -> None:
    """An M300's ``distance`` (``worlds/m300.py``), on the VM directly."""
    call = HostCall(vm)
    if not call.expect_args(4):
        return
    x1, y1, x2, y2 = call.args
    if not all(isinstance(a, int | float) for a in (x1, y1, x2, y2)):
        call.fail("TYPE")
        return
    call.ret(int(round(math.hypot(x1 - x2, y1 - y2))))  # type: ignore[operator]


def _run(source: str, profile: Profile, stress: bool, count: int, budget: int | None
         ) -> list[tuple]:
    program = compile_source(source, "walk.bzz",
                             string_table=bittybuzz_string_table(["led", "distance"])).to_bbo()
    vm = VM(profile, stress_gc=stress)
    if budget is not None:
        vm.instruction_budget = budget
    vm.construct()
    vm.set_bcode(program.bbo)
    vm.function_register(program.strings.index("led"), "led", _led)
    vm.function_register(program.strings.index("distance"), "distance", _distance)
    vm.host.mark_computed("distance", fasthost.HOST_DISTANCE, 4)
    vm.run(max_instructions=100_000)
    states = [observe(vm)]
    vm.state = State.READY
    for rid in range(1, count + 1):
        values = (10.0 * rid, 3.0 * rid, 0.0)
        if profile.neighbors_floats:
            d, a, e = (bbzfloat.from_float(v) for v in values)
        else:
            d, a, e = (min(255, round(v)) for v in values)
        neighbors.add(vm, neighbors.NeighborEntry(rid, d, a, e))
    states.append(observe(vm))
    return states + observe_steps(vm, program.strings.index("step"), STEPS)


@pytest.mark.parametrize("name", sorted(SCRIPTS))
@pytest.mark.parametrize("profile", [KILOBOT, CRAZYFLIE, PC], ids=lambda p: p.name)
def test_walks_identical(name: str, profile: Profile) -> None:
    count = min(15, profile.neighbors_cap)
    budget = 150 if name == "budget" else None
    assert_same_runs(_run(SCRIPTS[name], profile, True, count, budget),
                     _run(SCRIPTS[name], profile, False, count, budget),
                     f"{name} on {profile.name}, observation (0: loaded, 1: neighbours "
                     "added, then one per step)")


@pytest.mark.parametrize("heap_size", [300, 360, 420, 480])
def test_walks_identical_on_a_full_heap(heap_size: int) -> None:
    """A heap with no room for a neighbour's objects: the kernel hands the neighbour back
    (or the reference runs out of memory at the same allocation)."""
    small = Profile(name="small", heap_size=heap_size, ptr_size=2, xtreme=True,
                    neighbors_floats=False, float_ops=False)
    for name in ("foreach", "reduce", "map and filter", "table map filter reduce"):
        stress = _run(SCRIPTS[name], small, True, 15, None)
        fast = _run(SCRIPTS[name], small, False, 15, None)
        assert stress == fast, f"{name} with a {heap_size}-byte heap"


@pytest.mark.parametrize("dx", [0, 1, 2, 3, 7, 100, 181, 255, 4095, 32767, 65535, -65535])
def test_rounded_distance_is_pythons_rounded_hypot(dx: int) -> None:
    """``fasthost.rounded_distance`` (integers only) against ``round(math.hypot)``."""
    for dy in (*range(-300, 301), 32767, -32768, 65535, 46341, 23170):
        assert fasthost.rounded_distance(dx, dy) == int(round(math.hypot(dx, dy))), (dx, dy)
