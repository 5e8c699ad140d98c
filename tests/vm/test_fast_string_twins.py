"""Strings deduplicated through the twin registers, in the fast mode against the reference.

A ``pushs`` reuses the lowest valid string with its id when no free slot comes before it
(``first_free``). The compiled kernel keeps each id's lowest string in registers
(``fastloop.R_TWIN_END``, ``R_TWINS``) while every slot below their end stays valid. These
scripts free strings below the ones the registers know (a global's only string dropped, a
table of strings dropped), so that the next ``pushs`` of that id must take the hole; they
use more names than the registers hold, so that ids share a register; and they run on
heaps small enough that the holes are reused at once. Every observable byte must be the
reference's, at the end of a whole run and after each chunk of a run in chunks.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from bbzide.compiler import compile_source
from bbzide.vm.compiled import fastloop
from bbzide.vm.heap import INT, STRING
from bbzide.vm.profiles import KILOBOT, PC, Profile
from bbzide.vm.vm import VM
from tests.vm.chunked_runs import assert_modes_agree

#: field names enough to fill the registers twice over (ids sharing their low bits)
_MANY_NAMES = [f"n{k:02d}" for k in range(2 * fastloop.TWIN_SLOTS + 3)]

SCRIPTS = {
    "strings freed below their twins": """
a = "alpha"
b = "beta"
keep = {}
i = 0
while (i < 60) {
  keep[i % 5] = "gamma"
  if (i % 4 == 0) { a = nil }
  if (i % 4 == 2) { a = "alpha" }
  if (i % 6 == 0) { keep = {} }
  b = "beta"
  x = {.f1 = i, .f2 = a, .f3 = b}
  i = i + 1
}
""",
    "more names than registers": "t = {}\ni = 0\nwhile (i < 12) {\n"
    + "".join(f"  t.{name} = i\n" for name in _MANY_NAMES)
    + "  if (i % 3 == 0) { t = {} }\n  i = i + 1\n}\n",
}

PROFILES = [PC, KILOBOT,
            dataclasses.replace(KILOBOT, name="small heap", heap_size=600),
            dataclasses.replace(PC, name="small pc heap", heap_size=1100)]


def _bbo(name: str) -> bytes:
    return compile_source(SCRIPTS[name], "twins.bzz").to_bbo().bbo


@pytest.mark.parametrize("name", sorted(SCRIPTS))
@pytest.mark.parametrize("profile", PROFILES, ids=lambda p: p.name)
def test_string_twins_identical(name: str, profile: Profile) -> None:
    assert_modes_agree(_bbo(name), profile, 400, name)


def _string(vm: VM, regs: np.ndarray, sid: int) -> int:
    """``pushs``'s allocation of string ``sid`` by the kernel, its id written."""
    h = vm.heap
    x = fastloop._obj_alloc(h.view, regs, h.obj_size, h.reserved, STRING, sid)
    h.view[x * h.obj_size + 1] = sid & 0xFF
    h.view[x * h.obj_size + 2] = sid >> 8
    return x


def _fresh_vm_and_a_number() -> tuple[VM, np.ndarray, int]:
    """A fast VM just constructed, a kernel register array for it, and an int the kernel
    allocated first (the slot below the strings the tests make next)."""
    vm = VM(PC, stress_gc=False)
    vm.construct()
    h = vm.heap
    regs = vm.kernel_registers(None, None)
    return vm, regs, fastloop._obj_alloc(h.view, regs, h.obj_size, h.reserved, INT, 0)


def test_a_string_takes_a_hole_freed_below_its_known_twin() -> None:
    """The registers name a string's twin once a scan found it; a slot freed below it
    makes the next string of that id a new one in that slot, as the scan would."""
    vm, regs, number = _fresh_vm_and_a_number()
    h = vm.heap
    first = _string(vm, regs, 999)
    assert first == number + 1
    register = regs[fastloop.R_TWINS + (999 & (fastloop.TWIN_SLOTS - 1))]
    assert (register >> 16, register & 0xFFFF) == (1000, first)
    assert regs[fastloop.R_TWIN_END] == first + 1
    assert _string(vm, regs, 999) == first  # the twin
    h.view[number * h.obj_size] &= 0xFF ^ 0x08  # the number freed
    fastloop._slot_freed(regs, number)
    assert _string(vm, regs, 999) == number  # a new string in the hole
    assert _string(vm, regs, 999) == number  # its twin from now on


def test_a_string_python_made_below_a_known_twin_is_found() -> None:
    """Python may make a string of a known id below the slot the registers name (each
    kernel entry then starts with their end at 0); a later scan that raises the end again
    must not bring the old register back: the next string of that id is Python's."""
    vm, regs, number = _fresh_vm_and_a_number()
    h = vm.heap
    known = _string(vm, regs, 999)
    o = number * h.obj_size  # Python's string in the number's slot
    h.view[o:o + 3] = (STRING | 0x08, 999 & 0xFF, 999 >> 8)
    regs[fastloop.R_TWIN_END] = 0
    assert _string(vm, regs, 555) > known  # a scan from the reserved slots past both
    assert _string(vm, regs, 999) == number
