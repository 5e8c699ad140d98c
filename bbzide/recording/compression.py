"""The compressor of a recording's own blobs (keyframes, VM inputs): Zstandard.

Design: the recorder compresses one keyframe per robot every `KEYFRAME_EVERY` steps on the
simulation's thread, so the compressor's speed is recording cost. Measured on a 25-drone SAR
swarm (M300, steps 50-200): zstd level 1 compresses a 10.6 KB keyframe delta in ~110 us,
against zlib level 1's ~310 us, to sizes a few % smaller. Until format 3 each step's input
blob was compressed alone (level -1, ~40 us for an M300 step's 11.7 KB, ~13 us for a Kilobot
step: a zstd call's fixed cost dominates such small blobs); format 4 compresses a flush's
input blobs as one frame (~5 us a Kilobot step, ~7 an M300 step). Left to the LZ4 that
Rerun's writer thread applies to every chunk, the raw inputs cost that thread more (~14 us a
Kilobot step, ~25 more for SAR) and the file grew. `zstandard` comes with viser already; it
is pinned in pyproject.toml because we use it directly.

Every blob carries zstd's content checksum (4 bytes: the low half of the XXH64 of its
decompressed bytes), which the decompressor verifies on every read. Without it a flipped bit
mostly decompressed to other bytes without a word: flipping the lowest bit of each byte of a
481-byte frame, 458 of the 481 frames gave wrong bytes silently; with it every one was
refused, so a damaged keyframe or input frame no longer rebuilds a different robot.
Older recordings' blobs have none and still open (the frame header says whether one is there).

A blob that does not decompress is a `CompressionError` (a corrupt recording). A recording
is untrusted input: a zstd frame states its decompressed size in its header and zstandard
allocates that much before decompressing (a 13-byte crafted frame asked for 2^40 bytes:
MemoryError), and a frame of zeros compresses ~32000:1, so `decompress` refuses a frame that
states more than `limit` bytes, or none (ours always state it).
"""

from __future__ import annotations

import zstandard

#: zstd level 1 for keyframes: level 3 makes full snapshots 6 % smaller (5.7 vs 6.1 KB) for
#: 40 % more time, level -1 makes deltas 20 % larger.
KEYFRAME_LEVEL = 1
#: zstd level -1 for the inputs: a Kilobot flush's 2.7 KB a step compress to 1.48 KB in
#: 4.8 us a step (level 1: 1.38 KB, 6.9 us; level 3: 1.31 KB, 8.7 us), an M300 flush's
#: 8.1 KB to 0.85 KB in 6.8 us (level 1: the same size, 10 us). Formats 2-3: per step.
INPUT_LEVEL = -1


class CompressionError(ValueError):
    """Bytes that are not a compressed blob of ours."""


class Compressor:
    """One zstd context reused for every blob (building a context costs as much as a blob)."""

    def __init__(self, level: int) -> None:
        self._context = zstandard.ZstdCompressor(level=level, write_checksum=True)

    def compress(self, data: bytes) -> bytes:
        return self._context.compress(data)


#: The most bytes a blob of ours decompresses to: the largest is a flush's input frame, ~4 MB
#: for 500 steps of a 25-drone M300 swarm (8.1 KB a step); 256 MiB leaves 60x that for larger
#: swarms and bounds what a crafted frame can make the reader allocate. The recorder cannot
#: write a larger one: a flush comes at least every `FLUSH_SECONDS` (10 s), and the fastest
#: input producer we have, 1,000 gradient Kilobots at ~15 steps/s with ~10,000 receptions of
#: ~16 bytes a step, makes ~25 MB in 10 s (measured: ~9,000 deliveries a step, 40 recorded
#: steps in 3.0 s, so ~19 MB of raw inputs in 10 s).
MAX_BLOB_BYTES = 256 << 20


def decompress(blob: bytes, limit: int = MAX_BLOB_BYTES) -> bytes:
    """`blob` decompressed, refused unless its frame states a size of at most `limit` bytes."""
    try:
        size = zstandard.frame_content_size(blob)
        if not 0 <= size <= limit:
            raise CompressionError(f"a compressed blob states {size} bytes (at most {limit})"
                                   if size >= 0 else "a compressed blob states no size")
        return zstandard.ZstdDecompressor().decompress(blob)
    except zstandard.ZstdError as error:
        raise CompressionError(str(error)) from None
