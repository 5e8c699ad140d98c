"""Damaged or crafted compressed blobs and input rows are refused, with bounded allocations.

A recording is untrusted input. A zstd frame states its decompressed size and zstandard
allocates that much first, so a 13-byte frame could ask for 2^40 bytes (a MemoryError escaped)
and a 32 KB frame of zeros grew to 1 GiB; a keyframe delta's u32 length made the reader build a
snapshot of up to 4 GiB; a flat snapshot whose message records were 0 bytes long let any
record count pass the length checks (a loop of 2^40 records). A flush of inputs (format 4)
whose steps repeat or go backwards, or whose rows hold other types, is refused.
"""

from __future__ import annotations

import struct
from pathlib import Path

import numpy as np
import pyarrow as pa
import pytest
import zstandard

from bbzide.recording import keyframes, layout
from bbzide.recording.compression import (
    INPUT_LEVEL,
    MAX_BLOB_BYTES,
    CompressionError,
    Compressor,
    decompress,
)
from bbzide.recording.reader import _input_steps
from bbzide.recording.recorder import RecordingError
from bbzide.vm import snapshot_layout
from bbzide.vm.messages import VS_DATA
from bbzide.vm.profiles import PROFILES
from bbzide.vm.vm import VM


def frame_stating(size: int) -> bytes:
    """A zstd frame whose header states `size` bytes, holding one empty raw block."""
    single_segment_8_byte_size = 0xE0
    last_raw_block_of_0_bytes = b"\x01\x00\x00"
    return (b"\x28\xb5\x2f\xfd" + bytes([single_segment_8_byte_size]) + struct.pack("<Q", size)
            + last_raw_block_of_0_bytes)


@pytest.mark.parametrize("size", [MAX_BLOB_BYTES + 1, 2 ** 40, 2 ** 62])
def test_a_frame_stating_a_huge_size_is_refused_before_allocating(size: int) -> None:
    with pytest.raises(CompressionError, match="states"):
        decompress(frame_stating(size))
    with pytest.raises(keyframes.KeyframeError):
        keyframes.decode_full(frame_stating(size))


def test_a_frame_of_zeros_past_the_limit_is_refused_and_one_within_opens() -> None:
    bomb = zstandard.ZstdCompressor(level=3).compress(bytes(MAX_BLOB_BYTES + 64))
    assert len(bomb) < MAX_BLOB_BYTES // 1000  # the ratio that made it a bomb
    with pytest.raises(CompressionError, match="states"):
        decompress(bomb)
    snapshot = bytes(keyframes.MAX_SNAPSHOT_BYTES + 1)
    with pytest.raises(keyframes.KeyframeError):
        keyframes.decode_full(keyframes.encode_full(snapshot))
    assert keyframes.decode_full(keyframes.encode_full(snapshot[:70_000])) == snapshot[:70_000]


def test_a_frame_stating_no_size_is_refused() -> None:
    unsized = zstandard.ZstdCompressor(write_content_size=False).compress(b"inputs" * 100)
    with pytest.raises(CompressionError, match="no size"):
        decompress(unsized)



def flipped_bits(blob: bytes) -> list[bytes]:
    """`blob` with one bit flipped, for every bit."""
    out = []
    for at in range(len(blob)):
        for bit in range(8):
            damaged = bytearray(blob)
            damaged[at] ^= 1 << bit
            out.append(bytes(damaged))
    return out


def test_a_flipped_bit_in_any_blob_is_refused_never_read_as_other_bytes() -> None:
    """Blobs carry zstd's content checksum. Without it most flipped bits of a keyframe or an
    input frame decompressed to other bytes without a word (the contrast below), and the replay
    rebuilt a different robot."""
    snapshot = VM(PROFILES["kilobot"], 3).snapshot()
    later = bytearray(snapshot)
    later[200:264] = bytes(range(64))
    inputs = b"".join(struct.pack("<HHh", i, i * 7 % 300, -i) for i in range(200))
    blobs = {
        "full keyframe": keyframes.encode_full(snapshot),
        "keyframe delta": keyframes.encode_delta(bytes(later), snapshot),
        "input frame": Compressor(INPUT_LEVEL).compress(inputs),
    }
    for name, blob in blobs.items():
        original, refused = decompress(blob), 0
        for damaged in flipped_bits(blob):
            try:
                opened = decompress(damaged)
            except CompressionError:
                refused += 1
            else:
                assert opened == original, f"{name}: a flipped bit read as other bytes"
        assert refused >= 0.95 * 8 * len(blob), (name, refused)
    unchecked = zstandard.ZstdCompressor(level=INPUT_LEVEL).compress(inputs)
    assert decompress(unchecked) == inputs  # blobs of recordings made before the checksum
    silent = sum(1 for damaged in flipped_bits(unchecked)
                 if _opens_as_other_bytes(damaged, inputs))
    assert silent > len(unchecked), "without the checksum most flips pass unseen"


def _opens_as_other_bytes(blob: bytes, original: bytes) -> bool:
    try:
        return decompress(blob) != original
    except CompressionError:
        return False

def test_a_delta_stating_a_huge_snapshot_is_refused() -> None:
    base = bytes(range(256)) * 8
    delta = keyframes.decode_full(keyframes.encode_delta(base[:-64] + b"x" * 64, base))
    for length in (keyframes.MAX_SNAPSHOT_BYTES + 1, 2 ** 32 - 1):
        crafted = struct.pack("<I", length) + delta[4:]
        with pytest.raises(keyframes.KeyframeError, match="states"):
            keyframes.decode_delta(keyframes.encode_full(crafted), base)


def test_zero_byte_message_records_are_refused() -> None:
    data = bytearray(VM(PROFILES["kilobot"], 3).snapshot())
    fields = snapshot_layout.VM_FIELDS
    for name, value in (("obj_size", -VS_DATA), ("record_bytes", 0), ("inbox_records", 2 ** 40)):
        struct.pack_into("<q", data, len(snapshot_layout.VM_MAGIC) + 8 * fields.index(name),
                         value)
    with pytest.raises(snapshot_layout.SnapshotError, match="record size"):
        snapshot_layout.decode_vm(bytes(data))


def flush(frame: object, steps: list, ends: object) -> dict:
    row = np.array([40])
    # steps past an int64 only fit a u64 column
    past_int64 = any(isinstance(step, int) and step >= 2 ** 63 for step in steps)
    typed = pa.array([steps], pa.list_(pa.uint64())) if past_int64 else pa.array([steps])
    return {(layout.INPUTS, "inputs"): [(row, pa.array([[frame]]))],
            (layout.INPUTS, "input_steps"): [(row, typed)],
            (layout.INPUTS, "input_ends"): [(row, pa.array([ends]))]}


def test_a_flush_whose_steps_repeat_go_back_or_have_other_types_is_refused() -> None:
    blobs = [b"a", b"bb", b"ccc"]
    frame = Compressor(INPUT_LEVEL).compress(b"".join(blobs))
    (steps, opened), = _input_steps(flush(frame, [40, 41, 42], [1, 3, 6]), Path("x.rrd"))
    assert steps.tolist() == [40, 41, 42] and opened == blobs
    for damaged in (flush(frame, [40, 40, 42], [1, 3, 6]), flush(frame, [41, 40, 42], [1, 3, 6]),
                    flush(frame, ["forty", "41", "42"], [1, 3, 6]),
                    flush(frame, [40, 41, 2 ** 63 + 5], [1, 3, 6]),
                    flush(frame, [40, 41, 42], ["one", "3", "6"]),
                    flush(frame, [40, 41, 42], [1, 3, 2 ** 40]),
                    flush(frame, [40, 41, 42], [-5, 3, 6]),
                    flush("not bytes", [40, 41, 42], [1, 3, 6]),
                    flush(frame_stating(2 ** 40), [40, 41, 42], [1, 3, 6])):
        with pytest.raises(RecordingError, match="corrupt"):
            _input_steps(damaged, Path("x.rrd"))


def test_crafted_mission_metadata_is_refused_when_read() -> None:
    """The per-robot metadata the replay indexes by robot: a short list, a missing key or a
    string where a number belongs escaped as KeyError/IndexError/ValueError from a seek."""
    import json

    from bbzide.recording.reader import _meta

    good = {"format": layout.FORMAT, "version": layout.FORMAT_VERSION, "robots": 2,
            "profiles": ["kilobot", "kilobot"], "robot_ids": [0, 1],
            "host_names": [["led"], ["led"]], "latched": [[["led", 1]], [["led", 1]]]}

    def read(meta: dict) -> dict:
        return _meta({f"{layout.MISSION}:meta": pa.array([[json.dumps(meta)]])}, Path("x.rrd"))

    assert read(good) == good
    assert read({**good, "latched": None})["robots"] == 2  # format 2: nothing latched
    for change in ({"version": "four"}, {"robots": "2"}, {"robots": -1},
                   {"profiles": ["kilobot"]}, {"profiles": None}, {"robot_ids": ["0", "1"]},
                   {"host_names": [["led"]]}, {"latched": [5, 5]}):
        with pytest.raises(RecordingError, match="unreadable mission metadata"):
            read({**good, **change})
    for key in ("profiles", "robot_ids", "host_names", "robots"):
        with pytest.raises(RecordingError, match="unreadable mission metadata"):
            read({k: v for k, v in good.items() if k != key})


def test_a_file_that_crashes_rerun_s_reader_is_refused_when_isolated(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """rerun 0.41's reader aborts the process on some damaged payloads (one byte changed at
    the right place; which place depends on the file). The replay reads a file in a child
    process first: a child killed by a signal (here made to abort) means a refusal, and a
    sound file still opens that way."""
    from bbzide.recording import reader
    from bbzide.recording.recorder import MissionRecorder
    from tests.recording.test_recording import toy_swarm

    sim, recordable = toy_swarm()
    path = tmp_path / "mission.rrd"
    with MissionRecorder(path, sim, recordable, flush_every=4) as recorder:
        for _ in range(6):
            sim.step()
            recorder.record_step()
    assert reader.read_recording(path, isolated=True).last_step == 6
    cut = tmp_path / "cut.rrd"  # a killed writer's file is read through a prefix copy
    cut.write_bytes(path.read_bytes()[:-40])
    assert reader.read_recording(cut, isolated=True).truncated
    monkeypatch.setattr(reader, "_TRIAL_READ", "import os\nos.abort()\n")
    for damaged in (path, cut):
        with pytest.raises(RecordingError, match="Rerun's reader crashed"):
            reader.read_recording(damaged, isolated=True)
