"""bbzfloat encoding and decoding against the vectors of spec §D.4 (verified on the reference)."""

import math

import pytest

from bbzide.compiler import bbzfloat

ENCODE_VECTORS = [
    (1.0, 0x3E00),
    (1.5, 0x3F00),
    (2.5, 0x4080),
    (-2.0, 0xC000),
    (0.5, 0x3C00),
    (100.0, 0x4B20),
    (0.1, 0x3733),
    (3.14159, 0x4124),
    (65504.0, 0x5DFF),
    (1e-10, 0x7E00),  # tiny non-zero values become infinity (reference bug, kept)
    (1e10, 0x7E00),
    (-0.0, 0x8000),
    (0.0, 0x0000),
]


@pytest.mark.parametrize(("value", "bits"), ENCODE_VECTORS)
def test_encode_matches_reference(value: float, bits: int) -> None:
    assert bbzfloat.from_float(value) == bits


@pytest.mark.parametrize(
    ("bits", "value"),
    [(0x3733, 0.0999755859375), (0x4124, 3.140625), (0x5DFF, 65472.0), (0x0001, 4.66571e-10)],
)
def test_decode_matches_reference(bits: int, value: float) -> None:
    assert bbzfloat.to_float(bits) == pytest.approx(value, rel=1e-5)


def test_quiet_nan_becomes_infinity_and_exponent_62_decodes_as_infinity() -> None:
    assert bbzfloat.from_float32_bits(0x7FC00000) == 0x7E00
    assert bbzfloat.from_float32_bits(0x7F800001) == 0x7E01
    assert math.isinf(bbzfloat.to_float(62 << 9))


def test_every_finite_bbzfloat_round_trips() -> None:
    for bits in range(0x10000):
        exponent = (bits >> 9) & 0x3F
        if exponent in (0, 62, 63):
            continue
        assert bbzfloat.from_float(bbzfloat.to_float(bits)) == bits
