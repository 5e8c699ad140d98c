"""Neighbors: the ``neighbors`` global, listeners and neighbor data (spec §F.7).

Construct part only (owned by vm-core until the handover); library closures are NOTIMPL
placeholders until vm-runtime implements them. XTREME builds (Kilobot) keep neighbor data
in a ring buffer of plain records; other builds keep them in heap tables.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from bbzide.vm.vm import VM

STR_NEIGHBORS = 17
STR_BROADCAST, STR_LISTEN, STR_IGNORE = 29, 30, 31
STR_FOREACH, STR_FILTER, STR_MAP, STR_GET, STR_REDUCE, STR_COUNT = 18, 28, 19, 34, 20, 24
STR_DATA = 44   # non-XTREME sub-table of neighbor data
STR_RESET = 45  # int 0 stored under this key


@dataclass
class NeighborEntry:
    robot: int
    distance: int
    azimuth: int
    elevation: int
    mark: int = 0


@dataclass
class NeighborsState:
    hpos: int = 0
    listeners: int = 0
    clear_counter: int = 10
    count: int = 0
    ring: list[NeighborEntry] = field(default_factory=list)


def _notimpl(vm: VM) -> None:
    vm.not_implemented()


def register(vm: VM) -> None:
    """``bbzneighbors_register`` in the reference allocation order (spec §E.11 step 9)."""
    p = vm.profile
    vm.neighbors = NeighborsState(clear_counter=p.neighbors_clr_period)
    vm.push_string(STR_NEIGHBORS)
    lst = vm.push_table()
    vm.make_permanent(lst)
    vm.neighbors.listeners = lst
    vm.pop()
    t = vm.push_table()
    vm.make_permanent(t)
    vm.neighbors.hpos = t
    if p.xtreme:
        vm.table_put_raw(t, vm.new_int(0), vm.new_string_obj(STR_RESET))
    vm.add_function(t, STR_BROADCAST, "bbzneighbors_broadcast", _notimpl)
    vm.add_function(t, STR_LISTEN, "bbzneighbors_listen", _notimpl)
    vm.add_function(t, STR_IGNORE, "bbzneighbors_ignore", _notimpl)
    if not p.xtreme:
        vm.table_put_raw(t, vm.new_table_obj(), vm.new_string_obj(STR_DATA))
        vm.table_put_raw(t, vm.new_int(0), vm.new_string_obj(STR_RESET))
    vm.add_function(t, STR_FOREACH, "bbzneighbors_foreach", _notimpl)
    vm.add_function(t, STR_FILTER, "bbzneighbors_filter", _notimpl)
    vm.add_function(t, STR_MAP, "bbzneighbors_map", _notimpl)
    vm.add_function(t, STR_GET, "bbzneighbors_get", _notimpl)
    vm.add_function(t, STR_REDUCE, "bbzneighbors_reduce", _notimpl)
    vm.add_function(t, STR_COUNT, "bbzneighbors_count", _notimpl)
    vm.gstore()
