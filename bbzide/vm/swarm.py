"""Swarms: the ``swarm`` global, the swarm stack and this robot's membership (spec §F.8).

Construct part only (owned by vm-core until the handover); library closures are NOTIMPL
placeholders until vm-runtime implements them.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from bbzide.vm.vm import VM

STR_SWARM = 1
STR_CREATE = 2
STR_ID = 0


@dataclass
class SwarmState:
    hpos: int = 0          # the swarm table
    swarmstack: int = 0    # darray of swarm ids being executed
    my_swarmlist: int = 0  # bit k = member of swarm k


def _notimpl(vm: VM) -> None:
    vm.not_implemented()


def register(vm: VM) -> None:
    """``bbzswarm_register`` (swarmlist broadcasts disabled, the default)."""
    from bbzide.vm.tables import darray_new

    vm.swarm = SwarmState()
    vm.push_string(STR_SWARM)
    t = vm.push_table()
    vm.make_permanent(t)
    vm.swarm.hpos = t
    d = vm.alloc_or_mem(darray_new)
    vm.make_permanent(d)
    vm.swarm.swarmstack = d
    vm.add_function(t, STR_CREATE, "bbzswarm_create", _notimpl)
    vm.add_function(t, STR_ID, "bbzswarm_id", _notimpl)
    vm.gstore()
