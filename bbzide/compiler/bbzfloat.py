"""bbzfloat: BittyBuzz's 16-bit floating-point format (spec §D.4, BBZ:src/bittybuzz/bbzfloat.c).

Layout: sign = bit 15, exponent = bits 14..9 (6 bits, bias 31), fraction = bits 8..0 (9 bits).
It is *not* IEEE half precision; the reference conversion has quirks this module keeps on
purpose, because `bo2bbo` and the VM must produce the same bits as the firmware:

* encoding truncates the float32 mantissa (no rounding);
* a float32 whose exponent does not fit (tiny non-zero values included) becomes infinity;
* a float32 NaN keeps its *low* 9 mantissa bits (a standard quiet NaN becomes infinity);
* exponent 0 with a non-zero fraction decodes as (1 + f/512) * 2**-31, not as a denormal.

Arithmetic on bbzfloats converts to float32, operates in float32 and re-encodes; `to_float32`
rounds a Python float (a double) to the nearest float32 for that purpose.
"""

from __future__ import annotations

import math
import struct

SIGN_BIT = 0x8000
EXPONENT_SHIFT = 9
EXPONENT_MASK = 0x3F  # 6 bits
FRACTION_MASK = 0x1FF  # 9 bits
#: bbzfloat exponent bias: exponent field 31 means 2**0.
EXPONENT_BIAS = 31
#: float32 exponent bias (127) minus the bbzfloat bias (31): float32 exponent E maps to E - 96.
FLOAT32_TO_BBZ_EXPONENT_OFFSET = 96
#: Exponent field 63 with fraction 0: the infinity the encoder produces.
INFINITY_EXPONENT = 63
POSITIVE_INFINITY = INFINITY_EXPONENT << EXPONENT_SHIFT  # 0x7E00
NEGATIVE_ZERO = SIGN_BIT

_FLOAT32 = struct.Struct("<f")
_UINT32 = struct.Struct("<I")


def to_float32(value: float) -> float:
    """Round a Python float to the nearest float32 (inf on overflow), as C would store it."""
    try:
        return _FLOAT32.unpack(_FLOAT32.pack(value))[0]
    except OverflowError:
        return math.copysign(math.inf, value)


def float32_bits(value: float) -> int:
    """The IEEE-754 single-precision bit pattern of `value` (rounded to float32 first)."""
    return _UINT32.unpack(_FLOAT32.pack(to_float32(value)))[0]


def from_float32_bits(bits: int) -> int:
    """Encode a float32 given by its bit pattern as a bbzfloat (`bbzfloat_fromfloat`)."""
    sign = (bits >> 31) & 1
    exponent = (bits >> 23) & 0xFF
    mantissa = bits & 0x7FFFFF
    if exponent == 0:
        return sign << 15
    if exponent == 0xFF:
        return (sign << 15) | (INFINITY_EXPONENT << EXPONENT_SHIFT) | (mantissa & FRACTION_MASK)
    if FLOAT32_TO_BBZ_EXPONENT_OFFSET < exponent < FLOAT32_TO_BBZ_EXPONENT_OFFSET + 62:
        bbz_exponent = exponent - FLOAT32_TO_BBZ_EXPONENT_OFFSET
        return (sign << 15) | (bbz_exponent << EXPONENT_SHIFT) | (mantissa >> 14)
    return (sign << 15) | POSITIVE_INFINITY


def from_float(value: float) -> int:
    """Encode a Python float as a bbzfloat (rounded to float32 first, as the C code does)."""
    return from_float32_bits(float32_bits(value))


def to_float(bbz: int) -> float:
    """Decode a bbzfloat (`bbzfloat_tofloat`) to a Python float (exact: bbzfloats are float32s)."""
    sign = -1.0 if bbz & SIGN_BIT else 1.0
    exponent = (bbz >> EXPONENT_SHIFT) & EXPONENT_MASK
    fraction = bbz & FRACTION_MASK
    if exponent == 0:
        if fraction == 0:
            return sign * 0.0
        return sign * (1.0 + fraction / 512.0) * 2.0**-31
    if exponent >= 62:
        return sign * math.inf
    return sign * (1.0 + fraction / 512.0) * 2.0 ** (exponent - EXPONENT_BIAS)


def negate(bbz: int) -> int:
    """`bbzfloat_neg`: flip the sign bit."""
    return bbz ^ SIGN_BIT
