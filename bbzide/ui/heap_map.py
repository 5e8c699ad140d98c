"""Draws a robot's heap to scale as an SVG: every byte has the same width.

The heap is wrapped into rows of `bytes_per_row` bytes (a Kilobot's 1,088-byte heap fits in 17
rows of 64). Reserved activation records are hatched grey, objects are coloured by type, table
and darray segments by their own colour, freed slots inside the used areas are pale, and the gap
between ROP and LSP is white. ROP and LSP are marked with their byte offsets.
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
    "segment": "#845ef7",
    "actrec": "#ced4da",
    "free": "#ffffff",
    "invalid": "#f1f3f5",
}
#: Pixels per byte and row height: a 64-byte row is 448 px, which fits the 520 px panel.
BYTE_PX = 7
ROW_PX = 14
ROW_GAP_PX = 5
#: Never more rows than this: larger heaps get wider rows (fewer pixels per byte).
MAX_ROWS = 28


def layout_bytes_per_row(heap_size: int) -> int:
    per_row = 64
    while heap_size / per_row > MAX_ROWS:
        per_row *= 2
    return per_row


def render_heap_svg(inspection: RobotInspection) -> str:
    size = inspection.heap_size
    per_row = layout_bytes_per_row(size)
    byte_px = BYTE_PX * 64 / per_row
    rows = (size + per_row - 1) // per_row
    width = per_row * byte_px + 60
    height = rows * (ROW_PX + ROW_GAP_PX) + 24
    parts = [
        '<svg xmlns="http://www.w3.org/2000/svg" width="100%" '
        f'viewBox="-2 -12 {width:.0f} {height + 12}" '
        f'class="heap-map" data-rop="{inspection.rop}" data-lsp="{inspection.lsp}" '
        'font-family="monospace" font-size="10">'
    ]
    for row in range(rows):
        y = row * (ROW_PX + ROW_GAP_PX)
        parts.append(f'<text x="0" y="{y + ROW_PX - 3}" fill="#868e96">{row * per_row}</text>')
    for block in inspection.blocks:
        parts.extend(_block_rects(block, per_row, byte_px))
    for name, offset, color in (
        ("ROP", inspection.rop, "#e8590c"),
        ("LSP", inspection.lsp, "#1971c2"),
    ):
        row, column = divmod(min(offset, size), per_row)
        if offset == size and column == 0 and row > 0:
            row, column = row - 1, per_row
        x = 34 + column * byte_px
        y = row * (ROW_PX + ROW_GAP_PX)
        parts.append(
            f'<line x1="{x:.1f}" x2="{x:.1f}" y1="{y - 2}" y2="{y + ROW_PX + 2}" '
            f'stroke="{color}" stroke-width="2"/>'
        )
        text_y = y - 3 if name == "ROP" else y + ROW_PX + ROW_GAP_PX + 1
        parts.append(
            f'<text x="{x + 2:.1f}" y="{text_y}" fill="{color}" font-weight="bold" font-size="13">'
            f"{name} {offset}</text>"
        )
    parts.append("</svg>")
    return "".join(parts)


def _block_rects(block: HeapBlock, per_row: int, byte_px: float) -> list[str]:
    """A block may cross row ends: one rectangle per row piece, all with the same tooltip."""
    color = _color_of(block)
    title = html.escape(
        block.label or f"{block.kind} {block.type_name} @{block.start} ({block.size} B)"
    )
    stroke = "#495057" if block.kind in ("object", "segment") and block.valid else "#dee2e6"
    rects = []
    start, remaining = block.start, block.size
    while remaining > 0:
        row, column = divmod(start, per_row)
        length = min(remaining, per_row - column)
        x = 34 + column * byte_px
        y = row * (ROW_PX + ROW_GAP_PX)
        rects.append(
            f'<rect x="{x:.1f}" y="{y}" width="{length * byte_px:.1f}" height="{ROW_PX}" '
            f'fill="{color}" stroke="{stroke}" stroke-width="0.5" class="heap-{block.kind}">'
            f"<title>{title}</title></rect>"
        )
        start += length
        remaining -= length
    return rects


def _color_of(block: HeapBlock) -> str:
    if block.kind == "free":
        return TYPE_COLORS["free"]
    if not block.valid:
        return TYPE_COLORS["invalid"]
    if block.kind == "actrec":
        return TYPE_COLORS["actrec"]
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
    swatches = "".join(
        f'<span style="display:inline-block;margin-right:6px"><span style="display:inline-block;'
        f'width:10px;height:10px;border:1px solid #868e96;background:{TYPE_COLORS[name]}"></span> '
        f"{'reserved actrec' if name == 'actrec' else name}</span>"
        for name in items
    )
    return f'<div style="font-size:11px;line-height:1.6">{swatches}</div>'
