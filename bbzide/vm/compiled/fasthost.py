"""Compiled host functions of the fast VM mode: a C closure's call without leaving machine code.

When the instruction kernel (:func:`fastloop.run`) meets a ``callc`` of a C closure it sets
the call up and returns ``HOST_CALL``; ``VM._loop`` then looks the host function up, runs
it in Python, and re-enters the kernel. For a Kilobot's ``step`` of the gradient example
(``neighbors.broadcast``, ``led``) those two round trips were a third of the VM's time.
:func:`run_hosted` is ``run`` plus the host functions whose whole effect the kernel can
do itself, on their happy path, under the kernel's rule (check everything first, hand the
call back to Python with nothing done otherwise):

* ``neighbors.broadcast(topic, value)`` — ``bbzneighbors_broadcast``: the out-queue append
  (``messages.outmsg_append_broadcast``, the full-queue overwrite and the sort by type
  included) on the packed out-queue (:mod:`packed_queues`), then ``ret0``;
* a **latched** host function (``host.LatchedHostFunction``: a world function whose only
  effect is to store its int arguments as the robot's state, e.g. a Kilobot's ``led``):
  its arguments are type-checked (ints only) and stored in the robot's latch slot, ``ret0``;
  the world gets them after the swarm step (``swarm_batch``). Anything else — another
  argument count (LNUM), a non-int (TYPE), a return the kernel's ``_ret`` refuses, the
  budget about to run out, a ``run`` without a saved block pointer — goes to Python.

After a host function ``VM._loop`` counts a step (``n``), applies no skip rule (``callc``
has none: the next step collects) and checks the budget; :func:`run_hosted` does the same
(it refuses a call after which the budget would be exceeded, so the error stays Python's).

The table of compiled host functions (``hosts``, one row per closure address: see the
``H_*`` columns) is built by ``Robot.compiled_hosts`` from the VM's host registry; it is
empty for a VM whose queues are not packed, so :func:`run_hosted` is then exactly ``run``.
:func:`call_pushed` is the set-up shared by every compiled entry into a closure call
(``fastinbox``): the argument count is on the stack, ``closure_call``'s registers, run.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from bbzide.vm.compiled.fastgc import COMPILED, _compile, _i
from bbzide.vm.compiled.fastloop import (
    HOST_CALL,
    NONE,
    R_BP,
    R_BUDGET,
    R_CALL_FIRST,
    R_FIXED,
    R_HOST,
    R_LSYMS,
    R_N,
    R_PENDING,
    R_SAVED,
    R_SP,
    _ret,
    _ret_ok,
    _s16,
    run,
)
from bbzide.vm.compiled.fastring import ring_size, sort_ring_by_type
from bbzide.vm.compiled.fasttables import darray_get, darray_size
from bbzide.vm.compiled.packed_queues import (
    CTL_SLOTS,
    LATCH_ARGS,
    OUT_END,
    OUT_SLOTS,
    OUT_START,
    ROBOT,
)
from bbzide.vm.heap_layout import INT
from bbzide.vm.message_layout import BC_TOPIC, BC_VALUE, BROADCAST, RID, TYPE

__all__ = ["COMPILED", "run_hosted", "call_pushed", "no_hosts", "HOST_BROADCAST",
           "HOST_LATCH", "HOST_COLUMNS", "NO_HOST_ARGS"]

# Columns of a ``hosts`` row, and its kinds.
H_ADDRESS, H_PTR_SIZE, H_KIND, H_SLOT, H_ARGC = range(5)
HOST_COLUMNS = 5
HOST_BROADCAST, HOST_LATCH = 1, 2



def no_hosts() -> np.ndarray:
    """An empty ``hosts`` table (the Python entries: their queues are not packed)."""
    return np.zeros((0, HOST_COLUMNS), np.int64)


#: (hosts, outq, ctl, latch) for an entry with no compiled host function (never written)
NO_HOST_ARGS = (no_hosts(), np.zeros(1, np.uint8), np.zeros(CTL_SLOTS, np.int64),
                np.zeros((1, 1 + LATCH_ARGS), np.int64))


@_compile
def out_append_broadcast(d: Any, outq: Any, ctl: Any, size: int, topic: int, value: int,
                         s: int) -> None:
    """``messages.outmsg_append_broadcast`` of heap objects ``topic`` (its u16) and
    ``value`` (its ``s`` bytes) on the packed out-queue (``_out_template``'s overflow bug
    included: a full queue gets the unused record copied over its last one)."""
    slots = ctl[OUT_SLOTS]
    start = ctl[OUT_START]
    end = ctl[OUT_END]
    m = (end & 0xFF) % slots
    if ring_size(start, end, slots) + 1 == slots:
        last = ((end - 1 + slots) & 0xFF) % slots
        for j in range(size):
            outq[last * size + j] = outq[m * size + j]
    else:
        ctl[OUT_END] = ((end + 1) & 0xFF) % slots
    o = m * size
    rid = ctl[ROBOT] & 0xFFFF
    outq[o + TYPE] = BROADCAST
    outq[o + RID] = rid & 0xFF
    outq[o + RID + 1] = rid >> 8
    outq[o + BC_TOPIC] = d[topic * s + 1]
    outq[o + BC_TOPIC + 1] = d[topic * s + 2]
    for j in range(s):
        outq[o + BC_VALUE + j] = d[value * s + j]
    sort_ring_by_type(outq, ctl[OUT_START], ctl[OUT_END], slots, size, outq[:0])


@_compile
def _address_matches(d: Any, c: int, s: int, address: int, ptr_size: int) -> bool:
    """Does C closure ``c`` hold ``address`` (``Heap.ptr_value`` masked to the pointer)?"""
    for j in range(min(ptr_size, s - 1)):
        if _i(d[c * s + 1 + j]) != (address >> (8 * j)) & 0xFF:
            return False
    return True


@_compile
def _host_compiled(d: Any, stack: Any, bsize: int, regs: Any, s: int, elems: int,
                   hosts: Any, outq: Any, ctl: Any, latch: Any) -> bool:
    """The host function of the C closure ``regs[R_HOST]`` whose call ``run`` set up, and
    ``VM._loop``'s end of that step; False with nothing done when Python must do it."""
    saved = regs[R_SAVED]
    budget = regs[R_BUDGET]
    n = regs[R_N]
    if saved == NONE or (budget != NONE and n + 1 > budget):
        return False
    nobj = len(d) // s
    c = regs[R_HOST]
    row = -1
    for r in range(len(hosts)):
        if _address_matches(d, c, s, hosts[r, H_ADDRESS], hosts[r, H_PTR_SIZE]):
            row = r
            break
    if row < 0:
        return False
    kind = hosts[row, H_KIND]
    argc = hosts[row, H_ARGC]
    lsyms = regs[R_LSYMS]
    if darray_size(d, lsyms, s, elems) != argc + 1:
        return False  # LNUM: Python reports it
    for i in range(1, argc + 1):
        o = darray_get(d, lsyms, i, s, elems)
        if o < 0 or o >= nobj:
            return False
        if kind == HOST_LATCH and _i(d[o * s]) & 7 != INT:
            return False  # TYPE (or a string id the world would read as an int): Python
    sp = regs[R_SP]
    bp = regs[R_BP]
    if not _ret_ok(d, stack, False, sp, bp, lsyms, bsize, s, elems):
        return False
    # ---- commit: the host function's effect, then ret0 and the end of the step
    if kind == HOST_BROADCAST:
        size = len(outq) // (ctl[OUT_SLOTS] + 1)
        out_append_broadcast(d, outq, ctl, size, darray_get(d, lsyms, 1, s, elems),
                             darray_get(d, lsyms, 2, s, elems), s)
    else:
        slot = hosts[row, H_SLOT]
        latch[slot, 0] = 1
        for i in range(1, argc + 1):
            o = darray_get(d, lsyms, i, s, elems)
            latch[slot, i] = _s16(_i(d[o * s + 1]) | (_i(d[o * s + 2]) << 8))
    _ret(d, stack, regs, False, sp, bp, lsyms, bsize, s, elems)
    regs[R_N] = n + 1
    regs[R_FIXED] = 0
    regs[R_PENDING] = -1
    return True


@_compile
def run_hosted(d: Any, stack: Any, bcode: Any, regs: Any, info: Any, traversed: Any,
               rules: Any, s: int, elems: int, reserved: int, hosts: Any, outq: Any,
               ctl: Any, latch: Any) -> int:
    """:func:`fastloop.run`, with the host functions of ``hosts`` done in place (see the
    module comment); returns what ``run`` last returned."""
    while True:
        status = run(d, stack, bcode, regs, info, traversed, rules, s, elems, reserved)
        if status != HOST_CALL or len(hosts) == 0 or not _host_compiled(
                d, stack, len(bcode), regs, s, elems, hosts, outq, ctl, latch):
            return status


@_compile
def call_pushed(d: Any, stack: Any, bcode: Any, regs: Any, info: Any, traversed: Any,
                rules: Any, s: int, elems: int, reserved: int, sp: int, hosts: Any,
                outq: Any, ctl: Any, latch: Any) -> int:
    """``closure_call``'s loop once its arguments and count are pushed (``sp``: the new
    stack top): the registers of a fresh ``_loop`` with its ``callc`` still to make, then
    :func:`run_hosted`."""
    regs[R_SP] = sp
    regs[R_SAVED] = regs[R_BP]
    regs[R_N] = 0
    regs[R_FIXED] = 0
    regs[R_PENDING] = -1
    regs[R_CALL_FIRST] = 1
    return run_hosted(d, stack, bcode, regs, info, traversed, rules, s, elems, reserved,
                      hosts, outq, ctl, latch)
