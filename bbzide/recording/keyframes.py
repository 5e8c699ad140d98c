"""Keyframe bytes: a robot's snapshot stored whole, or as the blocks that changed since its last.

Design: a keyframe is one robot's `snapshot()` bytes. Between two keyframes of a robot little
of it changes: an M300 SAR drone's snapshot is ~70 KB, of which the heap is 60 KB at a fixed
offset (right after the snapshot's fixed header, vm/snapshot_layout.py), and a few KB of it are
live objects. So most keyframes are stored as a *block delta* against the robot's previous
keyframe: the snapshot cut into `BLOCK`-byte blocks, and only the blocks that differ are kept,
with their numbers.

Finding them is a few numpy operations over the bytes in place (tens of microseconds), and only the
changed blocks are compressed (compression.py). The former XOR delta ran zlib over all 70 KB
of the mostly-zero XOR (and the reader inflated 70 KB per link of a chain).
A chain is bounded by the recorder (a full keyframe every `FULL_KEYFRAME_EVERY`), and
decoding one link is a numpy scatter.

Delta layout (little-endian), then compressed: u32 snapshot length, u32 changed blocks (k),
u32 block number[k] (ascending), then the k blocks back to back (the last block of a snapshot
whose length is not a multiple of `BLOCK` is zero-padded).
"""

from __future__ import annotations

import struct
import sys
from array import array

import numpy as np

from bbzide.recording.compression import KEYFRAME_LEVEL, CompressionError, Compressor, decompress

#: 64-byte blocks: an M300 table segment is 2 + 6 x 9 = 56 bytes, so one changed value dirties
#: one or two blocks. Measured on SAR keyframes 25 steps apart, 32- to 256-byte blocks all keep
#: 10.4-11.4 KB of 70 (most of it the records then pickled after the heap, which shifted when
#: they grew; a flat snapshot keeps all but its last sections at fixed offsets), so the size
#: hardly decides; 64 = 8 words lets `encode_delta` read each block's 8 word comparisons as
#: one u64 (the code relies on it).
BLOCK = 64
#: A full keyframe every 16 of a robot; the others are deltas, so decoding one applies at most
#: 15 deltas (a numpy scatter each) to one inflated snapshot.
FULL_KEYFRAME_EVERY = 16

#: The largest snapshot a keyframe may hold: an M300 drone's (the largest profile, a 60 KB
#: heap) is ~70 KB; 16 MiB is 200x that and bounds what a crafted keyframe (its stated
#: length, its zstd frame) can make the reader allocate.
MAX_SNAPSHOT_BYTES = 16 << 20

_HEAD = struct.Struct("<II")
#: the `array` type code of a u32 (block numbers)
_U32 = "I" if array("I").itemsize == 4 else "L"


class KeyframeError(ValueError):
    """Keyframe bytes that do not decode (a corrupt recording)."""


def _blocks(data: bytes, length: int) -> np.ndarray:
    """`data` cut or zero-padded to `length` rounded up to whole blocks, as (blocks, BLOCK)."""
    count = -(-length // BLOCK)
    padded = np.zeros(count * BLOCK, dtype=np.uint8)
    kept = min(len(data), length)
    padded[:kept] = np.frombuffer(data, dtype=np.uint8, count=kept)
    return padded.reshape(count, BLOCK)


_COMPRESSOR = Compressor(KEYFRAME_LEVEL)


def encode_full(snapshot: bytes) -> bytes:
    return _COMPRESSOR.compress(snapshot)


def decode_full(stored: bytes, limit: int = MAX_SNAPSHOT_BYTES) -> bytes:
    try:
        return decompress(stored, limit)
    except CompressionError as error:
        raise KeyframeError(str(error)) from None


def encode_delta(snapshot: bytes, base: bytes) -> bytes:
    """The blocks of `snapshot` that differ from `base` (any length), compressed.

    Written for speed (one call per keyframe, on the simulation's thread): the blocks whole in
    both snapshots are compared in place as u64 words, no padded copies; only the few blocks
    past that (the last, partial one, or any the base does not reach) are compared as bytes,
    zero-padded as `_blocks` pads."""
    length = len(snapshot)
    whole = min(length, len(base)) // BLOCK
    new = np.frombuffer(snapshot, np.uint8, whole * BLOCK)
    # a block's 8 word comparisons (8 bool bytes) read as one u64 are non-zero when any differs
    differs = new.view(np.uint64) != np.frombuffer(base, np.uint64, whole * (BLOCK // 8))
    changed = np.flatnonzero(differs.view(np.uint64))
    numbers = changed.tolist()
    blocks = [new.reshape(whole, BLOCK)[changed].tobytes()]
    for at in range(whole * BLOCK, length, BLOCK):
        end = min(at + BLOCK, length)
        block = snapshot[at:end]
        if block != base[at:end].ljust(end - at, b"\0"):
            numbers.append(at // BLOCK)
            blocks.append(block.ljust(BLOCK, b"\0"))
    words = array(_U32, numbers)
    if sys.byteorder == "big":
        words.byteswap()
    return _COMPRESSOR.compress(b"".join((_HEAD.pack(length, len(numbers)), words, *blocks)))


def decode_delta(stored: bytes, base: bytes) -> bytes:
    """`encode_delta`'s snapshot back, given the same `base`."""
    # every block of a snapshot changed, with its u32 number: (BLOCK + 4) / BLOCK of it
    data = decode_full(stored, MAX_SNAPSHOT_BYTES * (BLOCK + 4) // BLOCK + _HEAD.size)
    if len(data) < _HEAD.size:
        raise KeyframeError("keyframe delta shorter than its header")
    length, count = _HEAD.unpack_from(data)
    if length > MAX_SNAPSHOT_BYTES:
        raise KeyframeError(f"keyframe delta states a {length}-byte snapshot")
    blocks = -(-length // BLOCK)
    if len(data) != _HEAD.size + 4 * count + BLOCK * count:
        raise KeyframeError("keyframe delta length does not match its block count")
    numbers = np.frombuffer(data, dtype="<u4", count=count, offset=_HEAD.size)
    if count and (int(numbers.max()) >= blocks or np.any(np.diff(numbers.astype(np.int64)) <= 0)):
        raise KeyframeError("keyframe delta names blocks outside its snapshot")
    snapshot = _blocks(base, length)
    snapshot[numbers] = np.frombuffer(data, dtype=np.uint8,
                                      offset=_HEAD.size + 4 * count).reshape(count, BLOCK)
    return snapshot.tobytes()[:length]
