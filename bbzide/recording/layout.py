"""The shape of a bbzide mission recording: Rerun entity paths, component names, constants.

Design: a recording is a plain Rerun `.rrd` (rerun-sdk 0.41) on one timeline, `step` (a
sequence: the engine's `step_count` after that many control steps; step 0 is the state after
boot), plus `time` (a duration, simulated seconds) for the Rerun viewer. Everything a person
looks at uses Rerun archetypes so the Rerun viewer draws it; everything only bbzide needs
(headings, failure flags, per-robot counters, the VM inputs, keyframes, metadata) is stored as
`AnyValues` components next to them. Writer (`recorder.py`) and reader (`reader.py`) both use
the names below, and README.md ("Recording entity paths") lists them for users.

Per-robot values are batches of N (robot index order, the engine's `robots` order) per step.
"""

from __future__ import annotations

from bbzide.recording.input_log import LAYOUT_COMPACT, LAYOUT_FULL

#: `/mission` static component `meta` (JSON) starts with this; anything else is foreign.
FORMAT = "bbzide-mission"
#: Bumped when the layout changes; the reader refuses versions before `OLDEST_READABLE` or
#: after this one. 2: input log in columns, keyframe deltas as changed blocks, zstd (version 1:
#: packed messages, XOR deltas, zlib). 3: a latched host function's happy-path
#: calls (a Kilobot's `led`: see `input_log.SwarmCapture.tap`) are not in the input log, the
#: meta says which functions are latched (`latched`); version 2 files read as before. 4:
#: keyframes hold flat snapshots (vm/snapshot_layout.py), which an older bbzide
#: would try to unpickle; the input log's compact layout (`input_log.LAYOUT_COMPACT`: no
#: lengths column when a step's payloads are all as long, no bearing columns when they are all
#: zero, as for Kilobots), and one zstd frame for a flush's input blobs instead of one per step
#: (a zstd call's fixed cost made it ~13 us a Kilobot step, against ~5 for the flush's frame).
#: Versions 2 and 3 (pickled keyframes, the full input layout, a zstd frame per step) still
#: read and rebuild.
FORMAT_VERSION = 4
OLDEST_READABLE = 2
APPLICATION_ID = "bbzide"


def input_layout(version: int) -> int:
    """The `input_log` layout of the input blobs of a recording of format `version`."""
    return LAYOUT_COMPACT if version >= 4 else LAYOUT_FULL


def inputs_compressed(version: int) -> bool:
    """Whether each step's input blob, as `reader.Recording.inputs` holds it, is a zstd frame
    (formats 2-3); format 4 compresses a flush's steps as one frame, which the reader opens."""
    return version < 4


def inputs_per_flush(version: int) -> bool:
    """Whether a recording of format `version` holds one input row per flush (`inputs`: a
    zstd frame of the steps' blobs back to back, `input_steps`, `input_ends`: where each
    step's bytes end) instead of one per step."""
    return version >= 4


TIMELINE = "step"
TIME_SECONDS = "time"

MISSION = "/mission"                       # static: meta (JSON)
PROGRAMS = "/mission/programs"             # at first use: program (JSON: id, bbo, strings, ...)
WALLS = "/world/walls"                     # static LineStrips3D: walls and obstacles
ROBOTS = "/world/robots"                   # Points3D (positions, colors = LED, radii, labels)
#                                            + AnyValues heading, failed, label:<name>
HEADINGS = "/world/robots/headings"        # Arrows3D from each robot along its heading
LINKS = "/world/links"                     # Arrows3D sender -> receiver + AnyValues pairs
OVERLAYS = "/world/overlays"               # AnyValues overlays (JSON) when they change
TARGETS = "/world/targets"                 # Points3D of overlay targets (when a world has some)
MESSAGES = "/robots/messages"              # AnyValues sent, received, bytes_sent per robot
MESSAGE_TOTALS = "/stats/messages"         # Scalars sent, received, dropped, bytes (4 series)
HEAP = "/robots/heap"                      # /robots/heap/<figure>: Scalars, one per robot
HEAP_FIGURES = ("used", "free", "peak", "rop", "lsp", "gc_runs")
EVENTS = "/events"                         # TextLog + AnyValues kind, robot
INPUTS = "/vm/inputs"                      # AnyValues inputs, input_steps, input_ends: one
#                                            zstd frame of input_log blobs per flush (until
#                                            format 3: inputs, one zstd frame per step)
KEYFRAMES = "/vm/keyframes"                # AnyValues robots, snapshots, programs, bases
#                                            (keyframes.py: full or block delta, zstd)

#: Event kinds (the replay's jump buttons): a robot's VM stopped; a watched label changed;
#: a world overlay reports one more target found; recording started or a program was loaded.
EVENT_ERROR = "error"
EVENT_ROLE = "role"
EVENT_TARGET = "target"
EVENT_PROGRAM = "program"
