"""A damaged or crafted flat keyframe (format 4) is refused with a message, never run.

A recording is untrusted input. Format 4's keyframes are flat VM snapshots
(vm/snapshot_layout.py): an int64 header, then raw sections. Decoding checks every length
against the bytes present; `VM.restore_state` checks that the registers the compiled kernels
index with (heap pointers, stack pointers, message rings) fit the VM. Before that check, a
keyframe whose `rtobj`, `stackptr`, a ring's `start`/`end` or a queue's capacity was
overwritten segfaulted, aborted ("double free") or hung the replay in a numba kernel.

Each damaged keyframe here replaces a real Kilobot robot's keyframe (stored whole), and the
robot is rebuilt at that keyframe and a few steps after it: the outcome must be a rebuilt
robot (damage the VM cannot tell, e.g. a changed counter) or a `RecordingError`.
"""

from __future__ import annotations

import random
import struct
from pathlib import Path

import pytest

from bbzide.recording import keyframes
from bbzide.recording.reader import Keyframe, Recording, read_recording
from bbzide.recording.rebuild import RobotRebuilder
from bbzide.recording.recorder import MissionRecorder, Recordable, RecordingError
from bbzide.vm import snapshot_layout
from bbzide.worlds.commands import load_script
from bbzide.worlds.engine import Simulation
from bbzide.worlds.registry import WORLDS

REPO = Path(__file__).resolve().parents[2]
#: the robot whose keyframe is damaged, and how many steps after it are re-executed
ROBOT = 2
AFTER = 3
#: int64 values written into a header field: negative, past any buffer, past a u8 index
#: (ring indices), past a u16 (stack, pc), 0 and 1
HOSTILE = (-1, -(2 ** 63), 2 ** 62, 2 ** 31, 255, 256, 65535, 0, 1)
#: where the VM's header starts inside a flat robot snapshot, and its first int64 field
VM_HEADER = snapshot_layout._ROBOT_HEAD.size
FIRST_FIELD = VM_HEADER + len(snapshot_layout.VM_MAGIC)


@pytest.fixture(scope="module")
def recorded(tmp_path_factory: pytest.TempPathFactory) -> dict:
    spec = WORLDS["kilobot"]
    program = load_script(REPO / "examples/kilobot/gradient.bzz", spec.host_names, [])
    recordable = Recordable()
    sim = Simulation("kilobot", program, robots=4, seed=5, robot_factory=recordable.factory)
    path = tmp_path_factory.mktemp("damaged") / "mission.rrd"
    with MissionRecorder(path, sim, recordable, keyframe_every=5) as recorder:
        for _ in range(12):
            sim.step()
            recorder.record_step()
    recording = read_recording(path)
    keyframe = recording.keyframes[ROBOT][1]
    snapshot = RobotRebuilder(recording).snapshot(ROBOT, keyframe)
    assert snapshot.startswith(snapshot_layout.ROBOT_MAGIC)
    return {"recording": recording, "keyframe": keyframe, "snapshot": snapshot}


def rebuild_with(recorded: dict, damaged: bytes) -> str:
    """Rebuild robot ROBOT from `damaged` as its keyframe: "rebuilt", or the refusal."""
    keyframe: Keyframe = recorded["keyframe"]
    return rebuild_from(recorded, [Keyframe(keyframe.step, keyframes.encode_full(damaged),
                                            keyframe.program)])


def rebuild_from(recorded: dict, robot_keyframes: list[Keyframe]) -> str:
    """Rebuild robot ROBOT from `robot_keyframes` from the keyframe's step on: "rebuilt", or
    the refusal."""
    recording: Recording = recorded["recording"]
    keyframe: Keyframe = recorded["keyframe"]
    saved = recording.keyframes[ROBOT]
    recording.keyframes[ROBOT] = robot_keyframes
    try:
        rebuilder = RobotRebuilder(recording)
        for step in range(keyframe.step, keyframe.step + AFTER + 1):
            rebuilder.robot_at(ROBOT, step)
    except RecordingError as error:
        return str(error)
    finally:
        recording.keyframes[ROBOT] = saved
    return "rebuilt"


def test_the_undamaged_keyframe_rebuilds(recorded: dict) -> None:
    assert rebuild_with(recorded, recorded["snapshot"]) == "rebuilt"


#: header fields that give a section's length: any other value is refused (decoding checks
#: every length against the bytes present)
LENGTHS = ("heap_bytes", "stack_entries", "vstig_entries", "ring_records", "record_bytes",
           "inbox_records", "outbox_records", "bcode_bytes", "error_events")


@pytest.mark.parametrize("field", snapshot_layout.VM_FIELDS)
def test_any_header_field_overwritten_is_refused_or_rebuilt(recorded: dict, field: str) -> None:
    """No value of any field escapes as another exception, crashes or hangs the process."""
    at = FIRST_FIELD + 8 * snapshot_layout.VM_FIELDS.index(field)
    (original,) = struct.unpack_from("<q", recorded["snapshot"], at)
    for value in HOSTILE:
        damaged = bytearray(recorded["snapshot"])
        struct.pack_into("<q", damaged, at, value)
        outcome = rebuild_with(recorded, bytes(damaged))
        if field in LENGTHS and value != original:
            assert outcome != "rebuilt", (field, value)


@pytest.mark.parametrize("field, value", [
    ("rtobj", 2 ** 62), ("rtobj", 1 << 20), ("ltseg", -(2 ** 63)), ("ltseg", 2 ** 31),
    ("stackptr", 2 ** 31), ("ring_start", 255), ("ring_end", 1 << 20),
    ("inbox_capacity", 65535), ("inbox_end", 65535), ("outbox_start", -1)])
def test_registers_past_their_buffers_are_refused_before_running(
        recorded: dict, field: str, value: int) -> None:
    """The values that crashed the replay process (segfault, abort, hang) before the check."""
    damaged = bytearray(recorded["snapshot"])
    struct.pack_into("<q", damaged, FIRST_FIELD + 8 * snapshot_layout.VM_FIELDS.index(field),
                     value)
    refusal = rebuild_with(recorded, bytes(damaged))
    assert "do not fit this profile's VM" in refusal, refusal


def test_flipped_or_cut_bytes_are_refused_or_rebuilt(recorded: dict) -> None:
    snapshot, rng = recorded["snapshot"], random.Random(6)
    refused = 0
    for trial in range(120):
        damaged = bytearray(snapshot)
        if trial % 4 == 0:
            damaged = damaged[:rng.randrange(len(damaged))]
        else:
            for _ in range(rng.choice((1, 4, 32))):
                damaged[rng.randrange(len(damaged))] = rng.randrange(256)
        outcome = rebuild_with(recorded, bytes(damaged))
        refused += outcome != "rebuilt"
    assert refused >= 30  # every cut at least (a quarter of the trials) is refused


def test_a_protocol_0_pickle_is_refused_not_unpickled(recorded: dict, tmp_path: Path) -> None:
    """A pickle of protocol 0 or 1 has no 0x80 prefix: the allow-list unpickler used to let it
    through unchecked to `pickle.loads`, which ran the code it named (here: a shell command
    that writes a file), at the top level and as a robot snapshot's VM snapshot."""
    import pickle

    marker = tmp_path / "ran.txt"
    command = f"echo ran > {marker}".encode()
    crafted = b"cos\nsystem\n(S'" + command + b"'\ntR."
    assert not crafted.startswith(b"\x80")
    nested = pickle.dumps((crafted, None, 3, True))  # the layout of a pickled robot snapshot
    for payload in (crafted, nested):
        refusal = rebuild_with(recorded, payload)
        assert "not a VM snapshot" in refusal or "does not fit" in refusal, refusal
    assert not marker.exists()


def test_a_pickle_of_another_shape_is_refused(recorded: dict) -> None:
    """Allowed names only, but not a robot's state: refused, not a TypeError."""
    import pickle

    for payload in (pickle.dumps(5), pickle.dumps((b"\x80", None)), pickle.dumps([1, 2, 3, 4])):
        assert rebuild_with(recorded, payload) != "rebuilt"


def test_a_pickled_keyframe_with_registers_of_other_types_is_refused(recorded: dict) -> None:
    """Formats 2-3 keep pickled keyframes: the allow-list lets lists, strings and floats
    through, and a list as the pc escaped as a TypeError from the debug map's lookup."""
    import pickle

    from bbzide.vm.robot import Robot

    vm_state, failure, steps_done, booted = Robot.decode_snapshot(recorded["snapshot"])
    pickled = pickle.dumps((pickle.dumps(vm_state), failure, steps_done, booted))
    assert rebuild_with(recorded, pickled) == "rebuilt"  # the same state, pickled
    for at, value in ((4, []), (2, "0"), (7, 1.5), (14, None), (5, 1)):
        state = list(vm_state)
        state[at] = value
        crafted = pickle.dumps((pickle.dumps(tuple(state)), failure, steps_done, booted))
        assert "do not fit this profile's VM" in rebuild_with(recorded, crafted), (at, value)


def test_a_bit_flipped_in_a_stored_keyframe_is_refused(recorded: dict) -> None:
    """The stored bytes themselves (compressed, as the recorder wrote them): their zstd
    checksum refuses a flipped bit that would otherwise decompress to another robot."""
    recording: Recording = recorded["recording"]
    keyframe: Keyframe = recorded["keyframe"]
    stored = list(recording.keyframes[ROBOT])
    at = stored.index(keyframe)
    assert rebuild_from(recorded, stored) == "rebuilt"
    rng = random.Random(7)
    for _trial in range(40):
        damaged = bytearray(keyframe.snapshot)
        damaged[rng.randrange(len(damaged))] ^= 1 << rng.randrange(8)
        flipped = list(stored)
        flipped[at] = Keyframe(keyframe.step, bytes(damaged), keyframe.program, keyframe.base)
        outcome = rebuild_from(recorded, flipped)
        assert outcome != "rebuilt"
        assert "checksum" in outcome or "corrupt" in outcome or "keyframe" in outcome, outcome
