"""Virtual stigmergy: the ``stigmergy`` global and the vstig store (spec §F.6, §E.11 step 7).

Construct part only (owned by vm-core until the handover): ``register`` builds the
``stigmergy`` table with its ``create`` closure, in the reference allocation order. The
library closures are placeholders raising NOTIMPL until vm-runtime implements them.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from bbzide.vm.vm import VM

STR_STIGMERGY = 32  # base string ids of the BittyBuzz .bst (spec §E.11)
STR_CREATE = 2


@dataclass
class VstigEntry:
    key: int        # string id
    value: int      # heap index
    timestamp: int  # Lamport clock (u8)
    robot: int


@dataclass
class VstigStore:
    """``vm->vstig``: the table object and the fixed-capacity entry store."""

    hpos: int = 0
    entries: list[VstigEntry] = field(default_factory=list)


def _notimpl(vm: VM) -> None:
    vm.not_implemented()


def register(vm: VM) -> None:
    """``bbzvstig_register``: pushs stigmergy; table; add create; permanent; gstore; GC."""
    vm.vstig = VstigStore()
    vm.push_string(STR_STIGMERGY)
    t = vm.push_table()
    vm.vstig.hpos = t
    vm.add_function(t, STR_CREATE, "bbzvstig_create", _notimpl)
    vm.make_permanent(t)
    vm.gstore()
    vm.gc()
