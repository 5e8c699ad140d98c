"""Reads a BittyBuzz heap buffer the way the VM lays it out (notes §E.2-§E.4), for display.

Given the raw bytes and the platform's geometry, `decode_heap` lists every object slot and every
segment with its type, validity and payload, and the free gap between ROP and LSP. The VM room
owns the heap itself; this module only *reads* bytes, so the inspector shows exactly what a
firmware memory dump would show, including freed slots and stale bytes.

Layout reminder: object i lives at byte i*S (S = object size); slots 0..R-1 are reserved for
lambda activation records; segment j lives at byte SIZE-(j+1)*G (G = 4E+2: E keys, E values,
one metadata word, each u16 little-endian). Element words: bit 15 valid, bits 0-14 object index.
Segment metadata: bit 15 valid, bit 14 GC mark, bits 0-13 next segment (0x3FFF = none).
"""

from __future__ import annotations

import struct
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

from bbzide.compiler.bbzfloat import to_float
from bbzide.ui.inspection import TYPE_NAMES, HeapBlock, HeapObjectRow

TYPE_TABLE = 4
TYPE_CLOSURE = 5
VALID_BIT = 0x08
PERMANENT_BIT = 0x10
DARRAY_OR_NATIVE_BIT = 0x40
LAMBDA_BIT = 0x80
ELEMENT_VALID = 0x8000
NO_NEXT_SEGMENT = 0x3FFF
#: Deepest table nesting the object list expands (the GC marks only 7 levels anyway, §E.9).
MAX_EXPAND_DEPTH = 2
#: Entries shown per table in the object list (a long darray is summarised after this many).
MAX_ENTRIES_SHOWN = 40
#: Referrers listed per object: an interned string used as a key in every neighbour's table
#: has dozens; the first few say what it is, the count says the rest.
MAX_REFERRERS_SHOWN = 6
#: How deep object names follow tables from the globals (`pos.x`, `robots[2].pos`): deeper
#: paths are longer than the inspector's column and the GC's own marking stops at 7 levels.
MAX_PATH_DEPTH = 4


@dataclass(frozen=True)
class HeapGeometry:
    size: int  # heap bytes
    object_size: int  # S
    reserved: int  # R, reserved activation-record slots
    elems_per_segment: int  # E

    @property
    def segment_size(self) -> int:
        return 4 * self.elems_per_segment + 2


def _no_function_name(pc: int) -> str | None:
    return None


@dataclass(frozen=True)
class HeapRoots:
    """What the VM holds outside the heap's tables, to say who refers to each object: the
    globals table (`gsyms`), the function list of lambdas (`flist`), the running function's
    activation record (`lsyms`, between steps none), the stack, and the program's name for the
    function at a pc (a closure's code)."""

    globals_table: int = -1
    function_list: int = -1
    locals_table: int = -1
    stack: Sequence[int] = ()
    function_name: Callable[[int], str | None] = field(default=_no_function_name)


@dataclass
class DecodedHeap:
    blocks: list[HeapBlock]
    objects: list[HeapObjectRow]
    used_bytes: int
    free_bytes: int
    valid_objects: int
    valid_segments: int


class HeapReader:
    def __init__(
        self, heap: bytes, geometry: HeapGeometry, rop: int, lsp: int, strings: Sequence[str] = ()
    ) -> None:
        self.heap = bytes(heap)
        self.g = geometry
        self.rop = rop
        self.lsp = lsp
        self.strings = strings
        #: The heap is a frozen copy, so each table's chain is walked once (the decode asks
        #: for it for the heap map label, the object row and every parent's row: an M300 heap
        #: has ~500 objects, and this halved the inspector's decode).
        self._entries: dict[int, list[tuple[int | None, int]]] = {}
        self._segment_owner: dict[int, int] = {}  # segment -> the table whose chain holds it

    # ---- raw access -----------------------------------------------------------------------
    def object_count(self) -> int:
        return self.rop // self.g.object_size

    def segment_count(self) -> int:
        return (self.g.size - self.lsp) // self.g.segment_size

    def meta(self, index: int) -> int:
        return self.heap[index * self.g.object_size]

    def payload_u16(self, index: int) -> int:
        offset = index * self.g.object_size + 1
        return struct.unpack_from("<H", self.heap, offset)[0]

    def segment_offset(self, segment: int) -> int:
        return self.g.size - (segment + 1) * self.g.segment_size

    def segment_words(self, segment: int) -> list[int]:
        count = 2 * self.g.elems_per_segment + 1
        return list(struct.unpack_from(f"<{count}H", self.heap, self.segment_offset(segment)))

    # ---- meaning ----------------------------------------------------------------------------
    def type_name(self, index: int) -> str:
        meta = self.meta(index)
        kind = meta & 0x07
        if kind == TYPE_TABLE and meta & DARRAY_OR_NATIVE_BIT:
            return "darray"
        if kind == TYPE_CLOSURE:
            return "lambda" if meta & LAMBDA_BIT else "closure"
        return TYPE_NAMES[kind]

    def is_valid(self, index: int) -> bool:
        return bool(self.meta(index) & VALID_BIT)

    def value_text(self, index: int, depth: int = 0) -> str:
        if not 0 <= index < self.object_count():
            return f"<bad ref {index}>"
        meta = self.meta(index)
        kind = meta & 0x07
        if not meta & VALID_BIT:
            return f"<freed #{index}>"
        if kind == 0:
            return "nil"
        if kind == 1:
            return str(struct.unpack_from("<h", self.heap, index * self.g.object_size + 1)[0])
        if kind == 2:
            return f"{to_float(self.payload_u16(index)):.4g}"
        if kind == 3:
            string_id = self.payload_u16(index)
            if 0 <= string_id < len(self.strings):
                return repr(self.strings[string_id])
            return f"string#{string_id}"
        if kind == TYPE_TABLE:
            entries = self.table_entries(index)
            label = "darray" if meta & DARRAY_OR_NATIVE_BIT else "table"
            return f"{label}({len(entries)})"
        if kind == TYPE_CLOSURE:
            return "lambda" if meta & LAMBDA_BIT else "closure"
        return "userdata"

    def table_entries(self, index: int) -> list[tuple[int | None, int]]:
        """(key object, value object) pairs in chain order; darrays give (None, value)."""
        cached = self._entries.get(index)
        if cached is None:
            cached = self._entries[index] = self._walk_table(index)
        return cached

    def _walk_table(self, index: int) -> list[tuple[int | None, int]]:
        darray = bool(self.meta(index) & DARRAY_OR_NATIVE_BIT)
        segment = self.payload_u16(index)
        elems = self.g.elems_per_segment
        entries: list[tuple[int | None, int]] = []
        seen: set[int] = set()
        while 0 <= segment < self.segment_count() and segment not in seen:
            seen.add(segment)
            self._segment_owner.setdefault(segment, index)
            words = self.segment_words(segment)
            if darray:
                for word in words[: 2 * elems]:
                    if not word & ELEMENT_VALID:
                        return entries
                    entries.append((None, word & 0x7FFF))
            else:
                for key, value in zip(words[:elems], words[elems : 2 * elems], strict=True):
                    if key & ELEMENT_VALID:
                        entries.append((key & 0x7FFF, value & 0x7FFF))
            following = words[-1] & NO_NEXT_SEGMENT
            if following == NO_NEXT_SEGMENT:
                break
            segment = following
        return entries

    def named_refs(self, index: int) -> dict[str, int]:
        """A table's entries as key text -> value object index (e.g. global name -> object)."""
        if not (0 <= index < self.object_count()) or not self.is_valid(index):
            return {}
        return {
            self.value_text(key).strip("'") if key is not None else str(position): value
            for position, (key, value) in enumerate(self.table_entries(index))
        }

    def named_entries(self, index: int) -> list[tuple[str, str]]:
        """A table's entries as (key text, value text), e.g. the globals table."""
        if not (0 <= index < self.object_count()) or not self.is_valid(index):
            return []
        rows = []
        for key, value in self.table_entries(index):
            key_text = str(len(rows)) if key is None else self.value_text(key).strip("'")
            rows.append((key_text, self.value_text(value)))
        return rows

    def key_text(self, key: int | None, position: int) -> str:
        """A table key as code would write it: a string key bare (`x`), others in brackets."""
        if key is None:
            return f"[{position}]"
        if self.is_valid(key) and self.meta(key) & 0x07 == 3:
            return self.value_text(key).strip("'")
        return f"[{self.value_text(key)}]"

    def closure_pc(self, index: int, roots: HeapRoots) -> int | None:
        """Where a closure's code starts: a native closure holds its pc, a lambda the position
        of its native closure in the function list; a C closure (host function) has no pc."""
        meta = self.meta(index)
        if meta & 0x07 != TYPE_CLOSURE:
            return None
        offset = index * self.g.object_size + 1
        pointer_bytes = self.heap[offset : offset + self.g.object_size - 1]
        if meta & LAMBDA_BIT:
            functions = self.table_entries(roots.function_list) if self._is_table(
                roots.function_list) else []
            position = pointer_bytes[0]
            if position >= len(functions):
                return None
            native = functions[position][1]
            if not 0 <= native < self.object_count():
                return None
            offset = native * self.g.object_size + 1
            return int.from_bytes(self.heap[offset : offset + self.g.object_size - 1], "little")
        if meta & DARRAY_OR_NATIVE_BIT:
            return int.from_bytes(pointer_bytes, "little")
        return None

    def _is_table(self, index: int) -> bool:
        return (0 <= index < self.object_count() and self.is_valid(index)
                and self.meta(index) & 0x07 == TYPE_TABLE)

    def references(self, roots: HeapRoots) -> tuple[dict[int, list[str]], dict[int, str]]:
        """Who refers to each object (globals, locals, the stack, table entries and keys), and
        each object's shortest name from the globals (`pos`, `pos.x`, `list[2]`)."""
        referrers: dict[int, list[str]] = {}
        names: dict[int, str] = {}

        def add(target: int, text: str) -> None:
            referrers.setdefault(target, []).append(text)

        frontier: list[int] = []
        if self._is_table(roots.globals_table):
            for position, (key, value) in enumerate(self.table_entries(roots.globals_table)):
                name = self.key_text(key, position)
                add(value, f"global `{name}`")
                if value not in names:
                    names[value] = name
                    frontier.append(value)
        for _ in range(1, MAX_PATH_DEPTH):
            following = []
            for table in frontier:
                if not self._is_table(table):
                    continue
                for position, (key, value) in enumerate(self.table_entries(table)):
                    if value in names or not 0 <= value < self.object_count():
                        continue
                    key_name = self.key_text(key, position)
                    joiner = "" if key_name.startswith("[") else "."
                    names[value] = f"{names[table]}{joiner}{key_name}"
                    following.append(value)
            frontier = following
        if self._is_table(roots.locals_table):
            for position, (_, value) in enumerate(self.table_entries(roots.locals_table)):
                add(value, "`self` of the running function" if position == 0
                    else f"local {position} of the running function")
        for position, value in enumerate(roots.stack):
            add(int(value), f"stack[{position}]")
        for table in range(self.object_count()):
            if table in (roots.globals_table, roots.locals_table) or not self._is_table(table):
                continue
            owner = names.get(table)
            darray = bool(self.meta(table) & DARRAY_OR_NATIVE_BIT)
            kind = "darray" if darray else "table"
            for position, (key, value) in enumerate(self.table_entries(table)):
                key_name = self.key_text(key, position)
                if owner is not None:
                    joiner = "" if key_name.startswith("[") else "."
                    add(value, f"`{owner}{joiner}{key_name}` ({kind} #{table})")
                elif table == roots.function_list:
                    add(value, f"the function list (lambda {position})")
                else:
                    add(value, f"{kind} #{table}, key `{key_name}`")
                if key is not None:
                    add(key, f"a key of {kind} #{table}" + (f" (`{owner}`)" if owner else ""))
        return referrers, names

    def closure_name(self, index: int, roots: HeapRoots, names: dict[int, str]) -> str:
        """A closure named after its function: the program's name for its code, else the
        global or table entry that holds it (a host function: `led`)."""
        pc = self.closure_pc(index, roots)
        named = roots.function_name(pc) if pc is not None else None
        return named or names.get(index, "")

    def decode(self, roots: HeapRoots | None = None) -> DecodedHeap:
        g = self.g
        roots = roots or HeapRoots()
        referrers, names = self.references(roots)
        blocks: list[HeapBlock] = []
        objects: list[HeapObjectRow] = []
        valid_objects = 0
        for index in range(self.object_count()):
            start = index * g.object_size
            valid = self.is_valid(index)
            type_name = self.type_name(index) if valid else ""
            reserved = index < g.reserved
            row = self._object_row(index, roots, referrers, names) if valid else None
            label = _block_label(index, start, g.object_size, row, reserved)
            blocks.append(
                HeapBlock(
                    start,
                    g.object_size,
                    "actrec" if reserved else "object",
                    type_name,
                    index,
                    valid,
                    label,
                )
            )
            if row is not None:
                valid_objects += 1
                objects.append(row)
        blocks.append(
            HeapBlock(
                self.rop,
                max(0, self.lsp - self.rop),
                "free",
                label=f"free gap {self.lsp - self.rop} B ({self.rop}..{self.lsp})",
            )
        )
        valid_segments = 0
        for segment in range(self.segment_count()):
            offset = self.segment_offset(segment)
            valid = bool(self.segment_words(segment)[-1] & 0x8000)
            valid_segments += valid
            owner = self._segment_owner.get(segment)
            held = "" if owner is None or not valid else (
                f": entries of {'darray' if self.meta(owner) & DARRAY_OR_NATIVE_BIT else 'table'}"
                f" #{owner}" + (f" `{names[owner]}`" if owner in names else ""))
            blocks.append(
                HeapBlock(
                    offset,
                    g.segment_size,
                    "segment",
                    "segment",
                    segment,
                    valid,
                    f"table segment {segment} @{offset}, {g.segment_size} B"
                    + (held if valid else " (freed)"),
                )
            )
        free = max(0, self.lsp - self.rop)
        return DecodedHeap(
            sorted(blocks, key=lambda b: b.start),
            objects,
            g.size - free,
            free,
            valid_objects,
            valid_segments,
        )

    def _object_row(self, index: int, roots: HeapRoots, referrers: dict[int, list[str]],
                    names: dict[int, str]) -> HeapObjectRow:
        meta = self.meta(index)
        children: list[tuple[str, str]] = []
        if meta & 0x07 == TYPE_TABLE:
            for position, (key, value) in enumerate(self.table_entries(index)):
                if position == MAX_ENTRIES_SHOWN:
                    children.append(("…", "more entries"))
                    break
                key_text = str(position) if key is None else self.value_text(key)
                children.append((key_text, f"{self.value_text(value)} (#{value})"))
        value = self.value_text(index)
        name = names.get(index, "")
        if meta & 0x07 == TYPE_CLOSURE:
            name = self.closure_name(index, roots, names)
            if name:
                value = f"{value} `{name}`"
        if index == roots.globals_table:
            name = "the globals table"
        elif index == roots.function_list:
            name = "the function list (lambdas' code)"
        found = referrers.get(index, [])
        shown = found[:MAX_REFERRERS_SHOWN]
        if len(found) > MAX_REFERRERS_SHOWN:
            shown.append(f"and {len(found) - MAX_REFERRERS_SHOWN} more")
        return HeapObjectRow(
            index,
            self.type_name(index),
            value,
            children,
            permanent=bool(meta & PERMANENT_BIT),
            offset=index * self.g.object_size,
            size=self.g.object_size,
            referrers=shown,
            name=name,
        )


def _block_label(index: int, start: int, size: int, row: HeapObjectRow | None,
                 reserved: bool) -> str:
    """The heap map's text for an object slot: the tooltip, and what a click shows."""
    if row is None:
        return f"#{index} @{start}, {size} B: free slot (a freed object; the next allocation " \
               "reuses it)"
    kind = "reserved activation record, " if reserved else ""
    lines = [f"#{index} @{start}, {size} B: {kind}{row.type_name} {row.value}"]
    if row.name:
        lines.append(f"name: {row.name}")
    lines.append("referred to by: " + ("; ".join(row.referrers) if row.referrers else
                                       "nothing in the globals, tables or stack (garbage the "
                                       "next collection frees, or held by the VM itself)"))
    return "\n".join(lines)
