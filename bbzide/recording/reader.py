"""Reads a bbzide mission recording (`.rrd`) back into arrays, tolerating a cut-off tail.

Design: a replay needs random access to every step (seek <= 100 ms), so the whole recording is
read once into numpy arrays indexed by step (positions, LED colours, headings, failure flags,
labels, heap figures, message counters), plus the rare rows (keyframes, programs, events,
overlays) as sorted lists. Reading goes through `rerun.chunk.RrdReader(...).stream()` and each
chunk's Arrow record batch (no DataFusion needed).

Checks, each a `RecordingError` that says what is wrong:
* not starting with Rerun's `RRF2` header: not an `.rrd` at all (foreign file);
* an `.rrd` without our `/mission` metadata (`layout.FORMAT`): some other program's recording;
* another `layout.FORMAT_VERSION` (older or newer); rows that do not decode; steps missing
  in the middle.

A file whose writer was killed ends without Rerun's footer, maybe in the middle of a message.
`rrd_frames` walks Rerun's framing (12-byte file header; then messages of a u64 kind and a u64
length, both little-endian; kind 0 = end of stream, whose payload is the footer's index, then a
32-byte footer). Unless that end message and footer are whole, the file is read as truncated:
only its whole data messages go to a temporary file that Rerun then reads (so a cut anywhere,
even inside the end message, opens). Entities are flushed one after the other, so the
recording ends at the last step that *every* per-step entity reached; a cut before the first
flush (no mission metadata) is refused as holding no complete data.
"""

from __future__ import annotations

import json
import os
import struct
import tempfile
import warnings
from collections import defaultdict
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from bbzide.recording import layout
from bbzide.recording.recorder import RecordingError

RRD_MAGIC = b"RRF2"
#: "RRF2", a 4-byte version and 4 bytes of encoding options (rerun 0.41 `re_log_encoding`).
FILE_HEADER_BYTES = 12
#: Each message: u64 kind, u64 payload length (little-endian), then the payload.
MESSAGE_HEADER = struct.Struct("<QQ")
END_OF_STREAM = 0
#: After the end-of-stream message: u64 start and u64 length of the index, a u32 checksum,
#: "RRF2FOOT" and a u32 footer version (rerun 0.41's `StreamFooter`).
FOOTER_BYTES = 32
FOOTER_MAGIC = b"RRF2FOOT"

#: Per-step columns every recording has; a step counts only once all of them reached it.
_PER_STEP = (
    (layout.ROBOTS, "Points3D:positions"),
    (layout.ROBOTS, "heading"),
    (layout.MESSAGES, "sent"),
    (f"{layout.HEAP}/used", "Scalars:scalars"),
    (f"{layout.HEAP}/gc_runs", "Scalars:scalars"),
    (layout.MESSAGE_TOTALS, "Scalars:scalars"),
    (layout.LINKS, "pairs"),
    (layout.INPUTS, "inputs"),
)


def rrd_frames(data: bytes) -> tuple[int, bool]:
    """(bytes of complete data messages incl. the header, whether the stream ended cleanly).

    Rerun's end-of-stream message carries the footer's index in its payload and is followed by
    the 32-byte footer; the stream ended cleanly only if both are whole. A writer killed while
    writing them left every data message whole, so the data ends where that message starts.
    """
    end = FILE_HEADER_BYTES
    while end + MESSAGE_HEADER.size <= len(data):
        kind, length = MESSAGE_HEADER.unpack_from(data, end)
        after = end + MESSAGE_HEADER.size + length
        if kind == END_OF_STREAM:
            footer = data[after:]
            return end, len(footer) == FOOTER_BYTES and footer[-12:-4] == FOOTER_MAGIC
        if after > len(data):
            break
        end = after
    return end, False


@dataclass
class Keyframe:
    step: int
    snapshot: bytes  # keyframes.py bytes: a Robot.snapshot(), full or a block delta
    program: int
    base: int = -1   # step of the keyframe a delta applies to (-1: this one is full)


@dataclass
class Event:
    step: int
    kind: str
    robot: int  # robot index, -1 for the whole swarm
    text: str


@dataclass
class Recording:
    path: Path
    meta: dict[str, Any]
    steps: np.ndarray                      # (S,) int64, consecutive
    positions: np.ndarray                  # (S, N, 3) float32, metres
    headings: np.ndarray                   # (S, N) float32, radians
    leds: np.ndarray                       # (S, N, 3) uint8
    failed: np.ndarray                     # (S, N) bool
    labels: dict[str, np.ndarray]          # name -> (S, N) str
    heap: dict[str, np.ndarray]            # figure -> (S, N) int64
    messages: dict[str, np.ndarray]        # sent/received/bytes_sent -> (S, N) int64
    totals: np.ndarray                     # (S, 4): sent, received, dropped, bytes
    links: list[np.ndarray]                # per step (M, 2) robot indexes
    inputs: list[bytes]                    # per step: inputs that led to it (input_log blob)
    keyframes: dict[int, list[Keyframe]] = field(default_factory=dict)  # robot index -> sorted
    programs: dict[int, dict[str, Any]] = field(default_factory=dict)
    events: list[Event] = field(default_factory=list)
    overlays: list[tuple[int, dict[str, Any]]] = field(default_factory=list)
    truncated: bool = False                # the writer did not close the file

    @property
    def first_step(self) -> int:
        return int(self.steps[0])

    @property
    def last_step(self) -> int:
        return int(self.steps[-1])

    @property
    def robot_count(self) -> int:
        return int(self.meta["robots"])

    def row(self, step: int) -> int:
        if not self.first_step <= step <= self.last_step:
            raise RecordingError(f"step {step} is outside the recording "
                                 f"({self.first_step}..{self.last_step})")
        return step - self.first_step

    def overlays_at(self, step: int) -> dict[str, Any]:
        current: dict[str, Any] = {}
        for at, overlays in self.overlays:
            if at > step:
                break
            current = overlays
        return current


#: What a child process runs on a recording before this one reads it (`isolated=True`): the
#: chunk stream `_read_columns` reads, nothing kept. (`-I`: no user site, no PYTHONPATH.)
_TRIAL_READ = ("import sys, warnings\nwarnings.simplefilter('ignore')\n"
               "from rerun.chunk import RrdReader\n"
               "for chunk in RrdReader(sys.argv[1]).stream():\n    chunk.to_record_batch()\n")


def _crashes_rerun(readable: Path) -> bool:
    """Whether Rerun's reader kills the process that reads `readable`.

    rerun 0.41's reader (Rust, arrow-rs) panics on some damaged Arrow payloads in a thread of
    its own, which aborts the whole process (measured: one byte changed in a chunk's payload,
    "the offset of the new Buffer cannot exceed the existing length"; another file: "memory
    allocation of 8247061105401226112 bytes failed"). No exception reaches Python, so the
    replay reads a file in a child process first (~0.75 s for a 15 MB recording) and refuses
    it if that child dies by a signal. Other failures are left to the reading itself."""
    import subprocess
    import sys

    trial = subprocess.run([sys.executable, "-I", "-c", _TRIAL_READ, str(readable)],
                           capture_output=True, check=False)
    return trial.returncode < 0


def read_recording(path: Path | str, isolated: bool = False) -> Recording:
    """The recording at `path`, or a `RecordingError` saying why it cannot be read.
    `isolated`: Rerun's reader first reads it in a child process (`_crashes_rerun`)."""
    path = Path(path)
    try:
        data = path.read_bytes()
    except FileNotFoundError:
        raise RecordingError(f"no such recording: {path}") from None
    except OSError as error:
        raise RecordingError(f"cannot read {path}: {error.strerror}") from None
    if data[:4] != RRD_MAGIC:
        raise RecordingError(f"{path} is not a Rerun recording (.rrd): it does not start with "
                             f"the {RRD_MAGIC.decode()} header")
    complete, ended = rrd_frames(data)
    if complete <= FILE_HEADER_BYTES:
        raise RecordingError(f"{path} holds no complete data (cut off before its first flush)")
    if ended:
        columns = _read_columns(path, path, isolated)
    else:  # Rerun reads only whole messages: hand it the complete prefix
        with tempfile.NamedTemporaryFile(suffix=".rrd", delete=False) as prefix:
            prefix.write(data[:complete])
        try:
            columns = _read_columns(Path(prefix.name), path, isolated)
        finally:
            os.unlink(prefix.name)
        if f"{layout.MISSION}:meta" not in columns[1]:  # the first flush did not survive
            raise RecordingError(f"{path} holds no complete data (cut off before its first "
                                 "flush, or not a bbzide recording)")
    return _assemble(path, columns, truncated=not ended)


Columns = dict[tuple[str, str], list[tuple[np.ndarray, Any]]]


def _read_columns(readable: Path, shown: Path, isolated: bool = False
                  ) -> tuple[Columns, dict[str, Any]]:
    from rerun.chunk import RrdReader

    if isolated and _crashes_rerun(readable):
        raise RecordingError(f"{shown} is a corrupt recording: Rerun's reader crashed on it")
    columns: Columns = defaultdict(list)
    static: dict[str, Any] = {}
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # "no footer" on a killed writer's file
            stream = RrdReader(str(readable)).stream()
            for chunk in stream:
                batch = chunk.to_record_batch()
                entity = chunk.entity_path
                names = batch.schema.names
                if chunk.is_static:
                    for name in names:
                        if not name.startswith("rerun."):
                            static[f"{entity}:{name}"] = batch.column(name)
                    continue
                if layout.TIMELINE not in names:
                    continue
                steps = batch.column(layout.TIMELINE).to_numpy(zero_copy_only=False)
                for name in names:
                    if name.startswith("rerun.") or name in (layout.TIMELINE,
                                                             layout.TIME_SECONDS):
                        continue
                    columns[(entity, name)].append((steps, batch.column(name)))
    except (RuntimeError, ValueError, OSError) as error:
        if "No recording store" in str(error):  # only Rerun's store-info messages were whole
            return columns, static
        raise RecordingError(f"{shown} is a corrupt recording: {error}") from None
    return columns, static


def _meta(static: dict[str, Any], path: Path) -> dict[str, Any]:
    raw = static.get(f"{layout.MISSION}:meta")
    if raw is None:
        raise RecordingError(f"{path} is a Rerun recording, but not one of bbzide's (it has no "
                             f"{layout.MISSION} metadata)")
    try:
        meta = json.loads(raw.flatten()[0].as_py())
    except (ValueError, IndexError, TypeError) as error:
        raise RecordingError(f"{path}: unreadable mission metadata ({error})") from None
    if not isinstance(meta, dict) or meta.get("format") != layout.FORMAT:
        raise RecordingError(f"{path} is a Rerun recording, but not one of bbzide's")
    version = meta.get("version", 0)
    if type(version) is not int:
        raise RecordingError(f"{path}: unreadable mission metadata (format {version!r})")
    if version > layout.FORMAT_VERSION:
        raise RecordingError(f"{path} was written by a newer bbzide (format {version}; this "
                             f"one reads {layout.FORMAT_VERSION})")
    if version < layout.OLDEST_READABLE:
        raise RecordingError(f"{path} was written by an older bbzide (format {version}; this "
                             f"one reads {layout.OLDEST_READABLE}-{layout.FORMAT_VERSION}): "
                             "record the mission again")
    _check_robots(meta, path)
    return meta


def _check_robots(meta: dict[str, Any], path: Path) -> None:
    """The per-robot metadata the replay indexes by robot: one entry per robot, of its type
    (a crafted file's short list or string id escaped as an IndexError or ValueError)."""
    robots = meta.get("robots")
    per_robot = {"profiles": str, "robot_ids": int, "host_names": list}
    if meta.get("latched") is not None:  # format 3 on: each robot's latched host functions
        per_robot["latched"] = list
    if type(robots) is not int or robots < 0:
        raise RecordingError(f"{path}: unreadable mission metadata (robots {robots!r})")
    for key, kind in per_robot.items():
        values = meta.get(key)
        if type(values) is not list or len(values) != robots or \
                any(type(value) is not kind for value in values):
            raise RecordingError(f"{path}: unreadable mission metadata ({key} is not one "
                                 f"{kind.__name__} per robot)")


def _rows(parts: list[tuple[np.ndarray, Any]]) -> tuple[np.ndarray, list[Any]]:
    """All rows of one column, sorted by step: (steps, per-row python/arrow values)."""
    steps = np.concatenate([s for s, _ in parts]) if parts else np.zeros(0, np.int64)
    values: list[Any] = []
    for _, column in parts:
        values.extend(column[i] for i in range(len(column)))
    order = np.argsort(steps, kind="stable")
    return steps[order], [values[i] for i in order]


def _dense(parts: list[tuple[np.ndarray, Any]], first: int, last: int, width: int,
           inner: int = 0) -> np.ndarray:
    """A per-step, per-robot column as an (S, width[, inner]) array for steps first..last."""
    pieces = []
    for steps, column in parts:
        keep = (steps >= first) & (steps <= last)
        if not keep.any():
            continue
        values = column.flatten()
        if inner:
            values = values.flatten()
        flat = values.to_numpy(zero_copy_only=False)
        shape = (len(steps), width, inner) if inner else (len(steps), width)
        try:
            block = flat.reshape(shape)
        except ValueError:
            raise RecordingError("a per-robot column does not have one value per robot") from None
        pieces.append((steps[keep], block[keep]))
    steps = np.concatenate([s for s, _ in pieces])
    block = np.concatenate([b for _, b in pieces])
    order = np.argsort(steps, kind="stable")
    steps, block = steps[order], block[order]
    unique, first_index = np.unique(steps, return_index=True)
    if len(unique) != last - first + 1:
        raise RecordingError(f"steps missing between {first} and {last}")
    return block[first_index]


def _assemble(path: Path, read: tuple[Columns, dict[str, Any]], truncated: bool) -> Recording:
    columns, static = read
    meta = _meta(static, path)
    n = int(meta["robots"])
    per_flush = layout.inputs_per_flush(int(meta.get("version", 0)))
    if per_flush:  # one row per flush: made one row per step, as formats 2-3 have them
        columns[(layout.INPUTS, "inputs")] = _input_steps(columns, path)
    missing = [key for key in _PER_STEP if not columns.get(key)]
    if missing:
        raise RecordingError(f"{path} holds no complete step (cut off before its first flush)"
                             if len(missing) == len(_PER_STEP)
                             else f"{path} is a corrupt recording: no {missing[0][0]} data")
    first = max(int(min(s.min() for s, _ in columns[key])) for key in _PER_STEP)
    last = min(int(max(s.max() for s, _ in columns[key])) for key in _PER_STEP)
    if last < first:
        raise RecordingError(f"{path} holds no complete step")
    try:
        positions = _dense(columns[(layout.ROBOTS, "Points3D:positions")], first, last, n, 3)
        colors = _dense(columns[(layout.ROBOTS, "Points3D:colors")], first, last, n)
        leds = np.stack([(colors >> shift) & 0xFF for shift in (24, 16, 8)], -1).astype(np.uint8)
        headings = _dense(columns[(layout.ROBOTS, "heading")], first, last, n)
        failed = _dense(columns[(layout.ROBOTS, "failed")], first, last, n).astype(bool)
        labels = {name: _dense(columns[(layout.ROBOTS, f"label:{name}")], first, last, n)
                  for name in meta.get("watch", []) if columns.get((layout.ROBOTS,
                                                                    f"label:{name}"))}
        heap = {figure: _dense(columns[(f"{layout.HEAP}/{figure}", "Scalars:scalars")],
                               first, last, n).astype(np.int64)
                for figure in layout.HEAP_FIGURES}
        messages = {name: _dense(columns[(layout.MESSAGES, name)], first, last, n)
                    .astype(np.int64) for name in ("sent", "received", "bytes_sent")}
        totals = _dense(columns[(layout.MESSAGE_TOTALS, "Scalars:scalars")], first, last, 4)
        link_steps, link_rows = _rows(columns[(layout.LINKS, "pairs")])
        input_steps, input_rows = _rows(columns[(layout.INPUTS, "inputs")])
    except (KeyError, TypeError, ValueError) as error:
        raise RecordingError(f"{path} is a corrupt recording: {error}") from None
    links = _per_step(link_steps, link_rows, first, last,
                      lambda v: np.array(v.as_py() or [], dtype=np.int32).reshape(-1, 2))
    inputs = _per_step(input_steps, input_rows, first, last,
                       (lambda v: v) if per_flush else lambda v: (v.as_py() or [b""])[0])
    recording = Recording(
        path, meta, np.arange(first, last + 1, dtype=np.int64), positions, headings, leds,
        failed, labels, heap, messages, totals, links, inputs, truncated=truncated)
    _rare_rows(recording, columns, last)
    return recording


def _input_steps(columns: Columns, path: Path) -> list[tuple[np.ndarray, list[bytes]]]:
    """Format 4's input rows (one per flush: a zstd frame of the steps' input blobs back to
    back, the steps, where each one's bytes end) as per-step rows: (steps, their blobs) per
    flush. Decompressed here, once (~0.4 ms a Kilobot flush, ~0.7 for SAR), so a seek only
    slices."""
    from bbzide.recording.compression import CompressionError, decompress

    _, blobs = _rows(columns.get((layout.INPUTS, "inputs"), []))
    _, step_rows = _rows(columns.get((layout.INPUTS, "input_steps"), []))
    _, end_rows = _rows(columns.get((layout.INPUTS, "input_ends"), []))
    if not len(blobs) == len(step_rows) == len(end_rows):
        raise RecordingError(f"{path} is a corrupt recording: input rows do not match")
    flushes = []
    for blob, step_row, end_row in zip(blobs, step_rows, end_rows, strict=True):
        try:
            data = decompress((blob.as_py() or [b""])[0])
            steps, ends = list(step_row.as_py() or []), list(end_row.as_py() or [])
            in_order = np.array(steps, dtype=np.int64)
            ends_at = np.array([0, *ends], dtype=np.int64)
        except CompressionError as error:
            raise RecordingError(f"{path} is a corrupt recording: inputs: {error}") from None
        except (TypeError, ValueError, OverflowError, IndexError):  # rows of another type
            raise RecordingError(f"{path} is a corrupt recording: unreadable inputs") from None
        # a flush holds each of its steps once, in order; each step's bytes follow the last's
        if len(steps) != len(ends) or ends_at[-1] != len(data) or \
                np.any(np.diff(in_order) <= 0) or np.any(np.diff(ends_at) < 0):
            raise RecordingError(f"{path} is a corrupt recording: inputs do not match their "
                                 "steps")
        ends = ends_at.tolist()
        flushes.append((in_order, [data[a:b] for a, b in zip(ends, ends[1:], strict=False)]))
    return flushes


def _per_step(steps: np.ndarray, rows: list[Any], first: int, last: int, convert: Any
              ) -> list[Any]:
    out: list[Any] = [None] * (last - first + 1)
    for step, value in zip(steps.tolist(), rows, strict=True):
        if first <= step <= last:
            out[step - first] = convert(value)
    if any(v is None for v in out):
        raise RecordingError(f"steps missing between {first} and {last}")
    return out


def _row_group(recording: Recording, columns: Columns, entity: str, names: tuple[str, ...]
               ) -> tuple[np.ndarray, list[list[Any]]]:
    """The rows of one entity's columns, by step: (their steps, one list of values per name).

    The recorder sends some entities as more than one chunk a flush (an event's text, then its
    kind and robot), and a writer killed between two of them leaves the flush's rows in the
    first only. Those are the newest rows of the file, so a truncated recording keeps the rows
    every column holds, as if the writer had died a moment earlier; in a whole recording the
    columns must hold as many rows each."""
    read = [_rows(columns.get((entity, name), [])) for name in names]
    held = min(len(rows) for _, rows in read)
    if not recording.truncated and any(len(rows) != held for _, rows in read):
        raise ValueError(f"{entity}'s columns do not hold the same rows")
    return read[0][0][:held], [rows[:held] for _, rows in read]


def _rare_rows(recording: Recording, columns: Columns, last: int) -> None:
    try:
        for parts in (columns.get((layout.PROGRAMS, "program"), []),):
            steps, rows = _rows(parts)
            for value in rows:
                record = json.loads(value.as_py()[0])
                recording.programs[int(record["id"])] = record
        steps, (robots, snapshots, programs, bases) = _row_group(
            recording, columns, layout.KEYFRAMES, ("robots", "snapshots", "programs", "bases"))
        for step, who, snaps, progs, base in zip(steps.tolist(), robots, snapshots, programs,
                                                 bases, strict=True):
            if step > last:
                continue
            for index, snapshot, program, based_on in zip(
                    who.as_py(), snaps.as_py(), progs.as_py(), base.as_py(), strict=True):
                recording.keyframes.setdefault(int(index), []).append(
                    Keyframe(int(step), snapshot, int(program), int(based_on)))
        steps, (texts, kinds, robots) = _row_group(
            recording, columns, layout.EVENTS, ("TextLog:text", "kind", "robot"))
        for step, text, kind, robot in zip(steps.tolist(), texts, kinds, robots, strict=True):
            if step <= last:
                recording.events.append(Event(int(step), kind.as_py()[0], int(robot.as_py()[0]),
                                              text.as_py()[0]))
        steps, rows = _rows(columns.get((layout.OVERLAYS, "overlays"), []))
        for step, value in zip(steps.tolist(), rows, strict=True):
            if step <= last:
                recording.overlays.append((int(step), json.loads(value.as_py()[0])))
    except (ValueError, KeyError, TypeError, IndexError) as error:
        raise RecordingError(f"{recording.path} is a corrupt recording: {error}") from None
    if not recording.keyframes:
        raise RecordingError(f"{recording.path} has no VM keyframes")
