"""The seam between the model and its compiled kernels: the one module of the model that
imports ``bbzide/vm/compiled/``.

A VM runs in one of two modes. The **reference** mode (``stress_gc=True``, like clox's
DEBUG_STRESS_GC) is the model alone: plain Python over the heap bytes, a collection before
every instruction, nothing compiled — the readable account of what BittyBuzz does. The
**fast** mode runs the same routines as numba kernels (the instruction loop, the collector,
the in-queue, receiving, host calls, table reads, first-fit scans, a whole swarm's control
step) and hands back to the model's routines wherever a kernel does not cover a case.

Every model module that needs a kernel imports it from here, and takes it only when its
VM is in the fast mode (``vm.stress_gc`` false, ``heap.reference`` false) and numba compiled
it (:data:`COMPILED`); otherwise it runs its own Python. The kernels import the model's
layouts and constants only (``heap_layout``, ``message_layout``, ``packed_messages``,
``states``), never a module that imports this one, so the imports run one way.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from bbzide.vm.compiled import (
    fastbatch,
    fastgc,
    fasthost,
    fastinbox,
    fastloop,
    fastreceive,
    fasttables,
    fastvstig,
    packed_queues,
    swarm_batch_fast,
)
from bbzide.vm.states import State

if TYPE_CHECKING:
    from bbzide.vm.vm import VM

#: numba is installed and compiled the kernels (without it they run as plain Python, and
#: the callers that only gain speed from them take the model's routines instead)
COMPILED: bool = fastgc.COMPILED


def kernels_now(vm: VM) -> bool:
    """May a model routine of this VM hand its work to a kernel now (compiled, fast mode,
    READY)?"""
    return COMPILED and not vm.stress_gc and vm.state == State.READY


__all__ = ["COMPILED", "kernels_now", "fastbatch", "fastgc", "fasthost", "fastinbox",
           "fastloop", "fastreceive", "fasttables", "fastvstig", "packed_queues",
           "swarm_batch_fast"]
