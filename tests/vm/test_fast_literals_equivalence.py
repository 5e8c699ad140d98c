"""Table literals (``pusht``) and lambdas (``pushl``) in the fast mode against the reference.

The compiled kernel (``fastloop``) runs ``pusht`` and ``pushl`` on their happy path and hands
every other case back to the model: a heap too full for the objects or segments, no free
reserved slot for a lambda's activation record, a full stack. These scripts are made of
those instructions — lambdas at the top level (no activation record) and inside functions
and other lambdas (a copy of the caller's locals in a reserved slot), kept alive in tables
so that the reserved slots and the heap run out — and every observable byte must be the
reference's: after each chunk of a few instructions (the run stopped by its budget, as an
inspector pausing the VM), and at the end.
"""

from __future__ import annotations

import dataclasses

import pytest

from bbzide.compiler import compile_source
from bbzide.vm import vm as vm_module
from bbzide.vm.compiled import fastloop
from bbzide.vm.profiles import CRAZYFLIE, KILOBOT, PC, Profile
from tests.vm.chunked_runs import assert_modes_agree, run_whole

SCRIPTS = {
    "lambdas kept in tables": """
kept = {}
total = 0
function make(k) {
  var base = k * 2
  var f = function(x) { return {.x = x, .b = base} }
  var t = {.a = f(1).x, .b = {}, .c = {.d = {}, .e = k}}
  kept[k % 7] = {.f = f, .t = t}
  return f
}
i = 0
while (i < 30) {
  g = make(i)
  h = function(y) { return {.y = y} }
  kept[7 + i % 3] = {.g = g(i), .h = h(i)}
  total = total + i
  i = i + 1
}
""",
    "nested lambdas": """
acc = {}
function outer(k) {
  var a = k
  var b = {.k = k}
  var inner = function(x) {
    var c = x + a
    var deeper = function(y) { return y + c + a }
    acc[x % 5] = deeper
    return deeper(x)
  }
  return inner(k)
}
i = 0
s = 0
while (i < 25) {
  s = s + outer(i)
  acc[10 + i % 3] = function(z) { return {.z = z} }
  i = i + 1
}
""",
    "many locals copied": """
keep = {}
function wide(p) {
  var a = p var b = p + 1 var c = p + 2 var d = p + 3 var e = p + 4 var f = p + 5
  var g = p + 6 var h = p + 7 var j = p + 8 var k = p + 9 var l = p + 10 var m = p + 11
  var fn = function(x) { return x + a + m }
  keep[p % 9] = fn
  return fn(p)
}
i = 0
s = 0
while (i < 20) {
  s = s + wide(i)
  t = {}
  t[i] = {}
  i = i + 1
}
""",
}

def _bbo(name: str) -> bytes:
    return compile_source(SCRIPTS[name], "literals.bzz").to_bbo().bbo


PROFILES = [PC, KILOBOT, CRAZYFLIE,
            # the heap runs out (table segments, closures, records: MEM where it happens)
            dataclasses.replace(KILOBOT, name="small heap", heap_size=760),
            dataclasses.replace(PC, name="small pc heap", heap_size=1300),
            # the reserved slots for activation records run out
            dataclasses.replace(PC, name="few records", rsv_actrec=3)]


@pytest.mark.parametrize("name", sorted(SCRIPTS))
@pytest.mark.parametrize("profile", PROFILES, ids=lambda p: p.name)
def test_literals_and_lambdas_identical(name: str, profile: Profile) -> None:
    assert_modes_agree(_bbo(name), profile, 400, name)


@pytest.mark.skipif(not fastloop.COMPILED, reason="the kernel runs as Python without numba")
@pytest.mark.parametrize("opcode", [30, 40])
def test_the_kernel_runs_the_happy_path(opcode: int) -> None:
    """On a roomy heap the model's own ``op_pusht``/``op_pushl`` are not called in the
    fast mode: the kernel ran those instructions (the scripts above test its bytes)."""
    calls = []
    if opcode == 30:
        table, index = vm_module._SIMPLE_OPS, 30
    else:
        table, index = vm_module._OPERAND_OPS, 40 - 35
    original = table[index]

    def counted(*args: object) -> None:
        calls.append(args)
        original(*args)  # type: ignore[operator]

    table[index] = counted  # type: ignore[assignment]
    try:
        bbo = _bbo("lambdas kept in tables")
        stress = run_whole(bbo, PC, True)
        assert calls  # the reference mode runs every instruction in Python
        calls.clear()
        fast = run_whole(bbo, PC, False)
    finally:
        table[index] = original
    assert fast == stress
    assert calls == []
