"""Compiled entries of the firmware loop into Buzz code (fast VM mode): the in-queue's
listener calls and ``call_global`` (``init``, ``step``), in machine code.

With the instruction kernel (:mod:`fastloop`) running the listeners' bytecode, a swarm's
time went to the Python *around* each listener call: for every received broadcast
``process_inmsgs`` made a collection call, extracted the record, looked the topic string
and the listener up, allocated the userdata and int arguments, pushed them, entered
``closure_call``/``_loop`` (building a register array) and collected again — some 40 µs a
message, nine messages per Kilobot per step. :func:`process_broadcasts` does that whole loop
(``bbzvm_process_inmsgs`` + ``bbzmsg_process_broadcast``) for one robot in one call, calling
the instruction kernel's :func:`fastloop.run` for each listener.

A message's listener call begins on the heap the message's collection left
(``fastloop.CALL_ON_FIXED_HEAP``: the collection after its ``callc`` is replaced by its
effect) and, when nothing it made outlives it, ends with ``fastloop.undo_to_fixed_point``
instead of the collection after its return, leaving the same bytes; for a
Kilobot's gradient listener both hold at every message.

It follows :mod:`fastloop`'s rule — **handle only the happy path, give Python the rest
before any side effect it cannot hand over** — at two points of a message:

* after the message's collection (the first thing the reference does for it) and before its
  extraction: a record that is not a broadcast (stigmergy), a stack without room for the
  six pushes (five arguments and ``closure_call``'s argument count), a heap without room
  for the four objects (topic string, userdata, sender id, argument count): the kernel
  returns :data:`PYTHON_MESSAGE` and ``inmsgs.process_inmsgs`` runs that message with
  the reference routines, the collection already done;
* during the listener call: whatever :func:`fastloop.run` hands back (a host function, an
  instruction it does not cover, an error, the budget, a C closure as listener) is
  returned as :data:`IN_CALL` with the register array as ``run`` left it, and
  ``VM._loop`` resumes the call from that very status (``resume=``), exactly as it would
  have handled it; Python then ends the message (pop, collection).

:func:`call_global` is ``Robot.call_global`` the same way (name string, lookup, pushes,
``closure_call(0)``): :data:`PYTHON_MESSAGE` with nothing done when the stack or the heap
lacks room, ``CALL_UNDER_WAY + status`` when the call must go on in Python. Its call walks
the table library's ``foreach`` in place (``fasthost.run_walking``); a listener's does not.

The records travel as one byte array (the in-queue's records, concatenated: record ``k``
at ``k * record_size``; the last one is the scratch record of ``bbzinmsg_queue_extract``)
and the ring state in a small int64 array (``Q_*`` below). Equality with the reference
(stress mode, Python only) is by test: ``tests/vm/test_fast_inbox_equivalence.py`` and
``tests/worlds/test_fast_swarm_equivalence.py``.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from bbzide.vm.compiled.fastgc import COMPILED, _compile, _compile_owning, _i
from bbzide.vm.compiled.fasthost import (
    call_pushed,
    collect_on_registers,
    end_of_call_collection,
    enter_call,
    run_walking,
)
from bbzide.vm.compiled.fastloop import (
    CALL,
    CALL_ON_FIXED_HEAP,
    EXIT,
    NONE,
    R_GC_RUNS,
    R_GSYMS,
    R_LTSEG,
    R_MARK_DEPTH,
    R_NIL,
    R_OLD_CHANGED,
    R_PRIOR,
    R_REACHED,
    R_RTOBJ,
    R_SP,
    R_STACK_SIZE,
    R_UNSETTLED,
    _obj_alloc,
)
from bbzide.vm.compiled.fasttables import table_lookup
from bbzide.vm.heap_layout import INT, PERMANENT, STRING, TYPE_MASK, USERDATA, VALID
from bbzide.vm.message_layout import BC_TOPIC, BC_VALUE, BROADCAST, RID

# Slots of the ``inq`` array (in: the queue's values; out: the updated ones).
Q_START, Q_END, Q_SLOTS, Q_RECORD = 0, 1, 2, 3   # ring start/end, ring slots, record bytes
Q_COUNT, Q_MAX, Q_COLLECTED = 4, 5, 6   # messages taken, msg_in_proc_max, heap just collected
Q_LISTENERS, Q_EXTRACTED, Q_INNER = 7, 8, 9   # listeners table, kernel extractions, run status
#: slots in the array
QUEUE_SLOTS = 10

# Results.
DONE = 0            # the queue is empty or msg_in_proc_max messages were taken
PYTHON_MESSAGE = 1  # message Q_COUNT's collection is done; Python extracts and processes it
IN_CALL = 2         # a listener call is under way: fastloop.run returned inq[Q_INNER]

#: pushes of one call: nil, listener, topic, value, sender id, then the argument count
_PUSHES = 6
#: objects one call allocates before its callc: topic string, value, sender id, count
_OBJECTS = 4
#: ``closure_call(3)``: a listener gets (topic, value, sender id)
_LISTENER_ARGS = 3


@_compile
def _room_for_objects(d: Any, regs: Any, s: int, reserved: int, wanted: int) -> bool:
    """At least ``wanted`` allocations would succeed: free slots below rtobj plus room to
    grow (a deduplicated string needs neither, so this may be one too strict: harmless)."""
    rtobj = regs[R_RTOBJ]
    free = (regs[R_LTSEG] - rtobj) // s
    i = reserved
    while free < wanted and i < rtobj // s:
        if not _i(d[i * s]) & VALID:
            free += 1
        i += 1
    return free >= wanted


@_compile_owning
def process_broadcasts(d: Any, stack: Any, bcode: Any, regs: Any, info: Any,
                       traversed: Any, rules: Any, s: int, elems: int, reserved: int,
                       records: Any, inq: Any, hosts: Any, outq: Any, ctl: Any,
                       latch: Any) -> int:
    """``bbzvm_process_inmsgs`` from message ``inq[Q_COUNT] + 1`` on (see the module
    comment). ``regs``: the VM's registers in ``fastloop``'s ``R_*`` layout (``R_BUDGET``
    the instruction budget of one call); the VM must be READY. Returns :data:`DONE`,
    :data:`PYTHON_MESSAGE` or :data:`IN_CALL`. ``hosts`` ... ``latch``: the compiled host
    functions the listeners may call (:func:`fasthost.run_hosted`; empty from Python)."""
    limit = regs[R_MARK_DEPTH]
    frames = np.empty((4, limit + 2), np.int64)  # the collector's mark stack, reused
    n = inq[Q_RECORD]
    slots = inq[Q_SLOTS]
    scratch = slots * n  # records[capacity]: bbzinmsg_queue_extract's copy
    listeners = inq[Q_LISTENERS]
    while True:
        start = inq[Q_START]
        if start == inq[Q_END] or inq[Q_COUNT] >= inq[Q_MAX]:
            return DONE
        # ---- the message's collection (or, right after one, only its count)
        inq[Q_COUNT] += 1
        regs[R_GC_RUNS] += 1
        if inq[Q_COLLECTED] == 0:
            collect_on_registers(d, stack, regs, info, traversed, frames, s, elems, reserved)
        inq[Q_COLLECTED] = 0
        # the fixed point the listener call is begun on (CALL_ON_FIXED_HEAP) and undone to
        regs[R_REACHED] = 0
        regs[R_OLD_CHANGED] = 0
        # ---- anything but the happy path: Python takes the message from here
        head = ((start & 0xFF) % slots) * n
        sp = regs[R_SP]
        if _i(records[head]) != BROADCAST or sp + _PUSHES >= regs[R_STACK_SIZE] \
                or not _room_for_objects(d, regs, s, reserved, _OBJECTS):
            return PYTHON_MESSAGE
        # ---- inmsg_extract: the head into the scratch record, pop
        for j in range(n):
            records[scratch + j] = records[head + j]
        inq[Q_START] = ((start + 1) & 0xFF) % slots
        inq[Q_EXTRACTED] += 1
        # ---- process_broadcast: topic string (kept above the top), listener lookup
        sid = _i(records[scratch + BC_TOPIC]) | (_i(records[scratch + BC_TOPIC + 1]) << 8)
        topic = _obj_alloc(d, regs, s, reserved, STRING, sid)
        d[topic * s + 1] = sid & 0xFF
        d[topic * s + 2] = sid >> 8
        stack[sp + 1] = topic
        listener = table_lookup(d, listeners, topic, s, elems)
        if listener < 0:
            continue
        stack[sp + 1] = regs[R_NIL]  # self
        stack[sp + 2] = listener
        stack[sp + 3] = topic
        value = _obj_alloc(d, regs, s, reserved, USERDATA, 0)  # bbzvm_pushu(0)
        o = value * s
        for j in range(1, s):
            d[o + j] = 0
        stack[sp + 4] = value
        d[o] = (_i(d[o]) & (0xFF ^ TYPE_MASK ^ PERMANENT)) | \
            (_i(records[scratch + BC_VALUE]) & TYPE_MASK)
        for j in range(1, s):
            d[o + j] = records[scratch + BC_VALUE + j]
        sender = _obj_alloc(d, regs, s, reserved, INT, 0)
        d[sender * s + 1] = records[scratch + RID]
        d[sender * s + 2] = records[scratch + RID + 1]
        stack[sp + 5] = sender
        # ---- closure_call(3): push the count, the kernel's callc, run to the return
        argc = _obj_alloc(d, regs, s, reserved, INT, 0)
        d[argc * s + 1] = _LISTENER_ARGS
        d[argc * s + 2] = 0
        stack[sp + 6] = argc
        status = call_pushed(d, stack, bcode, regs, info, traversed, rules, s, elems,
                             reserved, sp + _PUSHES, hosts, outq, ctl, latch,
                             CALL if regs[R_UNSETTLED] else CALL_ON_FIXED_HEAP)
        if status != EXIT or regs[R_SP] < 0:
            inq[Q_INNER] = status
            return IN_CALL
        # ---- the end of process_broadcast: pop the result, collect
        regs[R_SP] -= 1
        end_of_call_collection(d, stack, regs, info, traversed, frames, s, elems, reserved,
                               True)
        inq[Q_COLLECTED] = 1 - regs[R_UNSETTLED]


#: pushes of a global's call: the name (then popped), nil, the closure, the argument count
_CALL_PUSHES = 3
#: objects it allocates before its callc: the name string, the argument count
_CALL_OBJECTS = 2
# Results of call_global.
NOT_DEFINED = 3     # no such global: the name was pushed and popped, nothing called
CALLED = 4          # the call ran to its return; its result is on the stack
CALL_UNDER_WAY = 8  # + fastloop.run's status (all below 8): Python goes on with the call


@_compile
def call_global(d: Any, stack: Any, bcode: Any, regs: Any, info: Any, traversed: Any,
                rules: Any, s: int, elems: int, reserved: int, sid: int, hosts: Any,
                outq: Any, ctl: Any, latch: Any, fixed: bool) -> int:
    """``Robot.call_global`` of string ``sid`` with no argument (``bbzkilo_func_call``:
    pushs, pop, look the global up, push nil and the closure, ``closure_call(0)``) on the
    happy path; the VM must be READY. ``fixed``: the heap is a fixed point of the collector
    (the in-queue's last message just ended with its collection), so the call may begin
    with ``CALL_ON_FIXED_HEAP`` when the name string was an old one. Returns
    :data:`PYTHON_MESSAGE` with nothing done (no room on the stack or in the heap: Python
    calls it), :data:`NOT_DEFINED`,
    :data:`CALLED`, or ``CALL_UNDER_WAY + status`` where ``status`` is what
    :func:`fastloop.run` returned, for ``VM._loop``'s ``resume``."""
    sp = regs[R_SP]
    if sp + _CALL_PUSHES >= regs[R_STACK_SIZE] \
            or not _room_for_objects(d, regs, s, reserved, _CALL_OBJECTS):
        return PYTHON_MESSAGE
    regs[R_REACHED] = 0
    regs[R_OLD_CHANGED] = 0
    name = _obj_alloc(d, regs, s, reserved, STRING, sid)
    entry = CALL_ON_FIXED_HEAP if fixed and regs[R_PRIOR] & VALID \
        and not regs[R_UNSETTLED] else CALL
    d[name * s + 1] = sid & 0xFF
    d[name * s + 2] = sid >> 8
    stack[sp + 1] = name  # push + pop: the slot above the top keeps it
    closure = table_lookup(d, regs[R_GSYMS], name, s, elems)
    if closure < 0:
        return NOT_DEFINED
    stack[sp + 1] = regs[R_NIL]
    stack[sp + 2] = closure
    argc = _obj_alloc(d, regs, s, reserved, INT, 0)
    d[argc * s + 1] = 0
    d[argc * s + 2] = 0
    stack[sp + 3] = argc
    enter_call(regs, sp + _CALL_PUSHES, entry)
    status = run_walking(d, stack, bcode, regs, info, traversed, rules, s, elems, reserved,
                         hosts, outq, ctl, latch)
    if status != EXIT:
        return CALL_UNDER_WAY + status
    return CALLED


__all__ = ["COMPILED", "process_broadcasts", "call_global", "DONE", "PYTHON_MESSAGE", "IN_CALL",
           "NOT_DEFINED", "CALLED", "CALL_UNDER_WAY", "QUEUE_SLOTS", "NONE"]
