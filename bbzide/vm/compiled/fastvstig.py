"""Compiled in-queue loop over stigmergy messages (fast VM mode): ``bbzvm_process_inmsgs`` +
``bbzmsg_process_vstig`` in machine code.

A search-and-rescue drone (examples/sar) receives some sixteen virtual-stigmergy records per
world step, most of them repeats of entries it already holds. In Python each cost ~23 µs:
the in-queue loop's collection call, the extraction, a walk over the entry list, an
out-queue append and a collection again. :func:`process_vstigs` runs that loop
(``inmsgs.go_on_inmsgs`` + ``vstig.process_vstig``) over the consecutive stigmergy records
at the head of the in-queue in one call:

* the message's collection at the top of the loop (only counted when the previous message
  ended with one: the heap is then the collector's fixed point);
* the extraction into the scratch record (``inmsg_extract``);
* the entry lookup and one of: a newer timestamp adopted (the old value's VALID bit
  cleared, a copy of the message's object allocated, the PERMANENT bit moved, the entry
  updated, a PUT queued), a QUERY answered with a newer local entry (a PUT queued), an equal
  timestamp from another robot with no ``onconflict`` handler (the string
  ``__INTERNAL_1_DO_NOT_USE__`` made, the remote value adopted when its robot id is not
  lower, a PUT queued), an unknown key appended (a copy made permanent, a PUT queued), or
  nothing;
* every PUT queued as ``messages.outmsg_append_vstig`` does (the full queue's overwrite of
  its last record and the sort by type included);
* the collection that ends ``process_vstig``. When the message wrote nothing to the heap
  (a repeat, an answer, a conflict the local entry keeps when the string already existed,
  as it does in a heap profile's ``neighbors`` table: 96 messages in 100 for a drone) the
  heap is still the fixed point the message's own collection left and the stack is
  untouched, so this collection would change nothing: it is counted and not run, the fast
  mode's rule for consecutive collections.

It follows the kernels' rule (:mod:`fastloop`): **check everything first, then commit**.
After a message's collection and before its extraction the kernel returns
:data:`PYTHON_MESSAGE` for anything off the happy path — a conflict with a handler (a Buzz
call), a heap without room for the objects the message allocates (error MEM in Python),
an entry table with no row left, an entry value outside the heap — and
``inmsgs.go_on_inmsgs`` runs that message with the reference routines, the collection
already done. The one write that may precede such a hand-back is the conflict's string,
which ``_conflict`` makes again first thing: its allocation finds the very object the
kernel made (the first free slot then, or the string it deduplicated to), so the
reference's state is the same as if the kernel had not run. A record that is not a
stigmergy message stops the loop with nothing done for it (:data:`OTHER`).

Layouts: ``records`` is the in-queue's records concatenated (record ``k`` at
``k * record``, the last one the scratch record), ``outq`` the out-queue's the same way;
``entries`` has one row per ``vm.vstig`` entry (``E_*`` columns) and room for the rows the
call may append; the ring indices, counters and constants travel in ``state`` (``V_*``).
The VM registers are ``fastloop``'s ``R_*`` array. Equality with the reference (stress
mode, Python only) is by test: ``tests/vm/test_fast_vstig_equivalence.py``,
``tests/vm/test_fast_inbox_equivalence.py`` and the swarm equivalence tests (sar).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from bbzide.vm.compiled.fastgc import COMPILED, _compile, _compile_owning, _i
from bbzide.vm.compiled.fasthost import collect_on_registers, find_entry, out_append_vstig
from bbzide.vm.compiled.fastinbox import _room_for_objects
from bbzide.vm.compiled.fastloop import (
    R_GC_RUNS,
    R_MARK_DEPTH,
    R_PRIOR,
    R_UNSETTLED,
    _obj_alloc,
    _slot_freed,
)
from bbzide.vm.compiled.fasttables import table_lookup
from bbzide.vm.compiled.packed_queues import VSTIG_COLUMNS
from bbzide.vm.heap_layout import PERMANENT, STRING, USERDATA, VALID
from bbzide.vm.message_layout import RID, TYPE, VS_DATA, VS_KEY, VS_LAMPORT, VSTIG_PUT, VSTIG_QUERY

__all__ = ["COMPILED", "process_vstigs", "DONE", "PYTHON_MESSAGE", "OTHER", "STATE_SLOTS",
           "ENTRY_COLUMNS", "E_KEY", "E_VALUE", "E_TIMESTAMP", "E_ROBOT", "V_START", "V_END",
           "V_SLOTS", "V_RECORD", "V_COUNT", "V_MAX", "V_COLLECTED", "V_TAKEN", "V_ROBOT",
           "V_THRESHOLD", "V_HPOS", "V_EXTRACTED", "V_ENTRIES", "V_OUT_START", "V_OUT_END",
           "V_OUT_SLOTS"]

# Slots of the ``state`` array (in: the queues' and VM's values; out: the updated ones).
V_START, V_END, V_SLOTS, V_RECORD = 0, 1, 2, 3   # in-queue ring start/end/slots, record bytes
V_COUNT, V_MAX = 4, 5          # messages taken so far, msg_in_proc_max
V_COLLECTED = 6                # the heap is what a collection left (the next one is counted)
V_TAKEN = 7                    # in: the head message's collection is already done
V_ROBOT, V_THRESHOLD = 8, 9    # vm.robot, the profile's lamport_threshold
V_HPOS = 10                    # vm.vstig.hpos: the stigmergy table (its onconflict handler)
V_EXTRACTED = 11               # out: messages the kernel extracted (scratch record written)
V_ENTRIES = 12                 # rows of ``entries`` in use
V_OUT_START, V_OUT_END, V_OUT_SLOTS = 13, 14, 15   # out-queue ring
#: slots in the array
STATE_SLOTS = 16

#: columns of an ``entries`` row: ``VstigEntry``'s fields
E_KEY, E_VALUE, E_TIMESTAMP, E_ROBOT = 0, 1, 2, 3
ENTRY_COLUMNS = VSTIG_COLUMNS

# Results.
DONE = 0            # the queue is empty or msg_in_proc_max messages were taken
PYTHON_MESSAGE = 1  # message V_COUNT's collection is done; Python extracts and processes it
OTHER = 2           # the head is not a stigmergy record: nothing done for it

#: ``__INTERNAL_1_DO_NOT_USE__``: the stigmergy table's key of the onconflict handler
_STR_ONCONFLICT_FIELD = 44

# What a message does once found off or on its entry (the reference's branches).
_APPEND, _ADOPT, _ANSWER, _CONFLICT, _NOTHING = range(5)


@_compile
def _newer(lamport: int, old: int, threshold: int) -> bool:
    """``bbzlamport_isnewer``: circular u8 comparison within the threshold."""
    return lamport != old and ((lamport - old) & 0xFF) < threshold


@_compile
def _alloc_copy(d: Any, regs: Any, s: int, reserved: int, records: Any, at: int) -> int:
    """``vstig._alloc_copy`` (room checked by the caller): a userdata slot overwritten with
    the ``s`` bytes at ``records[at]``, marked valid."""
    o = _obj_alloc(d, regs, s, reserved, USERDATA, 0)
    for j in range(s):
        d[o * s + j] = records[at + j]
    d[o * s] |= VALID
    return o


@_compile
def _adopt(d: Any, regs: Any, s: int, reserved: int, records: Any, at: int, entries: Any,
           i: int, rid: int, lamport: int) -> None:
    """The entry takes the message's value: robot, the old value's VALID bit cleared, the
    copy allocated (possibly into that very slot), PERMANENT moved, timestamp."""
    entries[i, E_ROBOT] = rid
    old = entries[i, E_VALUE]
    d[old * s] &= 0xFF ^ VALID
    _slot_freed(regs, old)
    o = _alloc_copy(d, regs, s, reserved, records, at)
    d[old * s] &= 0xFF ^ PERMANENT
    entries[i, E_VALUE] = o
    d[o * s] |= PERMANENT
    entries[i, E_TIMESTAMP] = lamport


@_compile_owning
def process_vstigs(d: Any, stack: Any, regs: Any, info: Any, traversed: Any, s: int,
                   elems: int, reserved: int, records: Any, state: Any, entries: Any,
                   outq: Any) -> int:
    """The in-queue loop over the stigmergy records at its head, from message
    ``state[V_COUNT] + 1`` on (see the module comment; ``state[V_TAKEN]``: message
    ``V_COUNT`` is collected already, its extraction is next). ``regs``: the VM's registers
    in ``fastloop``'s ``R_*`` layout; the VM must be READY. Returns :data:`DONE`,
    :data:`PYTHON_MESSAGE` or :data:`OTHER`."""
    size = len(d)
    nobj = size // s
    limit = regs[R_MARK_DEPTH]
    frames = np.empty((4, limit + 2), np.int64)  # the collector's mark stack, reused
    n = state[V_RECORD]
    slots = state[V_SLOTS]
    scratch = slots * n  # records[capacity]: bbzinmsg_queue_extract's copy
    threshold = state[V_THRESHOLD]
    while True:
        start = state[V_START]
        head = ((start & 0xFF) % slots) * n
        if state[V_TAKEN]:
            state[V_TAKEN] = 0
        else:
            if start == state[V_END] or state[V_COUNT] >= state[V_MAX]:
                return DONE
            typ = _i(records[head + TYPE])
            if typ != VSTIG_PUT and typ != VSTIG_QUERY:
                return OTHER
            # ---- the message's collection (or, right after one, only its count)
            state[V_COUNT] += 1
            regs[R_GC_RUNS] += 1
            if state[V_COLLECTED] == 0:
                collect_on_registers(d, stack, regs, info, traversed, frames, s, elems,
                                     reserved)
        state[V_COLLECTED] = 0
        # ---- the message's branch, and everything it needs, before any write
        typ = _i(records[head + TYPE])
        rid = _i(records[head + RID]) | (_i(records[head + RID + 1]) << 8)
        key = _i(records[head + VS_KEY]) | (_i(records[head + VS_KEY + 1]) << 8)
        lamport = _i(records[head + VS_LAMPORT])
        count = state[V_ENTRIES]
        i = find_entry(entries, count, key)
        objects = 0
        if i < 0:
            branch = _APPEND
            objects = 1
            if count >= len(entries):
                return PYTHON_MESSAGE
        else:
            ts = entries[i, E_TIMESTAMP]
            value = entries[i, E_VALUE]
            if not 0 <= value < nobj:
                return PYTHON_MESSAGE
            if _newer(lamport, ts, threshold):
                branch = _ADOPT
                objects = 1
            elif typ == VSTIG_QUERY and _newer(ts, lamport, threshold):
                branch = _ANSWER
            elif ts == lamport and entries[i, E_ROBOT] != rid:
                branch = _CONFLICT
                objects = 2 if rid >= entries[i, E_ROBOT] else 1
            else:
                branch = _NOTHING
        if objects > 0 and not _room_for_objects(d, regs, s, reserved, objects):
            return PYTHON_MESSAGE
        dirty = branch == _APPEND or branch == _ADOPT
        if branch == _CONFLICT:
            # _conflict's handler lookup: the string first (a new slot, or one deduplicated
            # to), then the table; with a handler Python makes the call (its own
            # new_string_obj finds this same object: see the module comment)
            name = _obj_alloc(d, regs, s, reserved, STRING, _STR_ONCONFLICT_FIELD)
            d[name * s + 1] = _STR_ONCONFLICT_FIELD & 0xFF
            d[name * s + 2] = _STR_ONCONFLICT_FIELD >> 8
            if not _i(regs[R_PRIOR]) & VALID:
                dirty = True  # a new string, not one deduplicated to
            if table_lookup(d, state[V_HPOS], name, s, elems) >= 0:
                return PYTHON_MESSAGE
        # ---- commit: inmsg_extract (the head into the scratch record, pop)
        for j in range(n):
            records[scratch + j] = records[head + j]
        state[V_START] = ((start + 1) & 0xFF) % slots
        state[V_EXTRACTED] += 1
        data = scratch + VS_DATA
        if branch == _APPEND:
            o = _alloc_copy(d, regs, s, reserved, records, data)
            d[o * s] |= PERMANENT
            entries[count, E_KEY] = key
            entries[count, E_VALUE] = o
            entries[count, E_TIMESTAMP] = lamport
            entries[count, E_ROBOT] = rid
            state[V_ENTRIES] = count + 1
            out_append_vstig(d, outq, state, V_OUT_START, n, s, VSTIG_PUT, rid, key, o, lamport)
        elif branch == _ADOPT:
            _adopt(d, regs, s, reserved, records, data, entries, i, rid, lamport)
            out_append_vstig(d, outq, state, V_OUT_START, n, s, VSTIG_PUT, rid, key,
                              entries[i, E_VALUE], lamport)
        elif branch == _ANSWER:
            out_append_vstig(d, outq, state, V_OUT_START, n, s, VSTIG_PUT, state[V_ROBOT], key,
                              entries[i, E_VALUE], entries[i, E_TIMESTAMP])
        elif branch == _CONFLICT:
            if rid >= entries[i, E_ROBOT]:
                _adopt(d, regs, s, reserved, records, data, entries, i, rid, lamport)
                dirty = True
            out_append_vstig(d, outq, state, V_OUT_START, n, s, VSTIG_PUT, entries[i, E_ROBOT],
                              entries[i, E_KEY], entries[i, E_VALUE],
                              entries[i, E_TIMESTAMP])
        # ---- process_vstig's closing collection (only counted on an unchanged heap)
        regs[R_GC_RUNS] += 1
        if dirty or regs[R_UNSETTLED]:
            collect_on_registers(d, stack, regs, info, traversed, frames, s, elems, reserved)
        state[V_COLLECTED] = 1 - regs[R_UNSETTLED]
