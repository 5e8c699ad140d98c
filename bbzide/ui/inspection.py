"""A plain snapshot of one robot's memory and runtime state, as the inspector panel shows it.

`RobotInspection` is built under the run controller's lock (between two steps) and rendered
afterwards, so drawing never races the simulation. The building half (`inspect_robot`) is the
only place that reads the VM room's objects; the panel and the heap map read only this module's
dataclasses.

BittyBuzz terms: ROP (right-of-objects pointer, `rtobj`) is the byte offset one past the highest
object slot in use; LSP (left segment pointer, `ltseg`) the byte offset of the lowest segment in
use. Objects grow right from the reserved activation records, segments grow left from the end.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

#: Object types by the 3 low metadata bits (notes §E.2), in the colours of the heap map.
TYPE_NAMES = ("nil", "int", "float", "string", "table", "closure", "userdata", "type7")


@dataclass(frozen=True)
class HeapBlock:
    """A run of heap bytes drawn as one box: an object slot, a segment, or the free gap."""

    start: int  # byte offset in the heap
    size: int  # bytes
    kind: str  # "actrec" | "object" | "segment" | "free"
    type_name: str = ""  # object type ("table", "int", ...), "darray", or "" for free/invalid
    index: int = -1  # object index or segment number
    valid: bool = True  # an invalid (freed) slot inside the used areas
    label: str = ""  # tooltip text


@dataclass
class HeapObjectRow:
    index: int
    type_name: str
    value: str
    children: list[tuple[str, str]] = field(default_factory=list)  # table entries (key, value)
    permanent: bool = False
    offset: int = -1  # byte offset of the object's slot in the heap
    size: int = 0  # bytes of the slot (the profile's object size)
    #: who refers to it: "global `x`", "`t.key` (table #12, key 'key')", "stack[3]", …
    referrers: list[str] = field(default_factory=list)
    name: str = ""  # a closure's function name, or the first path that reaches the object


@dataclass
class RobotInspection:
    robot_index: int
    robot_id: int
    step: int
    state: str  # "running", "error", "done", ...
    pc: int | None
    heap_size: int
    rop: int  # BittyBuzz rtobj, byte offset
    lsp: int  # BittyBuzz ltseg, byte offset
    reserved_bytes: int  # activation-record slots 0..R-1
    blocks: list[HeapBlock]
    used_bytes: int
    free_bytes: int
    peak_bytes: int | None
    gc_runs: int | None
    ram_bytes: int | None  # the platform's RAM (Kilobot: 2048)
    objects: list[HeapObjectRow] = field(default_factory=list)
    frames: list[str] = field(default_factory=list)
    globals: list[tuple[str, str]] = field(default_factory=list)
    stigmergy: list[tuple[str, str]] = field(default_factory=list)
    neighbors: list[tuple[str, str]] = field(default_factory=list)
    swarms: list[str] = field(default_factory=list)
    in_queue: list[str] = field(default_factory=list)
    out_queue: list[str] = field(default_factory=list)
    last_error: str | None = None
    last_error_line: str | None = None
    warnings: list[str] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)  # what could not be read (API gaps)
    pc_line: int | None = None  # the source line of `pc` (the debug map's)


def value_text(value: Any) -> str:
    """A short, readable rendering of a decoded Buzz value."""
    if value is None:
        return "nil"
    if isinstance(value, float):
        return f"{value:.4g}"
    if isinstance(value, str):
        return repr(value)
    return str(value)


@dataclass(frozen=True)
class FrameView:
    """One call frame of a paused robot: the function, the line it is at, its locals."""

    function: str
    line: int | None
    locals: dict[str, str] = field(default_factory=dict)


@dataclass(frozen=True)
class PausedAt:
    """Where the debugger stopped the swarm: which robot, at which instruction and line, why
    ("breakpoint", "step", "error", "pause"), and that robot's call frames (innermost first)."""

    robot_index: int
    robot_id: int
    step: int
    pc: int | None
    line: int | None
    column: int | None
    reason: str
    frames: tuple[FrameView, ...] = ()
    message: str | None = None  # an error's text
    #: the debugger stopped inside a control step: robots before this one have run it, the
    #: rest have not (the debugger room's "paused mid-step")
    mid_step: bool = False
