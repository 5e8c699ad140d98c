"""heap_decode reads a heap laid out by hand from the BittyBuzz spec (notes §E.2-§E.4)."""

from __future__ import annotations

import re
import struct

from bbzide.ui.heap_decode import HeapGeometry, HeapReader
from bbzide.ui.heap_map import render_heap_svg
from bbzide.ui.inspection import RobotInspection

KILOBOT = HeapGeometry(size=1088, object_size=3, reserved=28, elems_per_segment=5)


def kilobot_heap() -> tuple[bytearray, int, int]:
    """nil #28, int 42 #29, string 'b' #30, table {b: 42} #31 (segment 0), darray [42, 42] #32
    (segment 1), and a freed int #33 below ROP; one lambda actrec in reserved slot 0."""
    heap = bytearray(KILOBOT.size)
    S, G = 3, 22

    def obj(index: int, meta: int, payload: int = 0) -> None:
        heap[index * S] = meta
        struct.pack_into("<H", heap, index * S + 1, payload & 0xFFFF)

    def segment(number: int, words: list[int], mdata: int) -> None:
        struct.pack_into("<11H", heap, KILOBOT.size - (number + 1) * G, *(words + [mdata]))

    obj(0, 0x4C, 1)  # reserved actrec: darray (table + bit 6), valid
    obj(28, 0x38)  # nil: valid, permanent, marked
    obj(29, 0x09, 42)  # int 42
    obj(30, 0x0B, 1)  # string id 1
    obj(31, 0x0C, 0)  # table -> segment 0
    obj(32, 0x4C, 1)  # darray -> segment 1
    obj(33, 0x01, 7)  # int, not valid (freed)
    segment(0, [0x8000 | 30, 0, 0, 0, 0, 0x8000 | 29, 0, 0, 0, 0], 0xFFFF)
    segment(1, [0x8000 | 29, 0x8000 | 29] + [0] * 8, 0xFFFF)
    segment(2, [0] * 10, 0x0000)  # freed segment below LSP's neighbours
    rop = 34 * S  # one past object 33
    lsp = KILOBOT.size - 3 * G  # lowest segment slot in use: 2
    return heap, rop, lsp


def test_decode_objects_segments_and_gap() -> None:
    heap, rop, lsp = kilobot_heap()
    reader = HeapReader(heap, KILOBOT, rop, lsp, strings=["a", "b"])
    decoded = reader.decode()
    assert rop == 102 and lsp == 1022
    assert decoded.free_bytes == 1022 - 102
    assert decoded.used_bytes == 1088 - 920
    assert decoded.valid_objects == 6 and decoded.valid_segments == 2
    rows = {row.index: row for row in decoded.objects}
    assert rows[29].value == "42" and rows[30].value == "'b'"
    assert rows[31].type_name == "table" and rows[31].children == [("'b'", "42 (#29)")]
    assert rows[32].type_name == "darray" and rows[32].value == "darray(2)"
    assert rows[28].permanent and not rows[29].permanent
    assert 33 not in rows
    assert reader.named_entries(31) == [("b", "42")]
    assert reader.named_refs(31) == {"b": 29}
    kinds = [(b.start, b.kind, b.valid) for b in decoded.blocks]
    assert kinds[0] == (0, "actrec", True) and kinds[1] == (3, "actrec", False)
    assert (99, "object", False) in kinds  # freed slot below ROP
    assert (102, "free", True) in kinds
    assert (1022, "segment", False) in kinds and (1066, "segment", True) in kinds
    covered = sum(b.size for b in decoded.blocks)
    assert covered == KILOBOT.size  # every byte drawn exactly once


def test_heap_svg_marks_rop_and_lsp_to_scale() -> None:
    heap, rop, lsp = kilobot_heap()
    decoded = HeapReader(heap, KILOBOT, rop, lsp).decode()
    view = RobotInspection(
        0,
        0,
        0,
        "running",
        0,
        KILOBOT.size,
        rop,
        lsp,
        84,
        decoded.blocks,
        decoded.used_bytes,
        decoded.free_bytes,
        None,
        None,
        2048,
    )
    svg = render_heap_svg(view)
    assert "ROP 102" in svg and "LSP 1022" in svg
    # 64 bytes per row at 7 px per byte: the free gap's first piece (102..128) is 26 bytes wide.
    assert 'width="182.0" height="14" fill="#ffffff"' in svg


def test_a_large_heap_shows_its_used_areas_at_full_scale() -> None:
    """An M300's 60,000-byte heap: the objects and the segments drawn 64 bytes a row (7 px a
    byte, not stripes), the free gap between them folded into one row that says its size."""
    from bbzide.ui.inspection import HeapBlock

    size, rop, lsp = 60000, 1971, 59296
    blocks = [HeapBlock(0, 90, "actrec"), HeapBlock(90, 9, "object", "int"),
              HeapBlock(99, rop - 99, "object", "string"), HeapBlock(rop, lsp - rop, "free"),
              HeapBlock(lsp, size - lsp, "segment", "segment")]
    view = RobotInspection(0, 0, 0, "running", 0, size, rop, lsp, 90, blocks, 2675, 57325, None,
                           None, None)
    svg = render_heap_svg(view)
    assert 'width="63.0" height="14" fill="#4dabf7"' in svg   # the 9-byte int at 7 px a byte
    assert f"{lsp // 64 * 64 - 1984:,} bytes not drawn (1984..{lsp // 64 * 64}: free)" in svg
    assert "ROP 1971" in svg and "LSP 59296" in svg
    row_labels = re.findall(r'fill="#868e96">(\d+)</text>', svg)
    assert row_labels[0] == "0" and row_labels[-1] == str(59968) and len(row_labels) == 31 + 12
