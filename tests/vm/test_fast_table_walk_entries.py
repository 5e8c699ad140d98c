"""The table library's ``foreach`` element calls that begin without a collection, in the fast
mode against the reference.

In ``bbztable_foreach`` the only collection between two elements is the first step of the
next element's call. The compiled walk (``fasthost.table_walk``, ``fastloop.CALL_IN_WALK``)
replaces it by a return to the previous element's first collection plus the new frame when
nothing that element made outlives it. These scripts mix elements that leave nothing with
elements that store a number in a global or a table, call a function, make a closure or a
table, push strings, and end early; they run on roomy heaps and on heaps small enough that
each frame takes the slot and segment the previous one freed. Every observable byte must be
the reference's at the end of a whole run and after each chunk of a run in chunks, which
stops inside the elements.
"""

from __future__ import annotations

import dataclasses

import pytest

from bbzide.compiler import bittybuzz_string_table, compile_source
from bbzide.vm.profiles import CRAZYFLIE, KILOBOT, PC, Profile
from tests.vm.chunked_runs import assert_modes_agree

SCRIPTS = {
    "elements leaving nothing": """
t = {}
i = 0
while (i < 16) { t[i] = i * 3
                 i = i + 1 }
function walk() {
  foreach(t, function(k, v) {
    var d = k * v + 4
    var e = d % 5 + k
    if (e > 100) { d = d / 2 }
  })
}
lap = 0
while (lap < 3) {
  walk()
  lap = lap + 1
}
""",
    "elements storing now and then": """
t = {.a = 1, .b = 2, .c = 3, .d = 4, .e = 5, .f = 6, .g = 7}
near = 0
kept = {}
function half(x) { return x / 2 }
function walk() {
  foreach(t, function(k, v) {
    var d = v * 7 - lap
    if (v % 3 == 0) { near = near + d }
    if (v == 4) { kept[lap] = d }
    if (v == 5) { d = half(d) }
    if (v == 6 and lap == 2) { var f = function(x) { return x + d } }
    if (v == 2) { var s = "tag" }
    if (v == 7 and lap == 1) { var n = {.x = d} }
  })
}
lap = 0
while (lap < 4) {
  walk()
  lap = lap + 1
}
""",
}

PROFILES = [PC, KILOBOT, CRAZYFLIE,
            dataclasses.replace(KILOBOT, name="small heap", heap_size=700),
            dataclasses.replace(PC, name="small pc heap", heap_size=1300)]


def _bbo(name: str) -> bytes:
    # (the BittyBuzz string table: the table library's names at their firmware ids)
    return compile_source(SCRIPTS[name], "walk.bzz",
                          string_table=bittybuzz_string_table([])).to_bbo().bbo


@pytest.mark.parametrize("name", sorted(SCRIPTS))
@pytest.mark.parametrize("profile", PROFILES, ids=lambda p: p.name)
def test_walk_entries_identical(name: str, profile: Profile) -> None:
    assert_modes_agree(_bbo(name), profile, 600, name)
