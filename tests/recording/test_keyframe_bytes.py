"""Keyframe bytes (bbzide/recording/keyframes.py): a block delta gives back the snapshot exactly
whatever the lengths, stores only what changed, and damaged bytes are an error, not a state."""

from __future__ import annotations

import random

import pytest

from bbzide.recording import keyframes


def changed_copy(base: bytes, length: int, edits: int, rng: random.Random) -> bytes:
    data = bytearray(base[:length].ljust(length, b"\x07"))
    for _ in range(edits if length else 0):
        data[rng.randrange(length)] ^= 1 + rng.randrange(255)
    return bytes(data)


def test_a_delta_round_trips_for_any_lengths() -> None:
    rng = random.Random(3)
    base = bytes(rng.randrange(256) for _ in range(5000))
    for length in (0, 1, 63, 64, 65, 4999, 5000, 5001, 6000):  # shorter, equal, longer
        snapshot = changed_copy(base, length, 5, rng)
        stored = keyframes.encode_delta(snapshot, base)
        assert keyframes.decode_delta(stored, base) == snapshot, length
    assert keyframes.decode_full(keyframes.encode_full(base)) == base


def test_a_delta_keeps_only_the_changed_blocks() -> None:
    rng = random.Random(4)
    base = bytes(rng.randrange(256) for _ in range(64 * 1000))
    one_change = changed_copy(base, len(base), 1, rng)
    assert len(keyframes.encode_delta(one_change, base)) < 200   # one 64-byte block and a number
    assert len(keyframes.encode_delta(base, base)) < 40          # nothing changed


def test_damaged_keyframe_bytes_are_refused() -> None:
    base = bytes(range(256)) * 4
    stored = keyframes.encode_delta(base[::-1], base)
    with pytest.raises(keyframes.KeyframeError):
        keyframes.decode_delta(stored[:-5], base)
    with pytest.raises(keyframes.KeyframeError):
        keyframes.decode_full(b"not a compressed keyframe")
    # A well-compressed delta whose block numbers point outside its snapshot.
    forged = keyframes._COMPRESSOR.compress(keyframes._HEAD.pack(64, 1) + (5).to_bytes(4, "little")
                                            + bytes(64))
    with pytest.raises(keyframes.KeyframeError, match="outside"):
        keyframes.decode_delta(forged, base)


def test_a_delta_holds_exactly_the_blocks_that_differ_once_zero_padded() -> None:
    """`encode_delta` compares whole blocks in place and the rest as bytes: against a block by
    block reading of the padded snapshots, it keeps the same blocks, whatever the lengths."""
    rng = random.Random(5)
    block = keyframes.BLOCK
    for _ in range(200):
        length = rng.choice([0, 1, block - 1, block, block + 1, 3 * block + 5, 700])
        base = bytes(rng.randrange(2) for _ in range(max(0, length + rng.randrange(-90, 90))))
        snapshot = changed_copy(base, length, rng.randrange(4), rng)
        padded = -(-length // block) * block
        new, old = snapshot.ljust(padded, b"\0"), base[:length].ljust(padded, b"\0")
        expected = [k for k in range(padded // block)
                    if new[k * block:(k + 1) * block] != old[k * block:(k + 1) * block]]
        data = keyframes.decode_full(keyframes.encode_delta(snapshot, base))
        count = keyframes._HEAD.unpack_from(data)[1]
        numbers = [int.from_bytes(data[8 + 4 * i:12 + 4 * i], "little") for i in range(count)]
        assert numbers == expected, (length, len(base))
        blocks = data[8 + 4 * count:]
        assert blocks == b"".join(new[k * block:(k + 1) * block] for k in expected)
