"""Draws a robot's heap to scale as an SVG: every byte has the same width.

The heap is wrapped into rows of `bytes_per_row` bytes (a Kilobot's 1,088-byte heap fits in 17
rows of 64). Reserved activation records are hatched grey, objects are coloured by type, table
and darray segments by their own colour, freed slots inside the used areas are pale, and the gap
between ROP and LSP is white. ROP and LSP are marked with their byte offsets.

A large heap (an M300's 60,000 bytes) would need rows so wide that its 9-byte objects become
stripes. When the used areas fit `MAX_DETAIL_ROWS` rows of 64 bytes, the map shows them at that
scale and folds the free gap between them into one row that says how many bytes it holds: rows
are `spans` of the heap, each row labelled with its real offset.
"""

from __future__ import annotations

import html

from bbzide.ui.inspection import HeapBlock, RobotInspection

TYPE_COLORS = {
    "nil": "#adb5bd",
    "int": "#4dabf7",
    "float": "#3bc9db",
    "string": "#ffa94d",
    "table": "#9775fa",
    "darray": "#da77f2",
    "closure": "#69db7c",
    "userdata": "#f783ac",
    "segment": "#fcc419",
    "actrec": "#ced4da",
    "free": "#ffffff",
    "invalid": "#ffe3e3",
}
#: Freed slots (and freed segments) inside the used areas are outlined in red and dashed, so
#: they never read as the free gap (white, no outline).
INVALID_STROKE = "#fa5252"
#: What a click on a block does (viser runs inline handlers of its HTML, not scripts): copy the
#: block's text into the inspector's "picked" box and outline every piece of the block. The box
#: is a separate element that the server rewrites only for another robot, so the pick stays
#: while the map redraws.
PICK_HANDLER = (
    "var box=document.querySelector('.bbz-heap-pick');if(!box)return;"
    "box.textContent=this.querySelector('title').textContent;"
    "box.dataset.start=this.dataset.start;box.dataset.kind=this.dataset.kind;"
    "document.querySelectorAll('.heap-map rect.picked').forEach("
    "function(r){r.classList.remove('picked')});"
    "var start=this.dataset.start;this.ownerSVGElement.querySelectorAll('rect').forEach("
    "function(r){if(r.dataset.start===start)r.classList.add('picked')})"
)
#: Room a "ROP 59340" label needs right of its mark (9 characters of 13 px bold monospace).
POINTER_LABEL_PX = 75
#: Pixels per byte and row height: a 64-byte row is 448 px, which fits the 520 px panel.
BYTE_PX = 7
ROW_PX = 14
ROW_GAP_PX = 5
#: Never more rows than this: larger heaps get wider rows (fewer pixels per byte), unless
#: their used areas fit `MAX_DETAIL_ROWS` rows at `DETAIL_BYTES_PER_ROW` (module docstring).
MAX_ROWS = 28
#: The folded map's limit: 48 rows of 19 px are ~900 px, one scroll of the inspector panel
#: (an M300 drone of the flocking example uses ~2,700 bytes: 43 rows).
MAX_DETAIL_ROWS = 48
#: Bytes per row at the map's full scale (7 px a byte: a 9-byte M300 object is 63 px wide).
DETAIL_BYTES_PER_ROW = 64


def layout_bytes_per_row(heap_size: int) -> int:
    per_row = 64
    while heap_size / per_row > MAX_ROWS:
        per_row *= 2
    return per_row


class _Rows:
    """Where each heap byte is drawn: spans of the heap, each laid out in rows of `per_row`
    bytes one after the other, with one folded row between two spans."""

    def __init__(self, spans: list[tuple[int, int]], per_row: int) -> None:
        self.spans = spans
        self.per_row = per_row
        self.first_rows: list[int] = []  # row of each span's first byte
        row = 0
        for start, end in spans:
            self.first_rows.append(row)
            row += (end - start + per_row - 1) // per_row + 1  # + the folded row after it
        self.count = row - 1

    def place(self, offset: int) -> tuple[int, int] | None:
        """(row, column) of a byte offset, or None inside a folded gap."""
        for (start, end), first in zip(self.spans, self.first_rows, strict=True):
            if start <= offset < end:
                row, column = divmod(offset - start, self.per_row)
                return first + row, column
        return None

    def pieces(self, start: int, size: int) -> list[tuple[int, int, int]]:
        """(row, column, length) pieces of the bytes start..start+size that are shown."""
        out = []
        for span_start, span_end in self.spans:
            low, high = max(start, span_start), min(start + size, span_end)
            while low < high:
                row, column = self.place(low)  # type: ignore[misc]
                length = min(high - low, self.per_row - column)
                out.append((row, column, length))
                low += length
        return out


def _rows_for(inspection: RobotInspection) -> _Rows:
    """The whole heap, or its two used areas at 64 bytes a row with the gap folded."""
    size, per_row = inspection.heap_size, layout_bytes_per_row(inspection.heap_size)
    if per_row == DETAIL_BYTES_PER_ROW:
        return _Rows([(0, size)], per_row)
    left_end = -(-min(inspection.rop, size) // DETAIL_BYTES_PER_ROW) * DETAIL_BYTES_PER_ROW
    right_start = max(left_end, inspection.lsp // DETAIL_BYTES_PER_ROW * DETAIL_BYTES_PER_ROW)
    shown_rows = (left_end + size - right_start) / DETAIL_BYTES_PER_ROW
    if shown_rows > MAX_DETAIL_ROWS or right_start - left_end < 2 * DETAIL_BYTES_PER_ROW:
        return _Rows([(0, size)], per_row)  # the used areas are large: the overview
    return _Rows([(0, left_end), (right_start, size)], DETAIL_BYTES_PER_ROW)


def render_heap_svg(inspection: RobotInspection) -> str:
    layout = _rows_for(inspection)
    per_row = layout.per_row
    byte_px = BYTE_PX * 64 / per_row
    rows = layout.count
    width = per_row * byte_px + 60
    height = rows * (ROW_PX + ROW_GAP_PX) + 24
    parts = [
        '<svg xmlns="http://www.w3.org/2000/svg" width="100%" '
        f'viewBox="-2 -12 {width:.0f} {height + 12}" '
        f'class="heap-map" data-rop="{inspection.rop}" data-lsp="{inspection.lsp}" '
        'font-family="monospace" font-size="10">'
    ]
    for (start, end), first in zip(layout.spans, layout.first_rows, strict=True):
        for offset in range(start, end, per_row):
            y = (first + (offset - start) // per_row) * (ROW_PX + ROW_GAP_PX)
            parts.append(f'<text x="0" y="{y + ROW_PX - 3}" fill="#868e96">{offset}</text>')
    for index in range(len(layout.spans) - 1):
        (span_start, end), (start, _) = layout.spans[index], layout.spans[index + 1]
        row = layout.first_rows[index] + -(-(end - span_start) // per_row)
        y = row * (ROW_PX + ROW_GAP_PX)
        parts.append(
            f'<text x="34" y="{y + ROW_PX - 3}" fill="#868e96" font-style="italic" '
            f'class="heap-folded">⋯ {start - end:,} bytes not drawn ({end}..{start}: free) '
            f"⋯</text>")
    for block in inspection.blocks:
        parts.extend(_block_rects(block, layout, byte_px))
    for name, offset, color in (
        ("ROP", inspection.rop, "#e8590c"),
        ("LSP", inspection.lsp, "#1971c2"),
    ):
        # at the left edge of byte `offset`, or the right edge of the byte before it when
        # `offset` is not drawn (the heap's end, or the first byte of a folded gap)
        place = layout.place(offset)
        if place is None:
            before = layout.place(offset - 1)
            if before is None:
                continue
            place = (before[0], before[1] + 1)
        row, column = place
        x = 34 + column * byte_px
        y = row * (ROW_PX + ROW_GAP_PX)
        parts.append(
            f'<line x1="{x:.1f}" x2="{x:.1f}" y1="{y - 2}" y2="{y + ROW_PX + 2}" '
            f'stroke="{color}" stroke-width="2"/>'
        )
        text_y = y - 3 if name == "ROP" else y + ROW_PX + ROW_GAP_PX + 1
        # right of the mark, or left of it near the row's end (the label would be cut off)
        anchor = (f'x="{x - 2:.1f}" text-anchor="end"' if x > width - POINTER_LABEL_PX
                  else f'x="{x + 2:.1f}"')
        parts.append(
            f'<text {anchor} y="{text_y}" fill="{color}" font-weight="bold" font-size="13">'
            f"{name} {offset}</text>"
        )
    parts.append("</svg>")
    return "".join(parts)


def _block_rects(block: HeapBlock, layout: _Rows, byte_px: float) -> list[str]:
    """A block may cross row ends: one rectangle per row piece, all with the same tooltip."""
    color = _color_of(block)
    title = html.escape(
        block.label or f"{block.kind} {block.type_name} @{block.start} ({block.size} B)"
    )
    if block.kind == "free":
        stroke = "none"
    elif block.kind == "actrec":
        stroke = "#495057" if block.valid else "#dee2e6"
    elif not block.valid:
        stroke = f'{INVALID_STROKE}" stroke-dasharray="2 1.5'
    else:
        stroke = "#495057" if block.kind in ("object", "segment") else "#dee2e6"
    click = "" if block.kind == "free" else f' onclick="{html.escape(PICK_HANDLER)}"'
    rects = []
    for row, column, length in layout.pieces(block.start, block.size):
        x = 34 + column * byte_px
        y = row * (ROW_PX + ROW_GAP_PX)
        rects.append(
            f'<rect x="{x:.1f}" y="{y}" width="{length * byte_px:.1f}" height="{ROW_PX}" '
            f'fill="{color}" stroke="{stroke}" stroke-width="0.5" class="heap-{block.kind}" '
            f'data-start="{block.start}" data-kind="{block.kind}" data-index="{block.index}"'
            f'{click}><title>{title}</title></rect>'
        )
    return rects


def _color_of(block: HeapBlock) -> str:
    if block.kind == "free":
        return TYPE_COLORS["free"]
    if block.kind == "actrec":  # reserved whether in use or not: never taken for a freed slot
        return TYPE_COLORS["actrec"]
    if not block.valid:
        return TYPE_COLORS["invalid"]
    if block.kind == "segment":
        return TYPE_COLORS["segment"]
    return TYPE_COLORS.get(block.type_name, "#868e96")


def legend_html() -> str:
    items = [
        "int",
        "float",
        "string",
        "table",
        "darray",
        "closure",
        "userdata",
        "nil",
        "segment",
        "actrec",
        "invalid",
        "free",
    ]
    words = {
        "actrec": "reserved activation record",
        "segment": "table segment",
        "invalid": "freed slot",
        "free": "free gap",
    }
    swatches = "".join(
        f'<span style="display:inline-block;margin-right:6px"><span style="display:inline-block;'
        f'width:10px;height:10px;border:1px {_legend_border(name)};'
        f'background:{TYPE_COLORS[name]}"></span> {words.get(name, name)}</span>'
        for name in items
    )
    return (
        "<style>.heap-map rect{cursor:pointer}.heap-map rect.heap-free{cursor:default}"
        ".heap-map rect.picked{stroke:#e03131;stroke-width:2}</style>"
        f'<div style="font-size:11px;line-height:1.6">{swatches}</div>'
        f'<div class="heap-terms" style="font-size:11px;line-height:1.45;color:#495057;'
        f'margin-top:3px">{TERMS_HTML}</div>'
    )


#: The map's terms, where the map shows them (BittyBuzz's C names in brackets).
TERMS_HTML = (
    "<b>ROP</b> (<code>rtobj</code>): one past the last object slot in use; objects grow right "
    "from the <b>reserved activation records</b> (the first slots, kept for the activation "
    "records of lambdas: the locals a closure keeps). <b>LSP</b> (<code>ltseg</code>): the "
    "first byte of the lowest "
    "<b>table segment</b> in use; segments (a table's keys and values, a few per segment, "
    "chained) grow left from the heap's end. The heap is full when they meet."
)


def _legend_border(name: str) -> str:
    return f"dashed {INVALID_STROKE}" if name == "invalid" else "solid #868e96"
