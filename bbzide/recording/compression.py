"""The compressor of a recording's own blobs (keyframes; per-step VM inputs until format 3):
Zstandard.

Design: the recorder compresses one keyframe per robot every `KEYFRAME_EVERY` steps on the
simulation's thread, so the compressor's speed is recording cost. Measured on a 25-drone SAR
swarm (M300, steps 50-200): zstd level 1 compresses a 10.6 KB keyframe delta in ~110 us,
against zlib level 1's ~310 us, to sizes a few % smaller. Until format 3 each step's input
blob was compressed too (level -1, ~40 us for an M300 step's 11.7 KB, ~13 us for a Kilobot
step: a zstd call's fixed cost dominates such small blobs); format 4 leaves them to the
LZ4 compression Rerun's writer thread applies to every chunk (tests still write format 3
files, so `INPUT_LEVEL` stays). `zstandard` comes with viser already; it is pinned in
pyproject.toml because we use it directly.

A blob that does not decompress is a `CompressionError` (a corrupt recording).
"""

from __future__ import annotations

import zstandard

#: zstd level 1 for keyframes: level 3 makes full snapshots 6 % smaller (5.7 vs 6.1 KB) for
#: 40 % more time, level -1 makes deltas 20 % larger.
KEYFRAME_LEVEL = 1
#: zstd level -1 for the per-step inputs of formats 2-3: the same size as level 1 (1.30 vs
#: 1.28 KB a step) in two thirds of the time; one blob was compressed every step.
INPUT_LEVEL = -1


class CompressionError(ValueError):
    """Bytes that are not a compressed blob of ours."""


class Compressor:
    """One zstd context reused for every blob (building a context costs as much as a blob)."""

    def __init__(self, level: int) -> None:
        self._context = zstandard.ZstdCompressor(level=level)

    def compress(self, data: bytes) -> bytes:
        return self._context.compress(data)


def decompress(blob: bytes) -> bytes:
    try:
        return zstandard.ZstdDecompressor().decompress(blob)
    except zstandard.ZstdError as error:
        raise CompressionError(str(error)) from None
