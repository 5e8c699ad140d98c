"""A host function's record (``HostCall.ret`` of a dict, e.g. a drone's ``position()``)
built by the kernel (``fasthost.push_int_record``) against the reference's Python.

Every observable byte must match after every step (heap bytes, rtobj/ltseg, stack, pc,
lsyms, state, errors, GC runs, instruction counts), on heaps from roomy to full: the kernel
builds the table only when the stack and the heap have room for all of it and hands the
rest to Python (which then runs out of memory at the same allocation as the reference).
A record with a float, and ints beyond 16 bits (wrapped as ``new_int`` wraps them), take
their own paths.
"""

from __future__ import annotations

import pytest

from bbzide.compiler import bittybuzz_string_table, compile_source
from bbzide.vm.host import HostCall
from bbzide.vm.profiles import PC, Profile
from bbzide.vm.vm import VM, State
from tests.vm.chunked_runs import assert_same_runs, observe, observe_steps

#: control steps per run: enough to fill the smaller heaps
STEPS = 60

SCRIPT = """
kept = {}
n = 0
function step() {
  n = n + 1
  var p = where(n)
  kept[n % 7] = p
  if (n % 11 == 0) { kept = {} }
  var q = drift(n)
}
"""
NAMES = ["where", "drift", "x", "y", "z", "cell"]


def _run(profile: Profile, stress: bool) -> list[tuple]:
    program = compile_source(SCRIPT, "record.bzz",
                             string_table=bittybuzz_string_table(NAMES)).to_bbo()
    strings = program.strings

    def where(vm: VM) -> None:
        n = HostCall(vm, strings).arg(1)
        HostCall(vm, strings).ret({"x": n * 3000, "y": -n, "z": n % 2 == 0, "cell": n})

    def drift(vm: VM) -> None:
        n = HostCall(vm, strings).arg(1)
        HostCall(vm, strings).ret({"x": n / 4, "y": n})

    vm = VM(profile, stress_gc=stress)
    vm.construct()
    vm.set_bcode(program.bbo)
    vm.function_register(strings.index("where"), "where", where)
    vm.function_register(strings.index("drift"), "drift", drift)
    vm.run(max_instructions=100_000)
    states = [observe(vm)]
    vm.state = State.READY
    return states + observe_steps(vm, strings.index("step"), STEPS)


#: from a heap that runs out of memory after two steps to one that never does; the sizes
#: between run out after 3 to 8 steps, at one call site or the other
HEAP_SIZES = [1400, 1550, 1720, 1730, 1740, 1750, 1810, 1820, 1830, 4000]


@pytest.mark.parametrize("heap_size", HEAP_SIZES)
def test_records_identical(heap_size: int) -> None:
    profile = Profile(name="record", heap_size=heap_size, ptr_size=PC.ptr_size)
    assert_same_runs(_run(profile, True), _run(profile, False),
                     f"{heap_size}-byte heap, step")


def test_the_smallest_heap_runs_out_of_memory_and_the_largest_does_not() -> None:
    """The heaps above cover both ends: a run that ends in MEM and one that never does."""
    small = _run(Profile(name="record", heap_size=HEAP_SIZES[0], ptr_size=PC.ptr_size), False)
    large = _run(Profile(name="record", heap_size=HEAP_SIZES[-1], ptr_size=PC.ptr_size),
                 False)
    assert small[-1][1].name == "MEM"
    assert len(large) == STEPS + 1 and large[-1][0] != State.ERROR
