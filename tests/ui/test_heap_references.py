"""Who refers to each heap object, read from real Kilobot VMs: the inspector names an object
by the global or table entry that holds it, a closure by its function, and lists user globals
before the built-ins; the heap map's block of an object carries the same text a click shows."""

from __future__ import annotations

import re
from pathlib import Path

from bbzide.ui.heap_map import render_heap_svg
from bbzide.ui.world_adapter import WorldsBackend

BACKEND = WorldsBackend()

SCRIPT = """
pos = {.x = 417, .y = 5}
function blink(on) {
  led(on)
}
function init() {
  pos.x = 417
}
function step() {
  neighbors.foreach(function(rid, data) { blink(1) })
}
"""


def inspect(tmp_path: Path) -> object:
    path = tmp_path / "refs.bzz"
    path.write_text(SCRIPT)
    _, program = BACKEND.compile(SCRIPT, path, "kilobot")
    sim = BACKEND.create("kilobot", program, 2, 0)
    sim.step()
    return sim.inspect(0)


def test_objects_are_named_by_who_refers_to_them(tmp_path: Path) -> None:
    view = inspect(tmp_path)
    rows = {row.index: row for row in view.objects}
    table = next(row for row in rows.values() if row.name == "pos")
    assert table.type_name == "table" and "global `pos`" in table.referrers
    x = next(row for row in rows.values() if row.value == "417")
    assert x.name == "pos.x"
    assert any(f"`pos.x` (table #{table.index})" == text for text in x.referrers)
    blink = next(row for row in rows.values() if row.type_name == "closure"
                 and row.name == "blink")
    assert "global `blink`" in blink.referrers and blink.value == "closure `blink`"
    led = next(row for row in rows.values() if row.type_name == "closure" and row.name == "led")
    assert "global `led`" in led.referrers  # a host function: named by the global holding it
    for row in rows.values():
        assert row.offset == row.index * 3 and row.size == 3  # the Kilobot's 3-byte slots


def test_user_globals_come_before_the_built_ins(tmp_path: Path) -> None:
    names = [name for name, _ in inspect(tmp_path).globals]
    user = {"pos", "blink", "init", "step"}
    first_builtin = next(i for i, name in enumerate(names) if name not in user)
    assert set(names[:first_builtin]) == user and "id" in names[first_builtin:]


def test_a_heap_block_carries_its_object_for_the_click(tmp_path: Path) -> None:
    view = inspect(tmp_path)
    row = next(row for row in view.objects if row.name == "pos")
    svg = render_heap_svg(view)
    block = re.search(rf'<rect [^>]*data-start="{row.offset}"[^>]*onclick="[^"]+"[^>]*>'
                      r"<title>([^<]*)</title>", svg)
    assert block is not None
    assert block.group(1).startswith(f"#{row.index} @{row.offset}, 3 B: table table(2)")
    assert "name: pos" in block.group(1) and "global `pos`" in block.group(1)

