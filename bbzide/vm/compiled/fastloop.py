"""Compiled instruction kernel of the fast VM mode: the common instructions, in machine code.

With the collector compiled (:mod:`fastgc`), the cost of the fast VM was the Python
dispatch itself: one method call per instruction plus a few heap reads, ~4 µs. This module
runs the step loop of ``VM._loop`` — the collection (or the skip rule that proves it
changeless), then one instruction — as one numba function over the heap bytes
(``np.frombuffer(heap.data)``, the same memory as the ``bytearray``), the u16 stack
(``np.frombuffer`` of the VM's ``array('H')``) and the bytecode, so a loop never leaves
machine code until it meets an instruction the kernel does not cover.

**The one rule that keeps it exact: handle only the happy path, bail out before any side
effect.** For every covered instruction the kernel first checks everything that could make
the Python routine (:mod:`bbzide.vm.vm`) do something other than its normal path — stack
underflow/overflow, a wrong type, an object index past the heap, a full heap, a jump past
the code, a division by zero, a lambda to bind, a local to create — and if any holds it
returns :data:`NEED_PYTHON` *before touching anything* of that instruction: the Python
routine then runs it from the start, so errors, their pcs and every quirk stay in one place.
(``darray_size``'s unlinking write, done by ``lstore``'s check, is idempotent: Python redoing
it writes the same bytes.) Covered, on their happy path: nop, calls, pushnil, dup, pop,
int add/sub/mul/div/mod/pow/unm, float add/sub/mul/div/mod/unm (operands INT or FLOAT, one
FLOAT: the model's double operations and its float32 encoding, bit for bit, by test:
``tests/vm/test_fast_floats.py``), the logical ops, lnot, bnot, the six comparisons
(``bbztype_cmp``), gload, gstore, pusht (when the heap holds the table and its segment),
tget, tput (no method binding), pushf, pushi, pushs (string dedupe), pushcn, pushcc, pushl
(when the heap holds its objects and segments and, with lsyms set, a reserved slot is free
for the activation record), lload, lstore (existing local), jump, jumpz, jumpnz. callc and
ret0/ret1 of bytecode closures (Python only calls the host function of a C closure, status
HOST_CALL), lremove (of several locals when the last segment holds them). Python keeps:
done, float pow (a MATH error), every error.

Before each instruction the kernel does what ``VM._loop`` does: a collection by the
compiled ``fastgc.collect_with`` unless the previous instruction kept the heap a fixed point of
the collector (``_SKIP_RULES``, repeated here as :data:`RULES`), then counts ``gc_runs``.
A skipped collection may owe more than a mark bit: the *fresh* leaves (:data:`FRESH`) the
last instruction dropped, which it frees as that collection would (:func:`_free_dropped`);
in a real swarm script most temporaries (``pushi 33`` of ``d / 33``, a comparison's result
popped by ``jumpz``) die that way, a collection saved each. Every such rule rests on a
collection being a fixed point of itself, which one that marked a slot at or above the
object end it left is not (``fastgc.UNSETTLED``, :data:`R_UNSETTLED`): the one after it runs.
They also rest on a fresh object being referenced only where the code put it, which a heap
whose collector once stopped at the depth limit cannot promise (a freed slot may still be
named by a table's word: ``fastgc.TRUNCATED``): every collection of such a heap runs.
Calls have their own shortcuts, each checked before it writes anything: a listener or
``step`` called by a compiled entry on a heap its caller vouches for
(:data:`CALL_ON_FIXED_HEAP`) skips the collection after its ``callc``
(:func:`_entered_on_fixed_heap`), and when nothing the call did outlives it the entry ends
it by returning to that heap (:func:`undo_to_fixed_point`: the new objects freed, which
``info``'s :data:`NEW` bit and :data:`FRESH` value tell); a compiled host function's
frame whose dropped roots are all kept or fresh is freed without a collection
(:func:`end_host_frame`).
The VM registers travel in one int64 array (``R_*`` below) so that a call costs one
dispatch. Equality with the reference is by test: ``tests/vm/test_fast_vm_equivalence.py``.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from bbzide.vm.compiled.fastgc import (
    COMPILED,
    OWNED,
    PERMANENT_PHASE,
    TRUNCATED,
    UNSETTLED,
    VALID_BELOW_SHIFT,
    _compile,
    _compile_owning,
    _i,
    collect_with,
    first_free,
)
from bbzide.vm.compiled.fastgc import first_free_segment as _first_free_segment
from bbzide.vm.compiled.fasttables import darray_get, darray_set, darray_size, table_lookup

# Register slots of the ``regs`` array (in: the VM's values; out: the updated ones).
R_PC, R_SP, R_BP, R_RTOBJ, R_LTSEG, R_LSYMS, R_GC_RUNS, R_EXECUTED = range(8)
R_N, R_FIXED, R_PENDING, R_PEAK = 8, 9, 10, 11
R_NIL, R_GSYMS, R_SAVED, R_BUDGET, R_FLOAT_OPS, R_STACK_SIZE, R_MARK_DEPTH = range(12, 19)
R_FLIST, R_DFLT_ACTREC, R_HOST, R_CALL_FIRST, R_PRIOR = 19, 20, 21, 22, 23
#: set to 1 by an allocation that took a free slot the last collection reached (its mark
#: bit set: a stale reference leads there), which a new object changes the walk of
R_REACHED = 24
#: set to 1 by a collection, and by a skip rule that rewrites an old object's ``info``:
#: the caller's fixed point is then no longer the one :func:`fastinbox`'s shortcut undoes
R_OLD_CHANGED = 25
#: after a ``HOST_CALL``: the argument count's index, or -1 when an allocation of the call
#: took a slot the last collection reached (then the collection after the host function's
#: return must run; else :func:`host_frame_droppable` decides)
R_HOST_COUNT = 26
#: every object slot from the reserved ones up to this index is valid (0: nothing known),
#: so an allocation's first-fit scan may start there; a string's does not (it looks for a
#: twin among the valid strings below the first free slot). Allocations raise it, every
#: free lowers it (:func:`_slot_freed`; a collection sets it to the lowest slot its sweep
#: left invalid, ``fastgc.VALID_BELOW_SHIFT``); Python's registers start at 0,
#: and the swarm step sets it to 0 for each robot: Python may have freed objects since.
R_VALID_BELOW = 27
#: 1 when the last collection was not a fixed point of the collector (``fastgc.UNSETTLED``):
#: until the next one runs, no rule may take the heap for a fixed point and skip it
R_UNSETTLED = 28
#: 1 once a collection of this heap stopped at the depth limit (``fastgc.TRUNCATED``); it
#: stays 1, and so does :data:`R_UNSETTLED` after every collection
R_TRUNCATED = 29
#: the previous element of a table walk (:data:`CALL_IN_WALK`; 0: none): its activation
#: record and the return-address and block-pointer ints its ``callc`` pushed, which the
#: next element's entry frees with the rest of what the element left
R_LEFT_FRAME, R_LEFT_RET, R_LEFT_BP = 30, 31, 32
#: a string's twin known without a scan: ``pushs`` deduplicates its string by a first-fit
#: scan from the reserved slots for a valid string with the same id (``first_free``), and an
#: M300 drone's global names sit past ~90 host function names, so each global access
#: scanned ~90 slots. Every slot from the reserved ones up to ``R_TWIN_END`` is valid, and
#: each of the :data:`TWIN_SLOTS` registers from ``R_TWINS`` on (indexed by the id's low
#: bits) holds ``(id + 1) << 16 | slot``: that id's lowest string, when the slot is below
#: ``R_TWIN_END``. A scan from the reserved slots raises the end past what it passed (the
#: registers that slot does not vouch for cleared); every free lowers it, as it lowers
#: ``R_VALID_BELOW``, and Python's registers start at 0 (:func:`_known_twin`,
#: :func:`_note_twin`)
R_TWIN_END = 33
R_TWINS = 34
#: twins known at once (a power of two: the id's low bits pick the register): the flocking
#: example pushes 28 distinct strings, the gradient one 10; a name whose register another
#: name took is scanned for as before (the search-and-rescue mission pushes 229, most of
#: them once in a while). 32 adds 256 bytes to a robot's registers
TWIN_SLOTS = 32
#: registers in the array
REGISTERS = R_TWINS + TWIN_SLOTS
#: R_SAVED / R_BUDGET value meaning "none" (run() has no saved blockptr; no budget)
NONE = -(1 << 40)

# Kernel results.
EXIT = 0           # the loop's condition ended it (blockptr dropped to the saved one)
NEED_PYTHON = 1    # this step's collection is done; Python runs the instruction at pc
BUDGET = 2         # a step completed and the instruction budget condition now holds
HOST_CALL = 3      # a callc of a C closure (index in R_HOST) is set up: Python calls the
#                    host function and finishes the step (VM._host_call)
CALL_IN_PYTHON = 4  # R_CALL_FIRST: closure_call's callc is not the kernel's: Python makes it
SLICE = 5          # SLICE_STEPS steps done: back to Python, which re-enters at once (so
#                    that Ctrl-C reaches a VM looping forever without a budget)
#: R_CALL_FIRST values: the call of ``closure_call`` (1), or the same on a heap its caller
#: vouches for (2): a fixed point before the caller's pushes, which are new leaves (the
#: argument count last) only the stack holds: the collection after the ``callc`` may then
#: be replaced by its effect (:func:`_entered_on_fixed_heap`)
CALL, CALL_ON_FIXED_HEAP = 1, 2
#: R_CALL_FIRST value: a table walk's element call (``fasthost.table_walk``, the table
#: library's ``foreach``). Its first collection frees what the previous element left and
#: nothing else when, since that element's own first collection (a fixed point), nothing was
#: stored where it outlives the element (``R_OLD_CHANGED``) and no allocation took a
#: reached slot (``R_REACHED``): the return to that fixed point plus this element's frame
#: (:func:`_undo_to_element_start`) then replaces it. (The C loop collects only there:
#: ``bbztable_foreach`` calls the closure, and the closure's first step collects.)
CALL_IN_WALK = 3
#: steps per kernel call at most: ~0.5 s of machine code, then Python handles its signals
SLICE_STEPS = 1 << 20

# Metadata bits and types (heap.py), as literals for the compiled code.
_NIL, _INT, _FLOAT, _STRING, _TABLE, _CLOSURE, _USERDATA = 0, 1, 2, 3, 4, 5, 6
_VALID = 0x08
_PERMANENT = 0x10
_GC_MARK = 0x20
_FLAG1 = 0x40
_FLAG2 = 0x80
_NO_ACTREC = 0xFF
_NO_NEXT = 0x3FFF

#: skip rules by opcode — the same table as ``vm._SKIP_RULES`` (checked equal by a test;
#: the rules from _REPLACED_TOP on, those of instructions that drop stack roots, only this
#: kernel applies: see there)
_PC_ONLY, _PUSHED_OLD, _PUSHED_NEW, _REPLACED_TOP, _POPPED_TWO_NEW = 1, 2, 3, 4, 5
_POPPED_ONE, _POPPED_ONE_NEW, _POPPED_TWO_OLD, _STORED_NEW_LOCAL = 6, 7, 8, 9
_STORED_GLOBAL, _STORED_IN_TABLE, _REMOVED_LOCALS = 10, 11, 12
RULES = np.zeros(256, np.int64)
for _op in (0, 34, 44):
    RULES[_op] = _PC_ONLY
for _op in (2, 41):
    RULES[_op] = _PUSHED_OLD
for _op in (3, 35, 36, 37, 38, 39):
    RULES[_op] = _PUSHED_NEW
RULES[28] = _REPLACED_TOP  # gload
for _op in (7, 8, 9, 10, 11, 12, 14, 15, 17, 18, 22, 23, 24, 25, 26, 27):
    RULES[_op] = _POPPED_TWO_NEW  # arithmetic, logic and comparisons of two operands
for _op in (4, 45, 46):
    RULES[_op] = _POPPED_ONE  # pop, jumpz, jumpnz
for _op in (13, 16, 19):
    RULES[_op] = _POPPED_ONE_NEW  # unm, lnot, bnot
RULES[32] = _POPPED_TWO_OLD  # tget
RULES[42] = _STORED_NEW_LOCAL  # lstore
RULES[29] = _STORED_GLOBAL  # gstore
RULES[31] = _STORED_IN_TABLE  # tput
RULES[43] = _REMOVED_LOCALS  # lremove
#: ``info`` value of a *fresh* leaf: one a skipped step allocated (in a slot the last
#: collection did not reach), so its one reference is its own stack slot — or a ``dup``'s
#: copy of a table the permanent roots keep (see :func:`_table_copy_kept`). The collector
#: never writes it (its depths start at 2); a collection clears it.
FRESH = 1
#: ``info`` bit of an object allocated since the caller's fixed point that a skip rule
#: marked as reached (:func:`_entered_on_fixed_heap`, :func:`_stored_leaf_kept`): with the
#: fresh leaves (``info`` 0 or :data:`FRESH` on a valid object) these are the objects a
#: return to that fixed point frees (:func:`undo_to_fixed_point`). The collector's values
#: stay below it (depth < 64, plus ``PERMANENT_PHASE``).
NEW = 128
#: ``info`` of an :data:`OWNED` number that is also :data:`NEW`: a fresh temporary an
#: ``lstore`` moved into a local (its one reference the frame's slot)
OWNED_NEW = OWNED + NEW
#: OWNED numbers on the stack ``run`` follows at once: an expression reads several global
#: and local numbers before it drops the first one, ``gx = gx + (px - x) * (SEP - d) / d``
#: four (gx's, px's, x's, then SEP's and d's)
OWNED_FOLLOWED = 4
# OWNED (``fastgc.OWNED``): the ``info`` value of an int or float whose one reference is a
# slot of a table walked from the permanent roots (a global's, a table's, a frame's local):
# the collector says so of the numbers it meets once, and a skipped ``gstore`` or ``tput``
# of a fresh one (:func:`_stored_global_kept`, :func:`_stored_in_table_kept`). Overwriting
# that slot frees it, as the skipped collection would; any push of it (the only way to copy
# a reference to it) makes it a plain permanent-reached leaf again (:func:`_old_kept`).


@_compile
def _u16(d: Any, i: int, s: int) -> int:
    return _i(d[i * s + 1]) | (_i(d[i * s + 2]) << 8)


@_compile
def _true(d: Any, o: int, s: int) -> bool:
    """``bbztype_tobool`` of object ``o``: only a non-zero int is true."""
    return (_i(d[o * s]) & 7) == _INT and _u16(d, o, s) != 0


@_compile
def _s16(v: int) -> int:
    v &= 0xFFFF
    return v - 0x10000 if v & 0x8000 else v


@_compile
def _note_usage(regs: Any, size: int) -> None:
    used = regs[R_RTOBJ] + (size - regs[R_LTSEG])
    if used > regs[R_PEAK]:
        regs[R_PEAK] = used


@_compile
def _known_twin(d: Any, regs: Any, s: int, sid: int) -> int:
    """The lowest valid string of id ``sid`` when the twin registers know it (see
    :data:`R_TWIN_END`), or -1."""
    e = regs[R_TWINS + (sid & (TWIN_SLOTS - 1))]
    if e >> 16 != sid + 1:
        return -1
    slot = e & 0xFFFF
    o = slot * s
    if slot >= regs[R_TWIN_END] or _i(d[o]) & (_VALID | 7) != _VALID | _STRING \
            or (_i(d[o + 1]) | (_i(d[o + 2]) << 8)) != sid:
        return -1
    return slot


@_compile
def _note_twin(regs: Any, sid: int, slot: int) -> None:
    """A scan from the reserved slots found every slot below ``slot`` valid and ``slot``
    the lowest string of id ``sid`` (its twin, or the new string it takes)."""
    end = regs[R_TWIN_END]
    if slot + 1 > end:
        for j in range(TWIN_SLOTS):  # slots from the old end on: not known lowest
            if regs[R_TWINS + j] & 0xFFFF >= end:
                regs[R_TWINS + j] = 0
        regs[R_TWIN_END] = slot + 1
    regs[R_TWINS + (sid & (TWIN_SLOTS - 1))] = ((sid + 1) << 16) | slot


@_compile
def _obj_alloc(d: Any, regs: Any, s: int, reserved: int, typ: int, sid: int) -> int:
    """``Heap.obj_alloc`` for a non-table type; -1 (and nothing written) when full. A
    string's caller writes its id into it at once (the twin registers count on it)."""
    rtobj = regs[R_RTOBJ]
    if typ == _STRING:
        start = reserved
        found = _known_twin(d, regs, s, sid)
        if found < 0:
            found = first_free(d, rtobj, s, start, typ, sid)
        else:
            found = -2 - found
    else:
        start = max(reserved, regs[R_VALID_BELOW])
        found = first_free(d, rtobj, s, start, typ, sid)
    if found < -1:
        twin = -2 - found
        regs[R_PRIOR] = d[twin * s]
        regs[R_VALID_BELOW] = max(regs[R_VALID_BELOW], twin + 1)
        _note_twin(regs, sid, twin)
        return twin
    if found < 0:
        if rtobj + s > regs[R_LTSEG]:
            return -1
        found = rtobj // s
        regs[R_RTOBJ] = rtobj + s
        _note_usage(regs, len(d))
    regs[R_VALID_BELOW] = found + 1
    if typ == _STRING:
        _note_twin(regs, sid, found)
    o = found * s
    regs[R_PRIOR] = d[o]  # Heap.prior_mdata
    if _i(d[o]) & (_VALID | _GC_MARK) == _GC_MARK:
        regs[R_REACHED] = 1
    d[o] = typ | _VALID
    if typ == _CLOSURE:
        d[o + 2] = _NO_ACTREC
    return found


@_compile
def take_collection(regs: Any, r: int) -> None:
    """The registers after a collection that returned ``r`` (``fastgc.collect_with``):
    both heap ends, the valid run the sweep left, and whether the heap is settled
    (``R_UNSETTLED``, ``R_TRUNCATED``); the caller counts it."""
    regs[R_RTOBJ] = (r >> 16) & 0xFFFF
    regs[R_LTSEG] = r & 0xFFFF
    regs[R_VALID_BELOW] = r >> VALID_BELOW_SHIFT
    regs[R_TWIN_END] = min(regs[R_TWIN_END], regs[R_VALID_BELOW])
    if r & TRUNCATED:
        regs[R_TRUNCATED] = 1
    regs[R_UNSETTLED] = 1 if r & UNSETTLED or regs[R_TRUNCATED] else 0


@_compile
def _slot_freed(regs: Any, x: int) -> None:
    """Object slot ``x`` was freed: the valid runs below ``R_VALID_BELOW`` and
    ``R_TWIN_END`` end there."""
    if x < regs[R_VALID_BELOW]:
        regs[R_VALID_BELOW] = x
    if x < regs[R_TWIN_END]:
        regs[R_TWIN_END] = x


@_compile
def _room(d: Any, regs: Any, s: int, reserved: int, elems: int, objects: int,
          segments: int) -> bool:
    """Would ``objects`` object allocations, then ``segments`` segment allocations, all
    succeed? Each takes a free slot (first fit) or grows its end of the heap; the objects
    come first, so their growth is what the segments' growth must leave room for."""
    size = len(d)
    g = 4 * elems + 2
    rtobj = regs[R_RTOBJ]
    ltseg = regs[R_LTSEG]
    free = 0
    for i in range(reserved, rtobj // s):
        if free == objects:
            break
        if not _i(d[i * s]) & _VALID:
            free += 1
    rtobj += (objects - free) * s
    if rtobj > ltseg:
        return False
    free = 0
    mo = 4 * elems
    for j in range((size - ltseg) // g):
        if free == segments:
            break
        if not _i(d[size - (j + 1) * g + mo + 1]) & 0x80:  # SEG_VALID, high byte
            free += 1
    return ltseg - (segments - free) * g >= rtobj


@_compile
def _can_alloc(d: Any, regs: Any, s: int, reserved: int) -> bool:
    """Would an object allocation succeed (a free slot below rtobj, or room to grow)?"""
    if regs[R_RTOBJ] + s <= regs[R_LTSEG]:
        return True
    return first_free(d, regs[R_RTOBJ], s, reserved, _INT, 0) >= 0


@_compile
def _float_value(bits: int) -> float:
    """``bbzfloat.to_float``: sign, 6-bit exponent (bias 31), 9-bit fraction; exponent 0
    is (1 + f/512) * 2**-31 unless f is 0, exponents 62 and 63 are infinities. Exact: every
    step multiplies by a power of two."""
    sign = -1.0 if bits & 0x8000 else 1.0
    exponent = (bits >> 9) & 0x3F
    fraction = bits & 0x1FF
    if exponent == 0:
        if fraction == 0:
            return sign * 0.0
        return sign * math.ldexp(1.0 + fraction / 512.0, -31)
    if exponent >= 62:
        return sign * math.inf
    return sign * math.ldexp(1.0 + fraction / 512.0, exponent - 31)


@_compile
def _float_bits(value: float) -> int:
    """``bbzfloat.from_float``: the double rounded to the nearest float32 (past its range
    an infinity, as ``to_float32`` makes it), whose bits are then cut to a bbzfloat: float32
    exponent 0 (zero, denormals) gives a signed zero, 255 (infinity, NaN) an infinity that
    keeps the low 9 mantissa bits, any other outside 97..157 an infinity (tiny values
    included, as the model's encoder does); the mantissa is truncated, not rounded."""
    bits = _i(np.float32(value).view(np.uint32))
    sign = ((bits >> 31) & 1) << 15
    exponent = (bits >> 23) & 0xFF
    mantissa = bits & 0x7FFFFF
    if exponent == 0:
        return sign
    if exponent == 0xFF:
        return sign | 0x7E00 | (mantissa & 0x1FF)
    if 96 < exponent < 158:
        return sign | ((exponent - 96) << 9) | (mantissa >> 14)
    return sign | 0x7E00


@_compile
def _float_arith(op: int, tl: int, ul: int, tr: int, ur: int) -> int:
    """``VM._arith``'s float branch for add, sub, mul, div, mod (opcodes 7-11) of two
    operands, INT or FLOAT, one of them FLOAT (``ul``/``ur``: their u16 payloads): the
    result's bbzfloat bits; -1 when Python must run it. The same double operations as
    the model, in the same order (no fused multiply-add: numba's default, no fastmath)."""
    a = float(_s16(ul)) if tl == _INT else _float_value(ul)
    b = float(_s16(ur)) if tr == _INT else _float_value(ur)
    if op == 7:
        r = a + b
    elif op == 8:
        r = a - b
    elif op == 9:
        r = a * b
    elif op == 10:
        if b != 0:
            r = a / b
        elif a != 0:
            r = math.copysign(math.inf, a) * math.copysign(1.0, b)
        else:
            r = math.nan
    elif op == 11:
        if tl == _INT:
            a = float(ul)  # the model's modulo reads an int dividend unsigned
        if b == 0:
            r = math.nan
        else:
            q = a / b
            if not math.isfinite(q):
                r = math.nan
            elif abs(q) >= 9.2e18:
                # int(q) must stay in int64 to wrap as Python's int does (it does: the
                # operands keep |a| < 2**31 and |b| >= 2**-31, so |q| < 2**62)
                return -1
            else:
                r = a - float(_s16(int(q))) * b
    else:
        return -1
    return _float_bits(r)


@_compile
def _compare(d: Any, a: int, b: int, s: int) -> int:
    """``bbztype_cmp`` (tables.compare); both indices inside the heap."""
    ta = _i(d[a * s]) & 7
    tb = _i(d[b * s]) & 7
    if ta == _NIL or tb == _NIL:
        if ta == tb:
            return 0
        return -1 if ta == _NIL else 1
    if ta == _INT and tb == _INT:
        x = _s16(_u16(d, a, s))
        y = _s16(_u16(d, b, s))
    elif (ta == _FLOAT and (tb == _INT or tb == _FLOAT)) or (tb == _FLOAT and ta == _INT):
        x = _u16(d, a, s)
        y = _u16(d, b, s)
    elif ta == tb and (ta == _STRING or ta == _TABLE):
        x = _u16(d, a, s)
        y = _u16(d, b, s)
    elif ta == tb and ta == _USERDATA:
        # unsigned little-endian pointer values: compare from the most significant byte
        for j in range(s - 1, 0, -1):
            xa = _i(d[a * s + j])
            xb = _i(d[b * s + j])
            if xa != xb:
                return 1 if xa > xb else -1
        return 0
    else:
        return -1
    if x > y:
        return 1
    if x < y:
        return -1
    return 0


@_compile
def _word(d: Any, seg: int, k: int, g: int) -> int:
    o = len(d) - (seg + 1) * g + 2 * k
    return _i(d[o]) | (_i(d[o + 1]) << 8)


@_compile
def _set_word(d: Any, seg: int, k: int, g: int, value: int) -> None:
    o = len(d) - (seg + 1) * g + 2 * k
    d[o] = value & 0xFF
    d[o + 1] = (value >> 8) & 0xFF


@_compile
def _seg_alloc(d: Any, regs: Any, elems: int) -> int:
    """``Heap.seg_alloc``: first invalid segment slot, else grow left; -1 (nothing
    written) when there is no room."""
    size = len(d)
    g = 4 * elems + 2
    ltseg = regs[R_LTSEG]
    new = _first_free_segment(d, ltseg, size, g, elems)
    if new < 0:
        if ltseg - g < regs[R_RTOBJ]:
            return -1
        new = (size - ltseg) // g
        regs[R_LTSEG] = ltseg - g
        _note_usage(regs, size)
    o = size - (new + 1) * g
    if _i(d[o + g - 1]) & 0xC0 == 0x40:  # SEG_MARK without SEG_VALID: reached, free
        regs[R_REACHED] = 1
    for j in range(g - 2):
        d[o + j] = 0
    d[o + g - 2] = 0xFF
    d[o + g - 1] = 0xFF
    return new


@_compile
def _table_set(d: Any, regs: Any, t: int, k: int, v: int, s: int, elems: int) -> bool:
    """``tables.table_set`` on table ``t`` (type checked by the caller; ``k``, ``v`` inside
    the heap). False, with nothing written, when Python must run it: a segment outside
    the heap, a key index past the heap, an over-long chain, or no room for a segment."""
    size = len(d)
    g = 4 * elems + 2
    nobj = size // s
    mo = 2 * 2 * elems  # the mdata word: word index 2E
    v_is_nil = (_i(d[v * s]) & 7) == _NIL
    first = _u16(d, t, s)
    seg = first
    prev = -1
    free_seg = -1
    free_slot = -1
    ended = False
    for _ in range(size // g + 1):
        if seg < 0 or (seg + 1) * g > size:
            return False
        match = -1
        for sl in range(elems):
            kw = _word(d, seg, sl, g)
            if kw & 0x8000:
                if match < 0:
                    ki = kw & 0x7FFF
                    if ki >= nobj:
                        return False
                    if _compare(d, ki, k, s) == 0:
                        match = sl
            elif free_seg < 0:
                free_seg = seg
                free_slot = sl
        if match >= 0:
            if not v_is_nil:
                _set_word(d, seg, match + elems, g, v | 0x8000)
                return True
            _set_word(d, seg, match, g, 0)
            _set_word(d, seg, match + elems, g, 0)
            empty = True
            for sl in range(elems):
                if _word(d, seg, sl, g) & 0x8000:
                    empty = False
            if empty:
                nxt = _word(d, seg, mo // 2, g) & _NO_NEXT
                if seg == first:
                    if nxt != _NO_NEXT:
                        d[t * s + 1] = nxt & 0xFF
                        d[t * s + 2] = (nxt >> 8) & 0xFF
                        _set_word(d, seg, mo // 2, g, 0)
                else:
                    pm = _word(d, prev, mo // 2, g)
                    _set_word(d, prev, mo // 2, g, (pm & ~_NO_NEXT) | nxt)
                    _set_word(d, seg, mo // 2, g, 0)
            return True
        nxt = _word(d, seg, mo // 2, g) & _NO_NEXT
        if nxt == _NO_NEXT:
            ended = True
            break
        prev = seg
        seg = nxt
    if not ended:
        return False  # a chain longer than the heap: let Python do what it does
    if v_is_nil:
        return True
    if free_seg < 0:
        new = _seg_alloc(d, regs, elems)
        if new < 0:
            return False
        lm = _word(d, seg, mo // 2, g)
        _set_word(d, seg, mo // 2, g, (lm & ~_NO_NEXT) | (new & _NO_NEXT))
        free_seg = new
        free_slot = 0
    _set_word(d, free_seg, free_slot, g, k | 0x8000)
    _set_word(d, free_seg, free_slot + elems, g, v | 0x8000)
    return True


@_compile
def _last_segment(d: Any, a: int, s: int, elems: int) -> int:
    """``tables._last_segment`` of darray ``a``; -1 when a segment lies outside the heap
    or the chain is longer than the heap (Python then does what it does)."""
    size = len(d)
    g = 4 * elems + 2
    seg = _u16(d, a, s)
    for _ in range(size // g + 1):
        if (seg + 1) * g > size:
            return -1
        nxt = _word(d, seg, 2 * elems, g) & _NO_NEXT
        if nxt == _NO_NEXT:
            return seg
        seg = nxt
    return -1


@_compile
def _darray_push_in_place(d: Any, a: int, v: int, s: int, elems: int) -> bool:
    """``tables.darray_push`` when the last segment has a free word; False (nothing
    written) when it would need a new segment."""
    seg = _last_segment(d, a, s, elems)
    if seg < 0:
        return False
    g = 4 * elems + 2
    for p in range(2 * elems):
        if not _word(d, seg, p, g) & 0x8000:
            _set_word(d, seg, p, g, v | 0x8000)
            return True
    return False


@_compile
def _darray_pop(d: Any, a: int, s: int, elems: int) -> bool:
    """``tables.darray_pop``; False (nothing written) when the darray is empty or its
    chain is broken (Python then reports LNUM or does what it does)."""
    size = len(d)
    g = 4 * elems + 2
    n = 2 * elems
    first = _u16(d, a, s)
    if (first + 1) * g > size:
        return False
    if _word(d, first, n, g) & _NO_NEXT == _NO_NEXT and not _word(d, first, 0, g) & 0x8000:
        return False
    prev = -1
    seg = first
    ended = False
    for _ in range(size // g + 1):
        nxt = _word(d, seg, n, g) & _NO_NEXT
        if nxt == _NO_NEXT:
            ended = True
            break
        if (nxt + 1) * g > size:
            return False
        prev = seg
        seg = nxt
    if not ended:
        return False
    p = 0
    while p < n and _word(d, seg, p, g) & 0x8000:
        p += 1
    if p > 0:
        _set_word(d, seg, p - 1, g, _word(d, seg, p - 1, g) & 0x7FFF)
    else:
        _set_word(d, prev, n - 1, g, _word(d, prev, n - 1, g) & 0x7FFF)
        _set_word(d, seg, n, g, _word(d, seg, n, g) & 0x7FFF)  # ~SEG_VALID
        _set_word(d, prev, n, g, _word(d, prev, n, g) | _NO_NEXT)
    return True


@_compile
def _last_segment_filled(d: Any, a: int, s: int, elems: int) -> tuple[int, int]:
    """Darray ``a``'s last segment (-1 as :func:`_last_segment`) and how many of its words,
    from the first, are valid elements."""
    seg = _last_segment(d, a, s, elems)
    p = 0
    if seg >= 0:
        g = 4 * elems + 2
        while p < 2 * elems and _word(d, seg, p, g) & 0x8000:
            p += 1
    return seg, p


@_compile
def _last_elements(d: Any, a: int, k: int, s: int, elems: int) -> tuple[int, int]:
    """The objects of darray ``a``'s last ``k`` (1 or 2) elements, the last first, when its
    last segment holds them (-2, -2 otherwise: a pop would empty a segment, which the
    collector's end then walks past)."""
    seg, p = _last_segment_filled(d, a, s, elems)
    if seg < 0 or p < k:
        return -2, -2
    g = 4 * elems + 2
    last = _word(d, seg, p - 1, g) & 0x7FFF
    if k == 1:
        return last, -1
    return last, _word(d, seg, p - 2, g) & 0x7FFF


@_compile
def _darray_pop_in_place(d: Any, a: int, k: int, s: int, elems: int) -> bool:
    """``k`` times ``tables.darray_pop`` when the last segment holds ``k`` elements or more
    (each pop then clears its last valid word); False, with nothing written, otherwise."""
    seg, p = _last_segment_filled(d, a, s, elems)
    if seg < 0 or p < k:
        return False
    g = 4 * elems + 2
    for q in range(p - k, p):
        _set_word(d, seg, q, g, _word(d, seg, q, g) & 0x7FFF)
    return True


@_compile
def _darray_push(d: Any, regs: Any, a: int, v: int, s: int, elems: int) -> bool:
    """``tables.darray_push`` on a well-formed darray. A push that needs a segment and
    finds no room writes nothing and returns False, as ``darray_push``'s ``HeapFull``
    (callers check the room first, or ignore the failure where ``lambda_alloc`` does)."""
    seg = _last_segment(d, a, s, elems)
    g = 4 * elems + 2
    n = 2 * elems
    p = 0
    while p < n and _word(d, seg, p, g) & 0x8000:
        p += 1
    if p == n:
        new = _seg_alloc(d, regs, elems)
        if new < 0:
            return False
        lm = _word(d, seg, n, g)
        _set_word(d, seg, n, g, (lm & ~_NO_NEXT) | (new & _NO_NEXT))
        seg = new
        p = 0
    _set_word(d, seg, p, g, v | 0x8000)
    return True


@_compile
def _darray_valid_count(d: Any, a: int, s: int, elems: int) -> int:
    """``len(tables.darray_elements(a))``; -1 when ``a`` is not a valid object or its
    chain leaves the heap, holds an invalid segment or is longer than the heap."""
    size = len(d)
    g = 4 * elems + 2
    n = 2 * elems
    if not 0 <= a < size // s or not _i(d[a * s]) & _VALID:
        return -1
    seg = _u16(d, a, s)
    count = 0
    for _ in range(size // g + 1):
        if (seg + 1) * g > size or not _word(d, seg, n, g) & 0x8000:
            return -1
        for p in range(n):
            if not _word(d, seg, p, g) & 0x8000:
                return count
            count += 1
        seg = _word(d, seg, n, g) & _NO_NEXT
        if seg == _NO_NEXT:
            return count
    return -1


@_compile
def _darray_tail(d: Any, a: int, s: int, elems: int) -> int:
    """Darray ``a`` read as ``darray_find``/``darray_size``/``darray_push`` read it, with no
    write: ``2 * count + 1`` when a push would need a new segment (every element of the
    chain valid), ``2 * count`` when it would fill the slot of the first invalid element
    (``darray_size`` unlinks what follows it); -1 when ``a`` is not a valid object in the
    heap, its chain leaves the heap, holds an invalid segment or is longer than the heap,
    or an element indexes past the heap (``darray_find`` reads each one's metadata)."""
    size = len(d)
    g = 4 * elems + 2
    n = 2 * elems
    nobj = size // s
    if not 0 <= a < nobj or not _i(d[a * s]) & _VALID:
        return -1
    seg = _u16(d, a, s)
    count = 0
    for _ in range(size // g + 1):
        if (seg + 1) * g > size or not _word(d, seg, n, g) & 0x8000:
            return -1
        for p in range(n):
            w = _word(d, seg, p, g)
            if not w & 0x8000:
                return 2 * count
            if (w & 0x7FFF) >= nobj:
                return -1
            count += 1
        seg = _word(d, seg, n, g) & _NO_NEXT
        if seg == _NO_NEXT:
            return 2 * count + 1
    return -1


@_compile
def _darray_find(d: Any, a: int, x: int, count: int, s: int, elems: int) -> int:
    """``tables.darray_find`` of object ``x`` in darray ``a`` of ``count`` elements (its
    chain checked by :func:`_darray_tail`): the first valid element comparing equal to
    ``x``, else ``count``."""
    g = 4 * elems + 2
    n = 2 * elems
    seg = _u16(d, a, s)
    for pos in range(count):
        if pos > 0 and pos % n == 0:
            seg = _word(d, seg, n, g) & _NO_NEXT
        e = _word(d, seg, pos % n, g) & 0x7FFF
        if _i(d[e * s]) & _VALID and _compare(d, e, x, s) == 0:
            return pos
    return count


@_compile
def _pushl(d: Any, regs: Any, lsyms: int, addr: int, s: int, elems: int,
           reserved: int) -> int:
    """``VM.op_pushl`` but the push: the lambda closure for bytecode address ``addr``, its
    index returned; -1, with nothing written, when Python must run it (a full heap, no
    free reserved slot for the activation record, a malformed function list or lsyms).

    The closure takes a slot, then the int holding ``addr``; the function list keeps the
    int unless an equal one is listed (then the int is freed); with ``lsyms`` set, a
    reserved slot becomes a darray copy of it (``lambda_alloc``), the closure's byte 2."""
    tail = _darray_tail(d, regs[R_FLIST], s, elems)
    if tail < 0:
        return -1
    slot = -1
    if lsyms != 0:
        if _darray_valid_count(d, lsyms, s, elems) < 0:
            return -1
        for i in range(reserved):
            if not _i(d[i * s]) & _VALID:
                slot = i
                break
        if slot < 0:
            return -1  # no reserved slot: MEM
    # the function list may need a segment (room asked even when the int will be found:
    # a too cautious refusal is only a step in Python); the record needs its first one,
    # its other pushes ignore a full heap as lambda_alloc does
    if not _room(d, regs, s, reserved, elems, 2, (tail & 1) + (1 if lsyms != 0 else 0)):
        return -1
    # ---- commit, in the order of VM.op_pushl
    flist = regs[R_FLIST]
    o = _obj_alloc(d, regs, s, reserved, _CLOSURE, 0)
    d[o * s] = _i(d[o * s]) | _FLAG1 | _FLAG2
    x = _obj_alloc(d, regs, s, reserved, _INT, 0)
    d[x * s + 1] = addr & 0xFF
    d[x * s + 2] = (addr >> 8) & 0xFF
    pos = _darray_find(d, flist, x, tail >> 1, s, elems)
    if pos == darray_size(d, flist, s, elems):
        _darray_push(d, regs, flist, x, s, elems)
    else:
        d[x * s] = _i(d[x * s]) & (0xFF ^ _VALID)
        _slot_freed(regs, x)
    d[o * s + 1] = pos & 0xFF
    if lsyms != 0:  # lambda_alloc(lsyms)
        m = _i(d[slot * s])
        d[slot * s] = ((m | _VALID) & (0xFF ^ 7) & (0xFF ^ _FLAG2)) | _TABLE | _FLAG1
        seg = _seg_alloc(d, regs, elems)
        d[slot * s + 1] = seg & 0xFF
        d[slot * s + 2] = (seg >> 8) & 0xFF
        count = darray_size(d, lsyms, s, elems)
        for k in range(count):
            e = darray_get(d, lsyms, k, s, elems)
            _darray_push(d, regs, slot, e if e >= 0 else 0, s, elems)
        d[o * s + 2] = slot
    return o


@_compile
def _callc(d: Any, stack: Any, regs: Any, sp: int, bp: int, lsyms: int, retpc: int,
           bsize: int, s: int, elems: int, reserved: int, host_ok: bool) -> int:
    """``VM.callc``'s happy path for a bytecode closure (native or lambda) — returns 1,
    ``regs`` gets the new sp, blockptr, lsyms and pc — or, when ``host_ok``, for a C
    closure that is not a lambda — returns 2 with everything done up to the host function
    call, the closure's index in ``R_HOST``. 0 with nothing written (but
    ``darray_size(flist)``'s idempotent unlinking) when Python must run it."""
    size = len(d)
    g = 4 * elems + 2
    n = 2 * elems
    nobj = size // s
    if sp < 0:
        return 0
    ai = _i(stack[sp])
    if ai >= nobj or _i(d[ai * s]) & 7 != _INT:
        return 0
    argn = _u16(d, ai, s)
    sp1 = sp - 1
    if sp1 < argn:
        return 0
    c = _i(stack[sp1 - argn])
    if c >= nobj or _i(d[c * s]) & 7 != _CLOSURE:
        return 0
    cm = _i(d[c * s])
    is_lambda = (cm & _FLAG2) != 0
    native = (cm & _FLAG1) != 0
    if not native and (is_lambda or not host_ok):
        return 0
    ref = _i(d[c * s + 1])
    actrec = _i(d[c * s + 2])
    flist = regs[R_FLIST]
    if is_lambda and ref >= darray_size(d, flist, s, elems):
        return 0  # FLIST error
    sp2 = sp1 - argn - 1
    if sp2 < 0:
        return 0
    own = not is_lambda or actrec == _NO_ACTREC
    src = regs[R_DFLT_ACTREC] if own else actrec
    if not own and actrec >= nobj:
        return 0
    m = _darray_valid_count(d, src, s, elems)
    if m < 0:
        return 0
    newpc = retpc
    if not native:
        pass  # the host function decides what follows
    elif is_lambda:
        fo = darray_get(d, flist, ref, s, elems)
        newpc = _u16(d, fo if fo >= 0 else 0, s)
    else:
        newpc = _u16(d, c, s)
    if newpc > bsize:
        return 0
    # every allocation below (table + segments, two ints) fits in the free gap
    if regs[R_LTSEG] - regs[R_RTOBJ] < 3 * s + (1 + (m + argn) // n) * g:
        return 0
    # ---- commit, in the order of VM.callc
    new = _obj_alloc(d, regs, s, reserved, _TABLE, 0)
    seg = _seg_alloc(d, regs, elems)
    d[new * s + 1] = seg & 0xFF
    d[new * s + 2] = seg >> 8
    d[new * s] = (_i(d[new * s]) | _FLAG1) & (0xFF ^ _FLAG2)
    seg = _u16(d, src, s)
    k = 0
    while k < m:
        _darray_push(d, regs, new, _word(d, seg, k % n, g) & 0x7FFF, s, elems)
        k += 1
        if k % n == 0:
            seg = _word(d, seg, n, g) & _NO_NEXT
    d[new * s] = _i(d[new * s]) | _PERMANENT
    for i in range(argn, 0, -1):
        _darray_push(d, regs, new, _i(stack[sp1 - (i - 1)]), s, elems)
    if own or not _i(d[actrec * s]) & _FLAG2:
        darray_set(d, new, 0, _i(stack[sp2]), s, elems)
    i1 = _obj_alloc(d, regs, s, reserved, _INT, 0)
    d[i1 * s + 1] = retpc & 0xFF
    d[i1 * s + 2] = (retpc >> 8) & 0xFF
    stack[sp2] = i1
    stack[sp2 + 1] = lsyms
    i2 = _obj_alloc(d, regs, s, reserved, _INT, 0)
    d[i2 * s + 1] = bp & 0xFF
    d[i2 * s + 2] = (bp >> 8) & 0xFF
    stack[sp2 + 2] = i2
    regs[R_SP] = sp2 + 2
    regs[R_BP] = sp2 + 2
    regs[R_LSYMS] = new
    regs[R_PC] = newpc
    if not native:
        regs[R_HOST] = c
        return 2
    return 1


@_compile
def _ret_ok(d: Any, stack: Any, with_value: bool, sp: int, bp: int, lsyms: int,
            bsize: int, s: int, elems: int) -> bool:
    """Would :func:`_ret` take its happy path? (Its checks alone: no side effect, so a
    compiled host function can ask before doing anything it could not hand back.)"""
    size = len(d)
    g = 4 * elems + 2
    nobj = size // s
    if sp + 1 < (4 if with_value else 3) or bp < 2 or bp > sp:
        return False
    bpobj = _i(stack[bp])
    back = _i(stack[bp - 2])
    if bpobj >= nobj or lsyms >= nobj or back >= nobj or _i(d[back * s]) & 7 != _INT:
        return False
    newpc = _u16(d, back, s)
    first = _u16(d, lsyms, s)
    return newpc <= bsize and (first + 1) * g <= size


@_compile
def _ret(d: Any, stack: Any, regs: Any, with_value: bool, sp: int, bp: int, lsyms: int,
         bsize: int, s: int, elems: int) -> bool:
    """``VM.ret0``/``ret1`` (+ ``op_ret*``'s pc check), their happy path: on success
    ``regs`` gets the new sp, blockptr, lsyms and pc; False with nothing written."""
    size = len(d)
    g = 4 * elems + 2
    if not _ret_ok(d, stack, with_value, sp, bp, lsyms, bsize, s, elems):
        return False
    bpobj = _i(stack[bp])
    newpc = _u16(d, _i(stack[bp - 2]), s)
    first = _u16(d, lsyms, s)
    value = _i(stack[sp]) if with_value else regs[R_NIL]
    # ---- commit (VM._unwind: unmake permanent, darray_destroy via segment_chain)
    d[lsyms * s] = _i(d[lsyms * s]) & (0xFF ^ _PERMANENT)
    seg = first
    limit = size // g
    length = 1
    while True:
        _set_word(d, seg, 2 * elems, g, _word(d, seg, 2 * elems, g) & 0x7FFF)
        nxt = _word(d, seg, 2 * elems, g) & _NO_NEXT
        if nxt == _NO_NEXT or (nxt + 1) * g > size or length > limit:
            break
        seg = nxt
        length += 1
    d[lsyms * s] = _i(d[lsyms * s]) & (0xFF ^ _VALID)
    _slot_freed(regs, lsyms)
    regs[R_LSYMS] = _i(stack[bp - 1])
    stack[bp - 2] = value
    regs[R_SP] = bp - 2
    regs[R_BP] = _s16(_u16(d, bpobj, s))
    regs[R_PC] = newpc
    return True


@_compile
def _is_leaf(m: int) -> bool:
    """Is an object of metadata ``m`` a leaf — anything but a table or a lambda closure —
    whose inside the marker never looks at?"""
    t = m & 7
    return t != _TABLE and (t != _CLOSURE or not m & _FLAG2)


@_compile
def _permanent_leaf(d: Any, x: int, nobj: int, s: int) -> bool:
    """Is ``x`` a leaf flagged permanent (nil): a root of its own, marked at every
    collection however many references to it are dropped?"""
    if not 0 <= x < nobj:
        return False
    m = _i(d[x * s])
    return _is_leaf(m) and (m & (_PERMANENT | _VALID)) == (_PERMANENT | _VALID)


@_compile
def _walked_from_permanent(info: Any, x: int, limit: int) -> bool:
    """Did the last collection first mark ``x`` from the permanent roots, at a depth whose
    children the marker visits (below the mark depth ``limit``)?"""
    first = _i(info[x])
    return (first & PERMANENT_PHASE) != 0 and (first & (PERMANENT_PHASE - 1)) < limit


@_compile
def _owned(info: Any, x: int) -> bool:
    """Is ``x`` a number whose one reference is a slot of a table walked from the permanent
    roots (:data:`OWNED`, new or not)?"""
    return (_i(info[x]) & (NEW - 1)) == OWNED


#: what a root an instruction dropped leaves behind (:func:`_dropped`): kept by the
#: permanent roots, a fresh temporary the skipped collection frees, or unknown
_DROP_KEPT, _DROP_FRESH, _DROP_UNKNOWN = 0, 1, 2


@_compile
def _dropped(info: Any, x: int, nobj: int) -> int:
    """How a dropped stack root ``x`` leaves the heap: :data:`_DROP_KEPT` when the last
    collection first marked it from the permanent roots (as a stack root it marked
    nothing), :data:`_DROP_FRESH` for a fresh temporary (nothing else reaches it), else
    :data:`_DROP_UNKNOWN` (a collection must tell)."""
    if x >= nobj or _owned(info, x):
        return _DROP_UNKNOWN  # (an OWNED number's one reference may be the one dropped)
    first = _i(info[x])
    if first == FRESH:
        return _DROP_FRESH
    return _DROP_KEPT if first & PERMANENT_PHASE else _DROP_UNKNOWN


@_compile
def _new_leaf_kept(d: Any, regs: Any, info: Any, x: int, s: int) -> bool:
    """After an instruction that pushed object ``x`` it allocated (``regs[R_PRIOR]``: the
    slot's mdata before): is the heap still a fixed point, but for the mark bit the next
    step sets (``pending``)? Yes for a leaf in a slot the last collection did not reach, or
    a deduplicated string (an old, marked object). Such a new leaf is also marked
    :data:`FRESH`; a fresh string that ``pushs`` deduplicated to has two references now,
    and is fresh no more."""
    prior = regs[R_PRIOR]
    if not _is_leaf(_i(d[x * s])):
        return False
    if prior & _VALID:
        if _i(info[x]) == FRESH:
            info[x] = 0
        return True
    if prior & _GC_MARK:
        return False
    info[x] = FRESH
    return True


@_compile
def _table_copy_kept(regs: Any, info: Any, copy: int, source: int, nobj: int,
                     limit: int) -> bool:
    """After a ``dup`` of the table ``source`` into the new object ``copy``: is the heap
    still a fixed point, but for the copy's mark bit (``pending``)? Yes when the source was
    first marked from the permanent roots at a depth whose segments the marker walked, and
    the copy's slot was not reached by the last collection: the copy shares the source's
    segments, all marked, so as a stack root it marks nothing else — and unreachable, the
    collector frees it alone (its first segment is marked), as a fresh leaf: it is marked
    :data:`FRESH`."""
    if source >= nobj or regs[R_PRIOR] & (_VALID | _GC_MARK) \
            or not _walked_from_permanent(info, source, limit):
        return False
    info[copy] = FRESH
    return True


@_compile
def _follow_push(info: Any, x: int, followed: Any) -> None:
    """After a push of the old object ``x``: ``run`` follows ``x`` (one of ``followed``'s
    :data:`OWNED_FOLLOWED` places, -1: free) when it is :data:`OWNED` (its slot's alone
    until now; when every place is taken, the number followed longest gives way and is
    followed no more), and stops following it when it did (on the stack twice now)."""
    for i in range(OWNED_FOLLOWED):
        if followed[i] == x:
            followed[i] = -1
            return
    if not _owned(info, x):
        return
    for i in range(OWNED_FOLLOWED):
        if followed[i] < 0:
            followed[i] = x
            return
    for i in range(OWNED_FOLLOWED - 1):
        followed[i] = followed[i + 1]
    followed[OWNED_FOLLOWED - 1] = x


@_compile
def _follow_drop(info: Any, followed: Any, top: int, below: int, two: bool) -> None:
    """An instruction dropped the stack top ``top`` (and ``below`` when ``two``): a followed
    number whose one stack slot that was is its slot's alone again, :data:`OWNED`."""
    for i in range(OWNED_FOLLOWED):
        x = followed[i]
        if x >= 0 and (x == top or (two and x == below)):
            info[x] = OWNED + (_i(info[x]) & NEW)
            followed[i] = -1


@_compile
def _old_kept(d: Any, info: Any, x: int, s: int) -> bool:
    """After an instruction that pushed the existing object ``x``: is the heap still a fixed
    point? Yes for a marked leaf (the marker never looks inside it), or a non-leaf the last
    collection first marked from the permanent roots (its stack root finds it marked)."""
    m = _i(d[x * s])
    if _owned(info, x):  # on the stack too now: not its slot's alone
        info[x] = 3 + PERMANENT_PHASE + (_i(info[x]) & NEW)
    if _is_leaf(m):
        return (m & _GC_MARK) != 0
    return (_i(info[x]) & PERMANENT_PHASE) != 0


@_compile
def _stored_leaf_kept(d: Any, regs: Any, info: Any, v: int, lsyms: int, nobj: int, s: int,
                      limit: int) -> bool:
    """After an ``lstore`` that moved the stack top ``v`` into a new local (no old value
    dropped): is the heap still a fixed point? Yes when ``v`` is a leaf and the activation
    record was first marked from the permanent roots at a depth whose words the marker
    visits: ``v``, marked already, is then marked from the permanent roots instead of its
    stack slot, one level below the record — which ``info`` now says (a fresh leaf is
    fresh no more, but still :data:`NEW`, and a fresh number is the local's alone,
    :data:`OWNED_NEW`; an old object's rewritten ``info`` is noted in ``R_OLD_CHANGED``)."""
    if v >= nobj or lsyms >= nobj:
        return False
    m = _i(d[v * s])
    if not _is_leaf(m) or not m & _GC_MARK or not _walked_from_permanent(info, lsyms, limit):
        return False
    first = _i(info[v])
    if first == FRESH and (m & 7 == _INT or m & 7 == _FLOAT):
        info[v] = OWNED_NEW  # its stack slot was its one reference: the local's now
    elif not first & PERMANENT_PHASE:
        depth = (_i(info[lsyms]) & (PERMANENT_PHASE - 1)) + 1
        if first <= FRESH or first & NEW:
            info[v] = depth + PERMANENT_PHASE + NEW
        else:
            info[v] = depth + PERMANENT_PHASE
            regs[R_OLD_CHANGED] = 1
    return True


@_compile
def _leaf_stored_kept(d: Any, regs: Any, info: Any, table: int, v: int, old: int, nobj: int,
                      s: int, limit: int) -> int:
    """After a store that replaced the value ``old`` of a slot of ``table`` (the globals' or
    any table) by the stack top ``v``: is the heap still a fixed point, but for ``old``
    the skipped collection frees? -2 when a collection must tell, else the object to free
    (-1: none). Yes when ``v`` is a marked leaf (not nil: storing nil deletes the slot),
    ``table`` is walked from the permanent roots (so it stays reached, and so does ``v``,
    one level below it), and ``old`` is ``v``, a permanent leaf (nil) or :data:`OWNED`
    (then unreachable now). A fresh int or float ``v`` becomes :data:`OWNED`; any other
    ``v`` not yet permanent-reached is said to be, one level below ``table``. ``table``
    changed: ``R_OLD_CHANGED``. The caller has judged the roots the store dropped."""
    m = _i(d[v * s])
    kind = m & 7
    if not _is_leaf(m) or not m & _GC_MARK or kind == _NIL \
            or not _walked_from_permanent(info, table, limit):
        return -2
    free = -1
    if old != v and not _permanent_leaf(d, old, nobj, s):
        if not _owned(info, old):
            return -2
        free = old
    first = _i(info[v])
    if first == FRESH and (kind == _INT or kind == _FLOAT):
        info[v] = OWNED
    elif first == FRESH or not first & PERMANENT_PHASE:
        info[v] = (_i(info[table]) & (PERMANENT_PHASE - 1)) + 1 + PERMANENT_PHASE
    regs[R_OLD_CHANGED] = 1
    return free


@_compile
def _stored_global_kept(d: Any, regs: Any, info: Any, v: int, k: int, old: int,
                        gsyms: int, nobj: int, s: int, limit: int) -> int:
    """After a ``gstore`` that replaced global ``k``'s value ``old`` by the stack top
    ``v`` (``old`` -1: a new global): is the heap still a fixed point, but for ``old``
    the skipped collection frees? -2 when a collection must tell, else the object to free
    (-1: none). Yes when the global was there, its name is kept by the permanent roots or
    a fresh string (the table keeps its own key for a global it had: the caller frees the
    name), and the store itself is, into the globals' table (:func:`_leaf_stored_kept`)."""
    if old < 0 or old >= nobj or v >= nobj or _dropped(info, k, nobj) == _DROP_UNKNOWN:
        return -2
    return _leaf_stored_kept(d, regs, info, gsyms, v, old, nobj, s, limit)


@_compile
def _stored_in_table_kept(d: Any, regs: Any, info: Any, t: int, k: int, v: int, old: int,
                          nobj: int, s: int, limit: int) -> tuple[int, int]:
    """After a ``tput`` that replaced table ``t``'s value ``old`` under the key ``k`` by the
    stack top ``v`` (``old`` -1: a new key): is the heap still a fixed point, but for the
    objects the skipped collection frees? (-2, -1) when a collection must tell, else those
    objects (-1: none). Yes when the key was there (nothing allocated, the table keeps its
    own key object), the dropped key ``k`` is kept by the permanent roots (a local of a
    frame, as ``rid`` of ``t[rid] = v``) or a fresh temporary (freed), ``t`` was dropped
    as a root the permanent roots keep (it is walked from them), and the store itself is
    (:func:`_leaf_stored_kept`)."""
    if old < 0 or old >= nobj or v >= nobj or k >= nobj or t >= nobj:
        return -2, -1
    key = _dropped(info, k, nobj)
    if key == _DROP_UNKNOWN or (key == _DROP_FRESH and k == v):
        return -2, -1
    free_old = _leaf_stored_kept(d, regs, info, t, v, old, nobj, s, limit)
    if free_old == -2:
        return -2, -1
    return free_old, k if key == _DROP_FRESH else -1


@_compile
def _table_of_leaves(d: Any, t: int, s: int, elems: int) -> bool:
    """Does table ``t`` hold valid leaves only, in segments inside the heap? Reached at
    depth 3, it then marks only leaves, at depth 4."""
    size = len(d)
    g = 4 * elems + 2
    n = 2 * elems
    nobj = size // s
    seg = _u16(d, t, s)
    for _ in range(size // g + 1):
        if (seg + 1) * g > size:
            return False
        for p in range(n):
            w = _word(d, seg, p, g)
            if w & 0x8000:
                y = w & 0x7FFF
                if y >= nobj:
                    return False
                m = _i(d[y * s])
                if not m & _VALID or not _is_leaf(m):
                    return False
        seg = _word(d, seg, n, g) & _NO_NEXT
        if seg == _NO_NEXT:
            return True
    return False


@_compile
def _mark_as_reached(d: Any, info: Any, y: int, depth: int, s: int) -> bool:
    """Leaf ``y`` reached from a new frame at ``depth``: marked if it was not (a new
    object, ``info`` as the collector would first set it, plus :data:`NEW`); a fresh
    temporary the frame now holds is fresh no more. A leaf the last collection reached
    from the stack only (a walk's accumulator) is now reached from the permanent roots,
    which its ``info`` then says, as the collection would; an :data:`OWNED` number has a
    second reference now, and is a plain leaf. True when that rewrote an old object's
    ``info`` (``R_OLD_CHANGED``)."""
    m = _i(d[y * s])
    if not m & _GC_MARK:
        d[y * s] = m | _GC_MARK
        info[y] = depth + PERMANENT_PHASE + NEW
        return False
    first = _i(info[y])
    if _owned(info, y):  # a second reference
        info[y] = depth + PERMANENT_PHASE + (first & NEW)
        return not first & NEW
    if first & PERMANENT_PHASE:
        return False
    if first <= FRESH or first & NEW:
        info[y] = depth + PERMANENT_PHASE + NEW
        return False
    info[y] = depth + PERMANENT_PHASE
    return True


@_compile
def _mark_new_table(d: Any, info: Any, t: int, s: int, elems: int) -> bool:
    """A new table of leaves (:func:`_table_of_leaves`) reached from a new frame:
    marked at depth 3, its segments and its keys and values (depth 4) as well; True when
    an old leaf's ``info`` was rewritten (:func:`_mark_as_reached`)."""
    g = 4 * elems + 2
    n = 2 * elems
    d[t * s] = _i(d[t * s]) | _GC_MARK
    info[t] = 3 + PERMANENT_PHASE + NEW
    seg = _u16(d, t, s)
    changed = False
    while True:
        _set_word(d, seg, n, g, _word(d, seg, n, g) | 0x4000)  # SEG_MARK
        for p in range(n):
            w = _word(d, seg, p, g)
            if w & 0x8000 and _mark_as_reached(d, info, w & 0x7FFF, 4, s):
                changed = True
        seg = _word(d, seg, n, g) & _NO_NEXT
        if seg == _NO_NEXT:
            return changed


@_compile
def _entered_on_fixed_heap(d: Any, stack: Any, regs: Any, info: Any, count: int,
                           closure: int, self_obj: int, s: int, elems: int,
                           limit: int) -> bool:
    """After ``closure_call``'s ``callc`` on a heap its caller vouches for
    (:data:`CALL_ON_FIXED_HEAP`, ``count`` the argument count it pushed): is the heap a
    fixed point of the collector but for the frame the call made, so that the collection
    that follows can be replaced by its effect? Yes when no allocation since took a slot the
    last collection reached (``R_REACHED``), the dropped closure and ``self`` are kept by the
    permanent roots (``self`` may also be the frame's first local), and every local of the
    new activation record is a valid leaf: the record, a new permanent root marked at depth
    2, then marks only leaves, so no other object's marking changes. A local may also be a
    table that holds leaves only: one the caller just made (the neighbour's data table of a
    walk), or an old one the last collection walked from the permanent roots (the
    ``neighbors`` table, a walk's ``self``). Reached from the record at depth 3, such an
    old table marks the leaves it marked before, so the marks stay as they are; which
    permanent root reaches it first may change, and with it the depth ``info`` gives it
    and its leaves, but a depth only decides whether the marker looks inside a table
    (below the mark depth: true either way), so ``info`` keeps the last collection's
    depths. The effect is then
    done here: the record, its segments and its new locals marked (``info`` as the
    collector would first set it, plus :data:`NEW`), the return address and block pointer
    ints marked as stack roots; the count, unreachable, is the caller's to free
    (``_free_dropped``). False with nothing written otherwise."""
    size = len(d)
    g = 4 * elems + 2
    n = 2 * elems
    nobj = size // s
    sp = regs[R_SP]
    frame = regs[R_LSYMS]
    if regs[R_REACHED] or limit < 3 or sp < 2 or count >= nobj \
            or _i(d[count * s]) & (_VALID | _GC_MARK) != _VALID:
        return False
    if _dropped(info, closure, nobj) != _DROP_KEPT:
        return False
    if _dropped(info, self_obj, nobj) != _DROP_KEPT \
            and darray_get(d, frame, 0, s, elems) != self_obj:
        return False
    # ---- the checks: every local a valid leaf, every segment inside the heap
    first = _u16(d, frame, s)
    seg = first
    for _ in range(size // g + 1):
        if (seg + 1) * g > size:
            return False
        for p in range(n):
            w = _word(d, seg, p, g)
            if w & 0x8000:
                y = w & 0x7FFF
                if y >= nobj:
                    return False
                m = _i(d[y * s])
                if not m & _VALID:
                    return False
                if not _is_leaf(m) and (
                        m & 7 != _TABLE or limit < 4 or not _table_of_leaves(d, y, s, elems)
                        or (m & _GC_MARK and not _walked_from_permanent(info, y, limit))):
                    return False
        seg = _word(d, seg, n, g) & _NO_NEXT
        if seg == _NO_NEXT:
            break
    else:
        return False
    for k in range(3):  # the return address, the caller's record, the block pointer
        x = _i(stack[sp - k])
        if x >= nobj or (k == 1 and not _i(d[x * s]) & _GC_MARK):
            return False
    # ---- the collection's effect
    d[frame * s] = _i(d[frame * s]) | _GC_MARK
    info[frame] = 2 + PERMANENT_PHASE + NEW
    seg = first
    while True:
        _set_word(d, seg, n, g, _word(d, seg, n, g) | 0x4000)  # SEG_MARK
        for p in range(n):
            w = _word(d, seg, p, g)
            if w & 0x8000:
                y = w & 0x7FFF
                if _i(d[y * s]) & 7 == _TABLE and not _i(d[y * s]) & _GC_MARK:
                    changed = _mark_new_table(d, info, y, s, elems)
                else:
                    changed = _mark_as_reached(d, info, y, 3, s)
                if changed:
                    regs[R_OLD_CHANGED] = 1
        seg = _word(d, seg, n, g) & _NO_NEXT
        if seg == _NO_NEXT:
            break
    for k in (0, 2):
        x = _i(stack[sp - k])
        m = _i(d[x * s])
        if not m & _GC_MARK:
            d[x * s] = m | _GC_MARK
            info[x] = 2 + NEW
    return True


@_compile
def host_frame_droppable(d: Any, info: Any, count: int, closure: int, frame: int, s: int,
                         elems: int) -> bool:
    """After a ``callc`` of a C closure set up on a fixed point (the step's collection or
    its skip) whose allocations took no slot the last collection reached
    (``R_HOST_COUNT``): once the host function has returned, will the heap be that fixed
    point but for objects the next collection frees? Yes when every root the call dropped
    — the closure, the argument count and the frame's locals (``self``, the arguments, the
    default record's copies) — is kept by the permanent roots or is a fresh temporary
    (each met once)."""
    size = len(d)
    g = 4 * elems + 2
    n = 2 * elems
    nobj = size // s
    if count >= nobj or closure >= nobj or frame >= nobj:
        return False
    a = _dropped(info, count, nobj)
    b = _dropped(info, closure, nobj)
    if a == _DROP_UNKNOWN or b == _DROP_UNKNOWN or (a == b == _DROP_FRESH and count == closure):
        return False
    seg = _u16(d, frame, s)
    for _ in range(size // g + 1):
        if (seg + 1) * g > size:
            return False
        for p in range(n):
            w = _word(d, seg, p, g)
            if not w & 0x8000:
                continue
            y = w & 0x7FFF
            kind = _dropped(info, y, nobj)
            if kind == _DROP_UNKNOWN:
                return False
            if kind == _DROP_FRESH and (y == count or y == closure):
                return False
        seg = _word(d, seg, n, g) & _NO_NEXT
        if seg == _NO_NEXT:
            break
    else:
        return False
    # a fresh local met twice (one temporary passed as two arguments) is not fresh
    seg = _u16(d, frame, s)
    while True:
        for p in range(n):
            w = _word(d, seg, p, g)
            if w & 0x8000 and _i(info[w & 0x7FFF]) == FRESH:
                if _fresh_met_again(d, frame, w & 0x7FFF, seg, p, s, elems):
                    return False
        seg = _word(d, seg, n, g) & _NO_NEXT
        if seg == _NO_NEXT:
            return True


@_compile
def _fresh_met_again(d: Any, frame: int, y: int, at_seg: int, at_word: int, s: int,
                     elems: int) -> bool:
    """Does the frame hold ``y`` in a word after (segment ``at_seg``, word ``at_word``)?"""
    g = 4 * elems + 2
    n = 2 * elems
    seg = at_seg
    p = at_word + 1
    while True:
        while p < n:
            w = _word(d, seg, p, g)
            if w & 0x8000 and w & 0x7FFF == y:
                return True
            p += 1
        seg = _word(d, seg, n, g) & _NO_NEXT
        if seg == _NO_NEXT:
            return False
        p = 0


@_compile
def end_host_frame(d: Any, regs: Any, info: Any, count: int, closure: int, frame: int,
                   return_pc: int, block: int, s: int, elems: int, reserved: int) -> None:
    """The collection after a compiled host function's ``ret0`` when
    :func:`host_frame_droppable` said yes: the fresh temporaries the call dropped (count,
    closure, locals), the return address and block pointer ints freed, the marks the
    returned frame's segments kept cleared, both ends of the heap retreated
    (``fastgc.collect_with``'s steps 1, 4, 5 and 6 for them)."""
    size = len(d)
    g = 4 * elems + 2
    n = 2 * elems
    seg = _u16(d, frame, s)
    for _ in range(size // g + 1):
        if (seg + 1) * g > size:
            break
        for p in range(n):
            w = _word(d, seg, p, g)
            if w & 0x8000 and _i(info[w & 0x7FFF]) == FRESH:
                _free_object(d, regs, info, w & 0x7FFF, s)
        w = _word(d, seg, n, g)
        _set_word(d, seg, n, g, w & (0xFFFF ^ 0x4000))
        seg = w & _NO_NEXT
        if seg == _NO_NEXT:
            break
    for x in (count, closure):
        if _i(info[x]) == FRESH:
            _free_object(d, regs, info, x, s)
    _free_object(d, regs, info, return_pc, s)
    _free_object(d, regs, info, block, s)
    _free_object(d, regs, info, frame, s)
    _retreat(d, regs, s, elems, reserved)


@_compile
def _free_object(d: Any, regs: Any, info: Any, x: int, s: int) -> None:
    """The sweep's effect on an unreached object: mark and validity cleared, no ``info``."""
    d[x * s] = _i(d[x * s]) & (0xFF ^ (_VALID | _GC_MARK))
    info[x] = 0
    _slot_freed(regs, x)


@_compile
def _retreat_objects(d: Any, regs: Any, s: int, reserved: int) -> None:
    """The collector's step 5: the object end retreats over invalid slots."""
    rtobj = regs[R_RTOBJ]
    low = reserved * s
    while rtobj > low and not _i(d[rtobj - s]) & _VALID:
        rtobj -= s
    regs[R_RTOBJ] = rtobj


@_compile
def _retreat(d: Any, regs: Any, s: int, elems: int, reserved: int) -> None:
    """The collector's last steps: both heap ends retreat over invalid slots."""
    size = len(d)
    g = 4 * elems + 2
    _retreat_objects(d, regs, s, reserved)
    ltseg = regs[R_LTSEG]
    while ltseg < size and not _i(d[ltseg + 4 * elems + 1]) & 0x80:  # SEG_VALID
        ltseg += g
    regs[R_LTSEG] = ltseg


@_compile
def _clear_segment_flags(d: Any, seg: int, flags: int, elems: int) -> None:
    """Clear ``flags`` (of SEG_VALID 0x8000, SEG_MARK 0x4000) in every segment of the chain
    from ``seg``, as far as it stays inside the heap."""
    size = len(d)
    g = 4 * elems + 2
    n = 2 * elems
    for _ in range(size // g + 1):
        if (seg + 1) * g > size:
            return
        w = _word(d, seg, n, g)
        _set_word(d, seg, n, g, w & (0xFFFF ^ flags))
        seg = w & _NO_NEXT
        if seg == _NO_NEXT:
            return


@_compile
def undo_to_fixed_point(d: Any, regs: Any, info: Any, s: int, elems: int,
                        reserved: int) -> None:
    """The collection that ends a call begun with :data:`CALL_ON_FIXED_HEAP`, when since
    that fixed point no collection ran, no skip rule rewrote an old object's ``info``
    (``R_OLD_CHANGED`` clear) and no allocation took a reached slot (``R_REACHED`` clear):
    with the call's frame returned and its stack popped, nothing reaches the objects
    allocated since (only that frame and stack did: the skip rules store nowhere else),
    and the old ones are reached as they were. So the collection frees exactly the new
    ones — a valid object whose ``info`` is 0, :data:`FRESH` or has :data:`NEW` — clears
    the marks the returned record and its segments kept, and retreats both ends of the
    heap (``fastgc.collect_with``'s steps 1, 4, 5 and 6 for them)."""
    _free_new_objects(d, regs, info, s, elems, reserved, -1, -1, -1, -1, -1)


@_compile
def _free_new_objects(d: Any, regs: Any, info: Any, s: int, elems: int, reserved: int,
                      kept_a: int, kept_b: int, kept_c: int, old_a: int, old_b: int) -> None:
    """The return to a fixed point: every valid object made since (``info`` 0,
    :data:`FRESH` or with :data:`NEW`) freed but ``kept_a``, ``kept_b`` and ``kept_c``, and
    the old ``old_a`` and ``old_b`` freed too (-1: none); the marks of the returned records
    cleared; both heap ends retreat."""
    for i in range(regs[R_RTOBJ] // s):
        if i == kept_a or i == kept_b or i == kept_c:
            continue
        first = _i(info[i])
        if first > FRESH and not first & NEW and i != old_a and i != old_b:
            continue  # an old object, or a free slot the marker reached: as they were
        m = _i(d[i * s])
        if m & _VALID:
            if m & 7 == _TABLE and first & NEW:
                # a table the caller made for the call (a walk's data table, marked with
                # its segments by _mark_new_table): its segments are its own, freed with it
                _clear_segment_flags(d, _u16(d, i, s), 0xC000, elems)  # SEG_VALID, SEG_MARK
            _free_object(d, regs, info, i, s)
        elif m & _GC_MARK:
            _unmark_returned_record(d, info, i, s, elems)
    _retreat(d, regs, s, elems, reserved)


@_compile
def _unmark_returned_record(d: Any, info: Any, x: int, s: int, elems: int) -> None:
    """An activation record its return freed, marked by the last collection or by a call's
    entry: its mark, ``info`` and its segments' marks (the return freed them, marks kept)
    cleared, as a collection's step 1 clears them."""
    m = _i(d[x * s])
    d[x * s] = m & (0xFF ^ _GC_MARK)
    info[x] = 0
    if m & 7 == _TABLE:
        _clear_segment_flags(d, _u16(d, x, s), 0x4000, elems)  # SEG_MARK


@_compile
def _undo_to_element_start(d: Any, stack: Any, regs: Any, info: Any, sp: int, s: int,
                           elems: int, reserved: int) -> None:
    """The collection that begins a walk's element call (:data:`CALL_IN_WALK`), once
    ``callc`` made its frame and :func:`_entered_on_fixed_heap` marked it: since the
    previous element's first collection nothing it made was stored where it outlives it, so
    that collection's heap, the new frame (record, return address, block pointer) and its
    marks are what this one leaves. Freed: every object made since (``info`` 0,
    :data:`FRESH` or :data:`NEW`: the previous element's temporaries, locals and, when that
    element began this way, its return address and block pointer; the argument count just
    pushed) but the new frame's, the previous element's return-address and block-pointer
    ints (``R_LEFT_RET``, ``R_LEFT_BP``: old when its entry collected), the marks its
    returned record kept (cleared before this element's allocations: ``fasthost.table_walk``);
    then both heap ends retreat (``fastgc.collect_with``'s steps 1, 4, 5 and 6 for them)."""
    _free_new_objects(d, regs, info, s, elems, reserved, regs[R_LSYMS], _i(stack[sp - 2]),
                      _i(stack[sp]), regs[R_LEFT_RET], regs[R_LEFT_BP])


@_compile
def forget_left_frame(d: Any, regs: Any, info: Any, s: int, elems: int) -> None:
    """Before a walk's next element allocates anything: the previous element's record,
    freed by its return, loses the marks its first collection gave it (its slot and
    segments, which the next frame takes first, are then no reached free slots:
    ``R_REACHED``). No collection reads a mark it did not write, and nothing observes the
    heap before the next element's first collection."""
    frame = regs[R_LEFT_FRAME]
    if frame > 0 and not _i(d[frame * s]) & _VALID:
        _unmark_returned_record(d, info, frame, s, elems)


@_compile
def _free_dropped(d: Any, regs: Any, info: Any, a: int, b: int, s: int,
                  reserved: int) -> None:
    """A skipped collection's effect on the fresh leaves ``a`` and ``b`` (-1: none) the
    last instruction dropped: unreached, they lose their mark and validity, and the object
    end retreats over invalid slots (``fastgc.collect_with``'s steps 1, 4 and 5 for them)."""
    _free_object(d, regs, info, a, s)
    if b >= 0:
        _free_object(d, regs, info, b, s)
    _retreat_objects(d, regs, s, reserved)


@_compile_owning
def run(d: Any, stack: Any, bcode: Any, regs: Any, info: Any, traversed: Any,
        rules: Any, s: int, elems: int, reserved: int) -> int:
    """Run steps (collection or skip, then one instruction) from ``regs[R_PC]``.

    Returns :data:`EXIT`, :data:`NEED_PYTHON` (collection done, instruction not run) or
    :data:`BUDGET`; ``regs`` then holds the VM's registers.
    """
    size = len(d)
    g = 4 * elems + 2
    nobj = size // s
    bsize = len(bcode)
    nil = regs[R_NIL]
    gsyms = regs[R_GSYMS]
    saved = regs[R_SAVED]
    budget = regs[R_BUDGET]
    float_ops = regs[R_FLOAT_OPS] != 0
    stack_size = regs[R_STACK_SIZE]
    limit = regs[R_MARK_DEPTH]
    lsyms = regs[R_LSYMS]
    pc = regs[R_PC]
    sp = regs[R_SP]
    bp = regs[R_BP]
    n = regs[R_N]
    fixed = regs[R_FIXED] != 0
    pending = regs[R_PENDING]
    # the collector's mark stack (rows 0-3, reused), and the OWNED numbers run follows
    frames = np.empty((5, max(limit + 2, OWNED_FOLLOWED)), np.int64)
    followed = frames[4]
    followed[:] = -1
    # fresh leaves the last instruction dropped (-1: none): the skipped collection frees them
    free_a = -1
    free_b = -1
    entry = regs[R_CALL_FIRST]
    # a walk's element: its first collection (or the return that replaces it) is the fixed
    # point the next element's entry returns to
    track_from_first = entry == CALL_IN_WALK
    if entry:
        # closure_call: its callc (pc pushed as is, no collection, not an instruction)
        regs[R_CALL_FIRST] = 0
        count = _i(stack[sp]) if sp >= 0 else nobj
        closure = nobj
        self_obj = nobj
        if entry != CALL and count < nobj:
            argn = _u16(d, count, s)
            if sp - 2 - argn >= 0:
                closure = _i(stack[sp - 1 - argn])
                self_obj = _i(stack[sp - 2 - argn])
        if _callc(d, stack, regs, sp, bp, lsyms, pc, bsize, s, elems, reserved, False) == 0:
            return CALL_IN_PYTHON
        sp = regs[R_SP]
        bp = regs[R_BP]
        lsyms = regs[R_LSYMS]
        pc = regs[R_PC]
        if entry == CALL_IN_WALK:
            if (regs[R_LEFT_FRAME] > 0 and closure < nobj and regs[R_OLD_CHANGED] == 0
                    and not regs[R_UNSETTLED]
                    and _entered_on_fixed_heap(d, stack, regs, info, count, closure,
                                               self_obj, s, elems, limit)):
                _undo_to_element_start(d, stack, regs, info, sp, s, elems, reserved)
                fixed = True
            regs[R_LEFT_FRAME] = lsyms
            regs[R_LEFT_RET] = _i(stack[sp - 2])
            regs[R_LEFT_BP] = _i(stack[sp])
        elif closure < nobj and _entered_on_fixed_heap(d, stack, regs, info, count, closure,
                                                       self_obj, s, elems, limit):
            fixed = True
            free_a = count
    status = EXIT
    slice_left = SLICE_STEPS
    # the last lstore made a new local, or replaced a permanent leaf (nil: the compiler's
    # ``pushnil; lstore`` declares a local), so no value it dropped can become unreachable
    new_local = False
    replaced = -1  # the value the last gstore or tput replaced (-1: a new global or key)
    stored_in = -1  # the table of the last tput
    removed_a = -2  # the values of the locals the last lremove took (-1: none, -2: unknown)
    removed_b = -2
    # a fresh number the last gstore (tput) moved into a global (a table's slot) whose old
    # value a collection must judge: that collection leaves it referenced by that slot
    # alone, so OWNED (when it marks it from the permanent roots)
    owned_next = -1
    # ``followed``: OWNED numbers pushed on the stack, once each (-1: none): while nothing
    # but that stack slot and its own slot refers to one, an instruction that drops the
    # stack slot makes it its slot's alone again, OWNED (how ``x = x + 1`` keeps x's number
    # OWNED; _follow_push, _follow_drop)
    while saved == NONE or saved < bp:
        # ---- the collection before the instruction (or its provably changeless skip)
        regs[R_GC_RUNS] += 1
        if fixed:
            if pending >= 0:
                d[pending] |= _GC_MARK
            if free_a >= 0:
                _free_dropped(d, regs, info, free_a, free_b, s, reserved)
        else:
            take_collection(regs, collect_with(
                d, stack, sp, regs[R_RTOBJ], regs[R_LTSEG], info, traversed, frames, size, s,
                g, elems, reserved, limit))
            regs[R_OLD_CHANGED] = 1
            if owned_next >= 0 and _i(info[owned_next]) & PERMANENT_PHASE:
                info[owned_next] = OWNED  # the collection changed no reference to it
            followed[:] = -1
        if track_from_first:
            track_from_first = False
            regs[R_OLD_CHANGED] = 0
            regs[R_REACHED] = 0
        owned_next = -1
        fixed = False
        pending = -1
        free_a = -1
        free_b = -1
        # ---- one instruction, or back to Python (nothing of it done yet)
        status = NEED_PYTHON
        if pc >= bsize:
            break
        op = _i(bcode[pc])
        nxt_pc = pc + 1
        # the roots an instruction may pop (for _REPLACED_TOP and _POPPED_TWO_NEW)
        top_before = _i(stack[sp]) if sp >= 0 else nobj
        below_before = _i(stack[sp - 1]) if sp >= 1 else nobj
        arg = 0
        if op >= 35:
            if op > 46 or pc + 3 > bsize:
                break
            arg = _i(bcode[pc + 1]) | (_i(bcode[pc + 2]) << 8)
            nxt_pc = pc + 3
        if op == 0 or op == 34:  # nop, calls
            pass
        elif op == 2:  # pushnil
            if sp + 1 >= stack_size:
                break
            sp += 1
            stack[sp] = nil
        elif op == 4:  # pop
            if sp < 0:
                break
            sp -= 1
        elif op == 3:  # dup
            if not 0 < sp + 1 < stack_size:
                break
            src = _i(stack[sp])
            if src >= nobj:
                break
            idx = _obj_alloc(d, regs, s, reserved, _USERDATA, 0)
            if idx < 0:
                break
            for j in range(s):
                d[idx * s + j] = d[src * s + j]
            d[idx * s] = (_i(d[idx * s]) | _VALID) & (0xFF ^ _PERMANENT)
            sp += 1
            stack[sp] = idx
        elif 7 <= op <= 12:  # add sub mul div mod pow
            if sp < 1:
                break
            rhs = _i(stack[sp])
            lhs = _i(stack[sp - 1])
            if lhs >= nobj or rhs >= nobj:
                break
            tl = _i(d[lhs * s]) & 7
            tr = _i(d[rhs * s]) & 7
            result_type = _INT
            if float_ops and (tl != _INT or tr != _INT):
                # float arithmetic; Python keeps pow and operands of other types (MATH)
                if op == 12 or (tl != _INT and tl != _FLOAT) or (tr != _INT and tr != _FLOAT):
                    break
                res = _float_arith(op, tl, _u16(d, lhs, s), tr, _u16(d, rhs, s))
                if res < 0:
                    break
                result_type = _FLOAT
            else:
                if tl == _FLOAT or tr == _FLOAT:  # a build without float operations: TYPE
                    break
                a = _s16(_u16(d, lhs, s))
                b = _s16(_u16(d, rhs, s))
                if op == 7:
                    res = a + b
                elif op == 8:
                    res = a - b
                elif op == 9:
                    res = a * b
                elif op == 10 or op == 11:
                    if b == 0:
                        break
                    q = abs(a) // abs(b)
                    if (a < 0) != (b < 0):
                        q = -q
                    res = q if op == 10 else a - q * b
                else:
                    if b >= 0:
                        res = 1
                        for _ in range(b):
                            res = (res * a) & 0xFFFFFFFF
                            if res & 0x80000000:
                                res -= 0x100000000
                    elif a == 1:
                        res = 1
                    elif a == -1:
                        res = -1
                    else:
                        break
            idx = _obj_alloc(d, regs, s, reserved, result_type, 0)
            if idx < 0:
                break
            d[idx * s + 1] = res & 0xFF
            d[idx * s + 2] = (res >> 8) & 0xFF
            sp -= 1
            stack[sp] = idx
        elif op == 13 or op == 16 or op == 19:  # unm, lnot, bnot
            if sp < 0:
                break
            o = _i(stack[sp])
            if o >= nobj:
                break
            t = _i(d[o * s]) & 7
            u = _u16(d, o, s)
            result_type = _INT
            if op == 13:
                if t == _FLOAT:  # bbzfloat.negate, whatever the build
                    res = u ^ 0x8000
                    result_type = _FLOAT
                elif t != _INT:
                    break
                else:
                    res = -_s16(u)
            elif t != _NIL and t != _INT:
                break
            elif op == 16:
                res = 1 if u != 0 else 0
            else:
                res = ~u
            idx = _obj_alloc(d, regs, s, reserved, result_type, 0)
            if idx < 0:
                break
            d[idx * s + 1] = res & 0xFF
            d[idx * s + 2] = (res >> 8) & 0xFF
            stack[sp] = idx
        elif op == 14 or op == 15 or op == 17 or op == 18 or 22 <= op <= 27:
            if sp < 1:
                break
            rhs = _i(stack[sp])
            lhs = _i(stack[sp - 1])
            if lhs >= nobj or rhs >= nobj:
                break
            if op <= 18:  # land lor band bor: int truth of both sides
                ta = 1 if _true(d, lhs, s) else 0
                tb = 1 if _true(d, rhs, s) else 0
                res = (ta & tb) if (op == 14 or op == 17) else (ta | tb)
            else:
                c = _compare(d, lhs, rhs, s)
                if op == 22:
                    res = 1 if c == 0 else 0
                elif op == 23:
                    res = 1 if c != 0 else 0
                elif op == 24:
                    res = 1 if c > 0 else 0
                elif op == 25:
                    res = 1 if c >= 0 else 0
                elif op == 26:
                    res = 1 if c < 0 else 0
                else:
                    res = 1 if c <= 0 else 0
            idx = _obj_alloc(d, regs, s, reserved, _INT, 0)
            if idx < 0:
                break
            d[idx * s + 1] = res
            d[idx * s + 2] = 0
            sp -= 1
            stack[sp] = idx
        elif op == 28:  # gload
            if sp < 0:
                break
            o = _i(stack[sp])
            if o >= nobj or (_i(d[o * s]) & 7) != _STRING:
                break
            v = table_lookup(d, gsyms, o, s, elems)
            stack[sp] = nil if v < 0 else v
        elif op == 29:  # gstore
            if sp < 1:
                break
            o = _i(stack[sp - 1])
            v = _i(stack[sp])
            if o >= nobj or v >= nobj or (_i(d[o * s]) & 7) != _STRING:
                break
            replaced = table_lookup(d, gsyms, o, s, elems)
            if not _table_set(d, regs, gsyms, o, v, s, elems):
                break
            sp -= 2
        elif op == 31:  # tput
            if sp < 2:
                break
            v = _i(stack[sp])
            k = _i(stack[sp - 1])
            t = _i(stack[sp - 2])
            if t >= nobj or k >= nobj or v >= nobj or (_i(d[t * s]) & 7) != _TABLE:
                break
            m = _i(d[v * s])
            if m & 7 == _CLOSURE and m & _FLAG2:
                ar = _i(d[v * s + 2])
                if ar != _NO_ACTREC and not _i(d[ar * s]) & _FLAG2:
                    break  # a method to bind (VM._bind_method)
            replaced = table_lookup(d, t, k, s, elems)
            if not _table_set(d, regs, t, k, v, s, elems):
                break
            stored_in = t
            sp -= 3
        elif op == 32:  # tget
            if sp < 1:
                break
            k = _i(stack[sp])
            t = _i(stack[sp - 1])
            if t >= nobj or (_i(d[t * s]) & 7) != _TABLE:
                break
            v = table_lookup(d, t, k, s, elems)
            sp -= 1
            stack[sp] = nil if v < 0 else v
        elif 35 <= op <= 39:  # pushf pushi pushs pushcn pushcc
            if sp + 1 >= stack_size:
                break
            if op == 35:
                idx = _obj_alloc(d, regs, s, reserved, _FLOAT, 0)
            elif op == 36:
                idx = _obj_alloc(d, regs, s, reserved, _INT, 0)
            elif op == 37:
                idx = _obj_alloc(d, regs, s, reserved, _STRING, arg)
            else:
                idx = _obj_alloc(d, regs, s, reserved, _CLOSURE, 0)
            if idx < 0:
                break
            if op <= 37:
                d[idx * s + 1] = arg & 0xFF
                d[idx * s + 2] = arg >> 8
            else:
                value = arg if op == 38 else _s16(arg)
                for j in range(s - 1):
                    d[idx * s + 1 + j] = (value >> (8 * j)) & 0xFF
                if op == 38:
                    d[idx * s] = _i(d[idx * s]) | _FLAG1
            sp += 1
            stack[sp] = idx
        elif op == 5 or op == 6 or op == 33:  # ret0 ret1 callc
            if op == 33:
                reached = regs[R_REACHED]
                regs[R_REACHED] = 0
                kind = _callc(d, stack, regs, sp, bp, lsyms, nxt_pc, bsize, s, elems,
                              reserved, True)
                if kind == 2:  # the count was the top; R_HOST: the closure
                    regs[R_HOST_COUNT] = -1 if regs[R_REACHED] else top_before
                regs[R_REACHED] = reached | regs[R_REACHED]
            else:
                kind = 1 if _ret(d, stack, regs, op == 6, sp, bp, lsyms, bsize, s,
                                 elems) else 0
            if kind == 0:
                break
            sp = regs[R_SP]
            bp = regs[R_BP]
            lsyms = regs[R_LSYMS]
            nxt_pc = regs[R_PC]
            if kind == 2:  # counted here; Python calls the host function, ends the step
                pc = nxt_pc
                regs[R_EXECUTED] += 1
                status = HOST_CALL
                break
        elif op == 30:  # pusht: a table and its first segment
            if sp + 1 >= stack_size or not _room(d, regs, s, reserved, elems, 1, 1):
                break
            idx = _obj_alloc(d, regs, s, reserved, _TABLE, 0)
            seg = _seg_alloc(d, regs, elems)
            d[idx * s + 1] = seg & 0xFF
            d[idx * s + 2] = (seg >> 8) & 0xFF
            sp += 1
            stack[sp] = idx
        elif op == 40:  # pushl
            if sp + 1 >= stack_size:
                break
            idx = _pushl(d, regs, lsyms, arg, s, elems, reserved)
            if idx < 0:
                break
            sp += 1
            stack[sp] = idx
        elif op == 41:  # lload
            if sp + 1 >= stack_size:
                break
            v = darray_get(d, lsyms, arg, s, elems)
            if v < 0:
                break
            sp += 1
            stack[sp] = v
        elif op == 42:  # lstore of an existing local, or of the next one (no new segment)
            if sp < 0:
                break
            count = darray_size(d, lsyms, s, elems)
            if count < arg:
                break
            if count == arg and not _darray_push_in_place(d, lsyms, nil, s, elems):
                break
            new_local = count == arg or _permanent_leaf(
                d, darray_get(d, lsyms, arg, s, elems), nobj, s)
            darray_set(d, lsyms, arg, _i(stack[sp]), s, elems)
            sp -= 1
        elif op == 43:  # lremove of one local, or of several held by the last segment
            removed_a, removed_b = -2, -2
            if arg <= 2:
                removed_a, removed_b = _last_elements(d, lsyms, arg, s, elems)
            if arg == 1 and not _darray_pop(d, lsyms, s, elems):
                break
            if arg > 1 and not _darray_pop_in_place(d, lsyms, arg, s, elems):
                break
        elif op == 44:  # jump
            if arg > bsize:
                break
            nxt_pc = arg
        elif op == 45 or op == 46:  # jumpz jumpnz
            if sp < 0:
                break
            o = _i(stack[sp])
            if o >= nobj:
                break
            t = _i(d[o * s]) & 7
            if t != _NIL and t != _INT:
                break
            if (_u16(d, o, s) == 0) == (op == 45):
                nxt_pc = arg
            if nxt_pc > bsize:
                break
            sp -= 1
        else:
            break
        # ---- the instruction is done: count it, then the skip rule (VM._loop)
        pc = nxt_pc
        regs[R_EXECUTED] += 1
        rule = rules[op]
        fixed = True
        if rule == _STORED_GLOBAL or rule == _STORED_NEW_LOCAL or rule == _STORED_IN_TABLE:
            followed[:] = -1  # the number may have moved into a second place
        if rule == _STORED_GLOBAL:
            name_fresh = _dropped(info, below_before, nobj) == _DROP_FRESH
            freed = _stored_global_kept(d, regs, info, top_before, below_before, replaced,
                                        gsyms, nobj, s, limit)
            fixed = freed > -2
            if freed >= 0:
                free_a = freed
            if fixed and name_fresh:
                # the name string: a new one when a free slot came before the table's key
                # (BittyBuzz deduplicates a string only when it meets it first)
                if free_a < 0:
                    free_a = below_before
                else:
                    free_b = below_before
            if not fixed and _i(info[top_before]) == FRESH \
                    and _i(d[top_before * s]) & 7 in (_INT, _FLOAT):
                owned_next = top_before
        elif rule == _STORED_IN_TABLE:
            free_a, free_b = _stored_in_table_kept(d, regs, info, stored_in, below_before,
                                                   top_before, replaced, nobj, s, limit)
            fixed = free_a > -2
            if not fixed:
                free_a = -1
                if _i(info[top_before]) == FRESH and below_before != top_before \
                        and _i(d[top_before * s]) & 7 in (_INT, _FLOAT):
                    owned_next = top_before
            elif free_a < 0:
                free_a = free_b
                free_b = -1
        elif rule == _REMOVED_LOCALS:
            # the locals' values lost the frame's slot: each must be a permanent leaf (nil)
            # or OWNED, whose one reference that slot was (the skipped collection frees it)
            fixed = removed_a >= 0 and removed_a != removed_b
            for x in (removed_a, removed_b):
                if x < 0 or not fixed or _permanent_leaf(d, x, nobj, s):
                    continue
                if x < nobj and _owned(info, x):
                    if not _i(info[x]) & NEW:
                        regs[R_OLD_CHANGED] = 1  # an old object freed
                    if free_a < 0:
                        free_a = x
                    else:
                        free_b = x
                else:
                    fixed = False
            if not fixed:
                free_a = -1
                free_b = -1
        elif rule == _STORED_NEW_LOCAL:
            fixed = new_local and _stored_leaf_kept(d, regs, info, top_before, lsyms, nobj,
                                                    s, limit)
        elif rule >= _REPLACED_TOP:
            # it dropped roots (the top, and the one below for two): each must be kept by
            # the permanent roots or be a fresh temporary, which the skipped collection frees
            top = _dropped(info, top_before, nobj)
            below = _DROP_KEPT
            two = rule == _POPPED_TWO_NEW or rule == _POPPED_TWO_OLD
            if two:
                below = _dropped(info, below_before, nobj)
            fixed = top != _DROP_UNKNOWN and below != _DROP_UNKNOWN and not (
                top == below == _DROP_FRESH and top_before == below_before)
            # a followed number's one stack slot dropped: its slot's alone again (a
            # collection that follows finds it so, see fastgc.OWNED)
            _follow_drop(info, followed, top_before, below_before, two)
            if not fixed or rule == _POPPED_ONE:
                pass
            elif sp < 0 or _i(stack[sp]) >= nobj:
                fixed = False
            elif rule == _POPPED_TWO_NEW or rule == _POPPED_ONE_NEW:
                pending = _i(stack[sp]) * s
                fixed = _new_leaf_kept(d, regs, info, _i(stack[sp]), s)
            else:
                _follow_push(info, _i(stack[sp]), followed)
                fixed = _old_kept(d, info, _i(stack[sp]), s)
            if fixed and top == _DROP_FRESH:
                free_a = top_before
            if fixed and below == _DROP_FRESH:
                if free_a < 0:
                    free_a = below_before
                else:
                    free_b = below_before
        elif rule >= _PUSHED_OLD and _i(stack[sp]) >= nobj:
            fixed = False
        elif rule == _PUSHED_NEW:
            pending = _i(stack[sp]) * s
            if op == 3 and (_i(d[pending]) & 7) == _TABLE:
                fixed = _table_copy_kept(regs, info, _i(stack[sp]), top_before, nobj, limit)
            else:
                fixed = _new_leaf_kept(d, regs, info, _i(stack[sp]), s)
        elif rule == _PUSHED_OLD:
            _follow_push(info, _i(stack[sp]), followed)
            fixed = _old_kept(d, info, _i(stack[sp]), s)
        else:
            fixed = rule == _PC_ONLY
        if regs[R_UNSETTLED]:
            fixed = False
        n += 1
        status = EXIT
        if budget != NONE:
            if saved == NONE:
                if n >= budget:
                    status = BUDGET
                    break
            elif n > budget:
                status = BUDGET
                break
        slice_left -= 1
        if slice_left == 0:
            status = SLICE
            break
    regs[R_PC] = pc
    regs[R_SP] = sp
    regs[R_BP] = bp
    regs[R_LSYMS] = lsyms
    regs[R_N] = n
    # frees a skipped collection owes stay the kernel's: whoever runs the next step (Python,
    # another kernel) collects instead, which frees them too
    regs[R_FIXED] = 1 if fixed and free_a < 0 else 0
    regs[R_PENDING] = pending
    return status


__all__ = ["COMPILED", "run", "RULES", "REGISTERS", "NONE", "EXIT", "NEED_PYTHON", "BUDGET"]
