"""Float arithmetic in the compiled kernel against the model, bit for bit.

The kernel (``fastloop``) decodes bbzfloats to doubles, operates on doubles and encodes the
result through float32, as the model does (``bbzfloat.to_float``/``from_float`` and
``VM._arith``). Checked here: the two conversions over every bbzfloat and over doubles at
every rounding and range edge of float32; the five operations over operand pairs at the
edges (zeros of both signs, infinities, the largest and smallest magnitudes, ints at their
limits), against the model's own instruction routines; and scripts doing float arithmetic
run in both modes, compared after every chunk of a few instructions.
"""

from __future__ import annotations

import dataclasses
import math
import random
import struct
from collections.abc import Callable

import pytest

from bbzide.compiler import bbzfloat, compile_source
from bbzide.vm import vm as vm_module
from bbzide.vm.compiled import fastloop
from bbzide.vm.heap import FLOAT, INT
from bbzide.vm.profiles import CRAZYFLIE, KILOBOT, PC, Profile
from bbzide.vm.vm import VM, State
from tests.vm.chunked_runs import assert_modes_agree, run_whole


def _double_bits(x: float) -> bytes:
    return struct.pack("<d", x)


def _float32_from_bits(bits: int) -> float:
    return struct.unpack("<f", struct.pack("<I", bits))[0]


def test_decoding_every_bbzfloat() -> None:
    for bits in range(1 << 16):
        assert _double_bits(fastloop._float_value(bits)) == \
            _double_bits(bbzfloat.to_float(bits)), hex(bits)


def _encoding_edges() -> list[float]:
    """Doubles at the edges of the encoding: every bbzfloat's value and its neighbours,
    float32s around each exponent with the halfway points between them (ties round to
    even), the float32 range's ends (overflow, denormals), and random doubles."""
    values = [0.0, -0.0, math.inf, -math.inf, math.nan, -math.nan, 1e300, -1e300,
              1e-300, 5e-324, -5e-324]
    for bits in range(1 << 16):
        x = bbzfloat.to_float(bits)
        values += [x, math.nextafter(x, math.inf), math.nextafter(x, -math.inf)]
    rng = random.Random(20261128)
    mantissas = [0, 1, 0x1FF, 0x200, 0x3FFF, 0x4000, 0x4001, 0x7FFFFE, 0x7FFFFF]
    for exponent in range(0, 255):
        for mantissa in mantissas + [rng.randrange(1 << 23) for _ in range(4)]:
            for sign in (0, 1 << 31):
                bits = sign | (exponent << 23) | mantissa
                low = _float32_from_bits(bits)
                high = _float32_from_bits(bits + 1)  # the next float32 (or infinity)
                values += [low, math.nextafter(low, math.inf), math.nextafter(low, -math.inf)]
                if math.isfinite(high):
                    middle = (low + high) / 2  # exact in a double
                    values += [middle, math.nextafter(middle, math.inf),
                               math.nextafter(middle, -math.inf)]
    largest = _float32_from_bits(0x7F7FFFFF)
    half_ulp = math.ldexp(1.0, 103)  # half a float32 ulp at the largest exponent
    for sign in (1.0, -1.0):
        values += [sign * largest, sign * (largest + half_ulp),
                   sign * math.nextafter(largest + half_ulp, 0.0),
                   sign * math.nextafter(largest + half_ulp, math.inf)]
    for _ in range(20000):
        values.append(rng.uniform(-1.0, 1.0) * math.ldexp(1.0, rng.randrange(-160, 140)))
    return values


def test_encoding_every_edge() -> None:
    for x in _encoding_edges():
        assert fastloop._float_bits(x) == bbzfloat.from_float(x), x.hex()


#: operand bits: zeros, infinities (exponents 62 and 63), the largest and smallest
#: magnitudes, exponent 0 with a fraction, ones, and a few others
FLOAT_OPERANDS = [0x0000, 0x8000, 0x7E00, 0xFE00, 0x7C00, 0xFC01, 0x7BFF, 0xFBFF, 0x0001,
                  0x8001, 0x0200, 0x81FF, 0x3E00, 0xBE00, 0x3F00, 0x4000, 0xC000, 0x3E01,
                  0x5E00, 0x2E00, 0x4A3F, 0xB5A5]
#: int operands (their u16 payload; the modulo reads the dividend's unsigned)
INT_OPERANDS = [0, 1, -1, 2, -7, 7, 1000, 32767, -32768, -12345]


def _model_result(vm: VM, op: int, left: tuple[int, int], right: tuple[int, int]
                  ) -> tuple[int, int] | None:
    """(type, u16) the model's instruction leaves on top, None when it errs."""
    for typ, value in (left, right):
        if typ == FLOAT:
            vm.push_float(value)
        else:
            vm.push_int(value)
    vm_module._SIMPLE_OPS[op](vm)
    if vm.state != State.READY:
        return None
    top = vm.stack[vm.stackptr]
    return vm.heap.obj_type(top), vm.heap.u16(top)


def test_arithmetic_at_the_edges() -> None:
    vm = VM(PC, stress_gc=False)
    vm.construct()
    vm.state = State.READY
    pairs = [((FLOAT, a), (FLOAT, b)) for a in FLOAT_OPERANDS for b in FLOAT_OPERANDS]
    pairs += [((INT, i), (FLOAT, f)) for i in INT_OPERANDS for f in FLOAT_OPERANDS]
    pairs += [((FLOAT, f), (INT, i)) for i in INT_OPERANDS for f in FLOAT_OPERANDS]
    checked = 0
    for op in (7, 8, 9, 10, 11):
        for left, right in pairs:
            vm.stackptr = -1
            model = _model_result(vm, op, left, right)
            assert model is not None and model[0] == FLOAT, (op, left, right)
            kernel = fastloop._float_arith(op, left[0], left[1] & 0xFFFF, right[0],
                                           right[1] & 0xFFFF)
            assert kernel == model[1], (op, left, right)
            checked += 1
            if checked % 64 == 0:
                vm.stackptr = -1
                vm.gc()
    assert checked == 5 * len(pairs)


SCRIPTS = {
    "mixed arithmetic": """
x = 0.5
y = 3
z = -2.25
acc = {}
i = 0
while (i < 40) {
  x = x * 1.5 + y / 4.0 - z
  z = -z % 7.0
  acc[i % 4] = {.q = x / z, .r = (y + i) % 2.5, .s = i * 0.25, .n = -x}
  if (x > 100.0) { x = x / 1000.0 }
  if (z <= 0.0) { z = z - 1 }
  y = y + 1
  i = i + 1
}
""",
    "overflow, zeros and nan": """
big = 2.0
zero = 0.0
r = {}
i = 0
while (i < 45) {
  big = big * 3.0
  r[0] = big - big
  r[1] = big / zero
  r[2] = zero / zero
  r[3] = -big / zero
  r[4] = i % zero
  r[5] = big % 3.0
  r[6] = 5.0 % big
  r[7] = zero * big
  r[8] = (big == big) + (big > r[0]) + (r[2] < 1.0)
  r[9] = -zero + -zero
  i = i + 1
}
""",
    "floats in functions and lambdas": """
function scale(v, k) { return v * k + 0.125 }
function wrap(k) {
  var g = function(a) { return a * 0.5 - 1 }
  return g(k) + scale(k, 1.5)
}
out = {}
i = 0
while (i < 30) {
  out[i % 3] = wrap(i * 0.75) / 3
  out[3] = -out[i % 3] % 1.5
  i = i + 1
}
""",
}

def _bbo(name: str) -> bytes:
    return compile_source(SCRIPTS[name], "floats.bzz").to_bbo().bbo


PROFILES = [PC, CRAZYFLIE, KILOBOT,  # Kilobot: no float operations (TYPE errors)
            dataclasses.replace(CRAZYFLIE, name="small heap", heap_size=900)]


@pytest.mark.parametrize("name", sorted(SCRIPTS))
@pytest.mark.parametrize("profile", PROFILES, ids=lambda p: p.name)
def test_float_scripts_identical(name: str, profile: Profile) -> None:
    assert_modes_agree(_bbo(name), profile, 600, name)


@pytest.mark.skipif(not fastloop.COMPILED, reason="the kernel runs as Python without numba")
def test_the_kernel_runs_float_arithmetic() -> None:
    """In the fast mode the model's own add/sub/mul/div/mod/unm routines see no float
    operand on a roomy heap: the kernel ran them (the tests above check its bits)."""
    float_calls = []
    originals = {op: vm_module._SIMPLE_OPS[op] for op in range(7, 14)}

    def counting(op: int) -> Callable[[VM], None]:
        def routine(vm: VM) -> None:
            top = vm.stack[vm.stackptr]
            below = vm.stack[vm.stackptr - 1] if vm.stackptr > 0 and op != 13 else top
            if FLOAT in (vm.heap.obj_type(top), vm.heap.obj_type(below)) and op != 12:
                float_calls.append(op)
            originals[op](vm)
        return routine

    for op in originals:
        vm_module._SIMPLE_OPS[op] = counting(op)
    try:
        bbo = _bbo("mixed arithmetic")
        stress = run_whole(bbo, PC, True)
        assert float_calls  # the reference mode runs them in Python
        float_calls.clear()
        fast = run_whole(bbo, PC, False)
    finally:
        for op, routine in originals.items():
            vm_module._SIMPLE_OPS[op] = routine
    assert fast == stress
    assert float_calls == []
