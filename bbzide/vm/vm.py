"""The BittyBuzz virtual machine record and its instructions (spec §D.5-D.6, §E.8, §F.1-F.3).

One :class:`VM` is one robot's ``bbzvm_t``: the heap buffer, the u16 stack of heap indices,
pc/blockptr/lsyms, the singletons (nil, default activation record, function list, globals)
and the non-heap records of swarms, stigmergy, neighbors and message queues. Every
instruction reproduces the reference C routine step by step — including the order of pops,
allocations and checks — because that order is visible in the heap bytes and in the state
left behind by an error.

Error handling mirrors the C macros: ``seterror`` puts the VM in ERROR and records the
event; the instruction then returns at the same point the C code returns. Allocation
failures (``HeapFull`` from the heap) become BBZVM_ERROR_MEM exactly where the C wrappers
(``bbzint_new`` ...) return ``vm->nil``.

Our additions (not in BittyBuzz), documented in ARCHITECTURE.md:
* ``Error.BUDGET`` (number 15): ``run``/``closure_call`` exceeded ``instruction_budget``.
* Malformed bytecode never raises: reading an opcode at pc ≥ size is a PC error (the C
  fetch function would read past the array), an unknown opcode is INSTR.
* Integer division or modulo by zero (a crash in C) is a MATH error.
"""

from __future__ import annotations

import math
from array import array
from collections.abc import Callable
from typing import Any

import numpy as np

from bbzide.compiler import bbzfloat
from bbzide.vm import gc as gcmod
from bbzide.vm.heap import (
    CLOSURE,
    FLAG1,
    FLAG2,
    FLOAT,
    GC_MARK,
    INT,
    NIL,
    NO_ACTREC,
    PERMANENT,
    STRING,
    TABLE,
    TYPE_MASK,
    USERDATA,
    VALID,
    Heap,
    HeapFull,
)
from bbzide.vm.host import HostFunction, HostRegistry
from bbzide.vm.kernels import fastgc, fasthost, fastloop, packed_queues
from bbzide.vm.messages import MessageQueues, record_size
from bbzide.vm.neighbors import NeighborsState
from bbzide.vm.profiles import PC, Profile
from bbzide.vm.states import Error, State
from bbzide.vm.swarm import SwarmState
from bbzide.vm.tables import (
    CloneFailed,
    darray_clone,
    darray_destroy,
    darray_find,
    darray_get,
    darray_new,
    darray_pop,
    darray_push,
    darray_set,
    darray_size,
    lambda_alloc,
    table_get,
    table_set,
)
from bbzide.vm.tables import (
    compare as type_compare,
)
from bbzide.vm.vstig import VstigEntry, VstigStore

_I16 = 0xFFFF
#: the registers of a fresh array from ``fastloop.R_LEFT_FRAME`` on: no walk element
#: before, no string twin known
_FRESH_TAIL = (0,) * (fastloop.REGISTERS - fastloop.R_LEFT_FRAME)


def _s16(v: int) -> int:
    v &= 0xFFFF
    return v - 0x10000 if v & 0x8000 else v


class VM:
    """One BittyBuzz VM (``bbzvm_t``)."""

    def __init__(self, profile: Profile = PC, robot: int = 0, stress_gc: bool = True) -> None:
        self.profile = profile
        self.heap = Heap(profile, reference=stress_gc)
        self.host = HostRegistry(profile.ptr_size)
        self._stress_gc = stress_gc
        #: u16 heap indices, as the C; an ``array`` so the compiled kernel shares it
        self.stack = array("H", bytes(2 * profile.stack_size))
        self._stack_view = np.frombuffer(self.stack, np.uint16)
        self._heap_view = self.heap.view
        self._bcode_view = np.zeros(0, np.uint8)
        self._bcode_of_view = b""
        #: registers of the compiled ``_ret`` a host function's return uses (fast mode)
        self._ret_registers = np.zeros(fastloop.REGISTERS, np.int64)
        self.stack_size = profile.stack_size
        self.stackptr = -1
        self.blockptr = -1
        self.pc = 0
        self.bcode = b""
        self.bcode_size = 0
        self.state = State.NOCODE
        self.error = Error.NONE
        self.lsyms = 0
        self.gsyms = 0
        self.nil = 0
        self.dflt_actrec = 0
        self.flist = 0
        self.robot = robot
        self.instruction_budget: int | None = None
        #: (error name, pc when the receiver was called) of every error, oldest first.
        self.error_events: list[tuple[str, int]] = []
        self.error_receiver: Callable[[VM, Error], None] | None = None
        self.instructions_executed = 0
        #: The debugger's hook (bbzide/debugger): called with the VM before each instruction
        #: `step` runs — the reference mode's loop, before the instruction's collection — so
        #: it sees the VM as the previous instruction left it. None: no call. The fast mode's
        #: compiled loop never calls it (a debugger puts a traced robot in the reference mode).
        self.tracer: Callable[[VM], None] | None = None
        #: heap geometry passed to the compiled collector (fastgc.collect)
        self._geometry = (self.heap.size, self.heap.obj_size, self.heap.seg_size,
                          self.heap.elems, self.heap.reserved, profile.gcmark_depth)
        self.swarm = SwarmState()
        self._vstig = VstigStore()
        #: (``fasthost`` rows, latch array) of the host functions a kernel may run in place
        #: while the robot finishes a compiled swarm step in Python (``swarm_batch``): its
        #: readings and computed ones. A reading is the robot's state before any host call
        #: made in Python, so the first one (`_call_host_function`) ends it (None).
        self.hosted: tuple[np.ndarray, np.ndarray] | None = None
        #: the queues and neighbor ring as arrays (fast mode's swarm step), and whether the
        #: arrays hold the truth now (packed_queues.py: one form is the truth at a time)
        self._packed: packed_queues.PackedQueues | None = None
        self._packed_live = False
        packed_queues.arrays_changed()
        self.neighbors = NeighborsState()
        self.queues = MessageQueues(profile.in_queue_cap, profile.out_queue_cap, profile.obj_size)

    # =================================================================== queues and ring
    @property
    def queues(self) -> MessageQueues:
        """``vm->inmsgs``/``vm->outmsgs`` (unpacked first when the arrays hold the truth)."""
        if self._packed_live:
            self._unpack()
        return self._queues

    @queues.setter
    def queues(self, value: MessageQueues) -> None:
        if self._packed_live:
            self._unpack()
        self._queues = value

    @property
    def neighbors(self) -> NeighborsState:
        """``vm->neighbors`` (unpacked first when the arrays hold the truth)."""
        if self._packed_live:
            self._unpack()
        return self._neighbors

    @neighbors.setter
    def neighbors(self, value: NeighborsState) -> None:
        if self._packed_live:
            self._unpack()
        self._neighbors = value

    @property
    def vstig(self) -> VstigStore:
        """``vm->vstig`` (unpacked first when the arrays hold the truth)."""
        if self._packed_live:
            self._unpack()
        return self._vstig

    @vstig.setter
    def vstig(self, value: VstigStore) -> None:
        if self._packed_live:
            self._unpack()
        self._vstig = value

    def _unpack(self) -> None:
        self._packed_live = False
        packed = self._packed
        packed.unpack(self._queues, self._neighbors)  # type: ignore[union-attr]
        changed, added = packed.vstig_changes()  # type: ignore[union-attr]
        entries = self._vstig.entries
        for k, (_key, value, timestamp, robot) in changed:
            e = entries[k]
            e.value, e.timestamp, e.robot = value, timestamp, robot
        entries.extend(VstigEntry(*row) for row in added)

    def packed(self) -> packed_queues.PackedQueues:
        """The queues, neighbor ring and stigmergy entries as arrays that hold the truth
        from now until the next Python access to ``queues``/``neighbors``/``vstig``
        (packed_queues.py)."""
        packed = self._packed
        if not self._packed_live:
            if packed is None:
                packed = self._packed = packed_queues.PackedQueues(self.profile,
                                                     len(self._queues.inbox.records[0]))
            packed.pack(self._queues, self._neighbors, self.robot)
            packed.pack_vstig(self._vstig)
            self._packed_live = True
        return packed  # type: ignore[return-value]

    @property
    def stress_gc(self) -> bool:
        """The reference mode: the model's own Python routines, a collection before every
        instruction, no compiled kernel (the heap's scans and table reads included)."""
        return self._stress_gc

    @stress_gc.setter
    def stress_gc(self, on: bool) -> None:
        self._stress_gc = on
        self.heap.reference = on

    # =================================================================== construct
    def construct(self, robot: int | None = None) -> None:
        """``bbzvm_construct`` (spec §E.11): singletons, globals, library tables."""
        from bbzide.vm import neighbors, swarm, table_library, vstig

        if robot is not None:
            self.robot = robot
        packed_queues.arrays_changed()
        self.bcode = b""
        self.bcode_size = 0
        self.pc = 0
        self.state = State.NOCODE
        self.error = Error.NONE
        self.stackptr = -1
        self.blockptr = -1
        self.lsyms = 0
        self.flist = 0
        h = self.heap
        h.clear()
        self.queues.clear()
        self.nil = h.obj_alloc(NIL)
        h.set_mdata(self.nil, h.mdata(self.nil) | PERMANENT)
        h.set_u16(self.nil, 0)
        self.dflt_actrec = darray_new(h)
        self.make_permanent(self.dflt_actrec)
        darray_push(h, self.dflt_actrec, self.nil)
        self.flist = darray_new(h)
        self.make_permanent(self.flist)
        self.gsyms = h.obj_alloc(TABLE)
        self.make_permanent(self.gsyms)
        # bbzvm_register_globals: id := robot
        self.push_int(self.robot)
        self.gsym_register(0, self.stack[self.stackptr])
        self.pop()
        vstig.register(self)
        swarm.register(self)
        neighbors.register(self)
        table_library.register(self)

    def set_bcode(self, bcode: bytes) -> None:
        """``bbzvm_set_bcode``: run the string-registration preamble up to its ``nop``."""
        self.bcode = bytes(bcode)
        self.bcode_size = len(self.bcode)
        packed_queues.arrays_changed()
        self.state = State.READY
        self.error = Error.NONE
        self.pc = 2
        while True:
            if self.pc >= self.bcode_size:
                self.seterror(Error.PC)
                return
            if self.bcode[self.pc] == 0:
                break
            self.step()
            if self.state != State.READY:
                return
        self.step()

    # =================================================================== errors
    def seterror(self, code: Error) -> None:
        self.state = State.ERROR
        self.error = code
        self.error_events.append((code.name, self.pc))
        if self.error_receiver is not None:
            self.error_receiver(self, code)

    def not_implemented(self) -> None:
        self.seterror(Error.NOTIMPL)

    # =================================================================== heap helpers
    def make_permanent(self, i: int) -> None:
        self.heap.set_mdata(i, self.heap.mdata(i) | PERMANENT)

    def unmake_permanent(self, i: int) -> None:
        self.heap.set_mdata(i, self.heap.mdata(i) & ~PERMANENT & 0xFF)

    def gc(self) -> None:
        """``bbzvm_gc`` (the reference collector in stress mode, the compiled one else)."""
        if not self.stress_gc:
            self.collect_fast()
            return
        gcmod.collect(self.heap, self.stack, self.stackptr)

    def collect_fast(self) -> None:
        """The same collection as :meth:`gc`, by the compiled kernel (:mod:`fastgc`)."""
        h = self.heap
        h.gc_runs += 1
        sp = self.stackptr
        r = fastgc.collect(h.view, self._stack_view, sp, h.rtobj, h.ltseg,
                     h.gc_info, h.gc_traversed, *self._geometry)
        h.rtobj = (r >> 16) & 0xFFFF
        h.ltseg = r & 0xFFFF
        h.truncated = h.truncated or bool(r & fastgc.TRUNCATED)
        h.unsettled = h.truncated or bool(r & fastgc.UNSETTLED)

    def settle(self) -> None:
        """Make every observable byte exact now. A no-op: the fast mode defers nothing
        past the instruction being run — it skips only collections that would change
        nothing but a new leaf's mark bit, which it sets where that collection would have
        run — so whenever the VM is not inside ``step``/``run``/``closure_call`` the heap,
        ROP/LSP and stack are those of the reference. Kept so that observers (inspector,
        dumps) can say what they need without knowing how the VM runs."""

    def alloc_or_mem(self, fn: Callable[[Heap], int]) -> int:
        """Run an allocating heap function; MEM error and nil on failure."""
        try:
            return fn(self.heap)
        except HeapFull:
            self.seterror(Error.MEM)
            return self.nil

    def new_int(self, value: int) -> int:
        """``bbzint_new``."""
        try:
            i = self.heap.obj_alloc(INT)
        except HeapFull:
            self.seterror(Error.MEM)
            return self.nil
        self.heap.set_u16(i, value & _I16)
        return i

    def new_float(self, bits: int) -> int:
        try:
            i = self.heap.obj_alloc(FLOAT)
        except HeapFull:
            self.seterror(Error.MEM)
            return self.nil
        self.heap.set_u16(i, bits & _I16)
        return i

    def new_string_obj(self, sid: int) -> int:
        """``bbzstring_get``: dedupe or allocate."""
        try:
            i = self.heap.obj_alloc(STRING, sid)
        except HeapFull:
            self.seterror(Error.MEM)
            return self.nil
        self.heap.set_u16(i, sid)
        return i

    def new_table_obj(self) -> int:
        try:
            return self.heap.obj_alloc(TABLE)
        except HeapFull:
            self.seterror(Error.MEM)
            return self.nil

    def new_closure_obj(self, value: int) -> int:
        try:
            i = self.heap.obj_alloc(CLOSURE)
        except HeapFull:
            self.seterror(Error.MEM)
            return self.nil
        self.heap.set_ptr(i, value)
        return i

    def new_userdata(self, value: int) -> int:
        try:
            i = self.heap.obj_alloc(USERDATA)
        except HeapFull:
            self.seterror(Error.MEM)
            return self.nil
        self.heap.set_ptr(i, value)
        return i

    def table_put_raw(self, t: int, value: int, key: int) -> None:
        """``bbztable_set(t, key, value)`` with MEM on failure (value allocated first)."""
        try:
            table_set(self.heap, t, key, value)
        except HeapFull:
            self.seterror(Error.MEM)

    # =================================================================== stack
    def stack_depth(self) -> int:
        return self.stackptr + 1

    def stack_at(self, i: int) -> int:
        """``bbzvm_stack_at``: the i-th entry from the top (0 = top)."""
        return self.stack[self.stackptr - i]

    def push(self, v: int) -> None:
        if self.stackptr + 1 >= self.stack_size:
            self.seterror(Error.STACK)
            return
        self.stackptr += 1
        self.stack[self.stackptr] = v

    def pop(self) -> None:
        if self.stackptr < 0:
            self.seterror(Error.STACK)
            return
        self.stackptr -= 1

    def push_int(self, v: int) -> None:
        self.push(self.new_int(v))

    def push_float(self, bits: int) -> None:
        self.push(self.new_float(bits))

    def push_string(self, sid: int) -> int:
        o = self.new_string_obj(sid)
        self.push(o)
        return o

    def push_table(self) -> int:
        o = self.new_table_obj()
        self.push(o)
        return o

    def push_nil(self) -> None:
        self.push(self.nil)

    def push_closure(self, value: int, native: bool) -> int:
        """``bbzvm_pushc``."""
        o = self.new_closure_obj(value)
        if native:
            self.heap.set_mdata(o, self.heap.mdata(o) | FLAG1)
        self.push(o)
        return o

    def assert_stack(self, n: int) -> bool:
        if self.stackptr + 1 < n:
            self.seterror(Error.STACK)
            return False
        return True

    def assert_type(self, i: int, typ: int) -> bool:
        if self.heap.obj_type(i) != typ:
            self.seterror(Error.TYPE)
            return False
        return True

    def assert_lnum(self, n: int) -> bool:
        """``bbzvm_assert_lnum``: the activation record holds self + n arguments."""
        if darray_size(self.heap, self.lsyms) != n + 1:
            self.seterror(Error.LNUM)
            return False
        return True

    def lsym(self, i: int) -> int:
        """Local symbol i of the current activation record (nil if absent)."""
        v = darray_get(self.heap, self.lsyms, i)
        return self.nil if v is None else v

    # =================================================================== registration
    def gsym_register(self, sid: int, v: int) -> None:
        self.push_string(sid)
        self.push(v)
        self.gstore()

    def register_host(self, symbol: str, fn: HostFunction, address: int | None = None) -> int:
        return self.host.register(symbol, fn, address)

    def function_register(self, sid: int, symbol: str, fn: HostFunction,
                          address: int | None = None) -> int:
        """``bbzvm_function_register``: closure first, then the name (gstore)."""
        addr = self.host.register(symbol, fn, address)
        self.push_closure(addr, native=False)
        if self.state == State.ERROR:
            return self.nil
        cpos = self.stack[self.stackptr]
        self.pop()
        if sid >= 0:
            self.gsym_register(sid, cpos)
        return cpos

    def add_function(self, t: int, sid: int, symbol: str, fn: HostFunction,
                     address: int | None = None) -> None:
        """``bbztable_add_function``: push t, pushs name, pushcc, tput."""
        addr = self.host.register(symbol, fn, address)
        self.push(t)
        self.push_string(sid)
        self.push_closure(addr, native=False)
        self.tput()

    # =================================================================== snapshots
    def snapshot(self) -> bytes:
        """The whole VM state as bytes: the flat layout of `snapshot_layout` (written from the
        live buffers and, when they hold the truth, the packed arrays: nothing is unpacked),
        or, for a state outside that layout's shape, the pickled one (`pickled_snapshot`)."""
        from bbzide.vm import snapshot_layout

        flat = snapshot_layout.vm_bytes(self)
        return flat if flat is not None else self.pickled_snapshot()

    def pickled_snapshot(self) -> bytes:
        """The state pickled (the only layout before the flat one; recordings of formats 2 and
        3 hold it): heap copy + records, through `snapshot_pickle`, which leaves the live
        objects as fast as they were. No deepcopy first: pickling copies the records."""
        from bbzide.vm import snapshot_pickle

        return snapshot_pickle.dumps((
            self.heap.snapshot(), list(self.stack), self.stackptr, self.blockptr, self.pc,
            self.state, self.error, self.lsyms, self.gsyms, self.nil, self.dflt_actrec,
            self.flist, self.robot, list(self.error_events), self.instructions_executed,
            (self.swarm, self.vstig, self.neighbors, self.queues),
            self.bcode,
        ))

    @staticmethod
    def decode_snapshot(snapshot: bytes) -> tuple[Any, ...]:
        """A `snapshot()` of either layout as the pickled layout's tuple of fresh records."""
        import pickle

        from bbzide.vm import snapshot_layout

        if snapshot.startswith(snapshot_layout.VM_MAGICS):
            return snapshot_layout.decode_vm(snapshot)
        if not snapshot.startswith(b"\x80"):  # not a pickle of ours (protocol 2+)
            raise snapshot_layout.SnapshotError("neither a flat nor a pickled VM snapshot")
        return pickle.loads(snapshot)  # type: ignore[no-any-return]

    def restore(self, snapshot: bytes) -> None:
        self.restore_state(self.decode_snapshot(snapshot))

    def restore_state(self, snap: tuple[Any, ...]) -> None:
        """Take over a decoded snapshot's state (`decode_snapshot`; its records are fresh).
        A state of another profile's heap or stack size is a `SnapshotError`, VM untouched."""
        from bbzide.vm.snapshot_layout import SnapshotError

        hs, stack = snap[0], snap[1]
        if len(hs[0]) != self.heap.size or len(stack) != len(self.stack):
            raise SnapshotError("the snapshot's heap or stack size is not this profile's")
        try:
            fits = self._fits(snap)
        except (AttributeError, TypeError, ValueError):  # a pickled state of another shape
            fits = False
        if not fits:
            raise SnapshotError("the snapshot's heap pointers, stack pointers or message "
                                "rings do not fit this profile's VM")
        (_, _, self.stackptr, self.blockptr, self.pc, self.state, self.error,
         self.lsyms, self.gsyms, self.nil, self.dflt_actrec, self.flist, self.robot,
         events, self.instructions_executed, recs, bcode) = snap
        self.heap.restore(hs)
        self.stack[:] = array("H", stack)
        self.error_events = list(events)
        self.swarm, self.vstig, self.neighbors, self.queues = recs
        self.bcode = bcode
        self.bcode_size = len(bcode)
        packed_queues.arrays_changed()

    def _fits(self, snap: tuple[Any, ...]) -> bool:
        """Whether a decoded snapshot's registers index inside this VM's buffers.

        A recording is untrusted input, and the compiled kernels (fastloop, fastgc,
        fastreceive: numba, no bounds checks) index the heap, the stack and the message rings
        with these registers as they are: a heap pointer or a ring index past its buffer read
        and wrote outside it (measured: segfaults, "double free" aborts, a hang). The heap's
        bytes and every object index are checked by the kernels themselves; these registers
        are not. The heap pointers keep ``reserved <= rtobj <= ltseg <= size`` on whole
        objects and segments; the stack pointers stay in the stack; the message queues and
        the neighbor ring keep this profile's sizes, with ``start``/``end`` inside them."""
        heap = self.heap
        held, stackptr, blockptr = snap[0], snap[2], snap[3]
        if len(held) not in (5, 7):  # (a snapshot of five values predates the heap's flags)
            return False
        rtobj, ltseg, flags = held[1], held[2], held[5:]
        # every scalar register an int (a pickled keyframe could hold any allowed value: a
        # list as the pc escaped as a TypeError from the debug map), the state and error kinds;
        # the heap's two flags bools
        ints = (rtobj, ltseg, stackptr, blockptr, snap[4], *snap[7:13], snap[14])
        if set(map(type, ints)) != {int} or set(map(type, flags)) - {bool} \
                or type(snap[5]) is not State \
                or type(snap[6]) is not Error \
                or not heap.reserved * heap.obj_size <= rtobj <= ltseg <= heap.size \
                or rtobj % heap.obj_size or (heap.size - ltseg) % heap.seg_size \
                or not -1 <= blockptr < len(self.stack) or not -1 <= stackptr < len(self.stack):
            return False
        _, _, neighbors, queues = snap[15]
        live = self.queues
        if (queues.in_capacity, queues.out_capacity, queues.obj_size) != (
                live.in_capacity, live.out_capacity, live.obj_size):
            return False
        record = record_size(live.obj_size)
        for ring, like in ((queues.inbox, live.inbox), (queues.outbox, live.outbox),
                           (neighbors.ring, self.neighbors.ring)):
            if ring.capacity != like.capacity or len(ring.records) != len(like.records) \
                    or {type(ring.start), type(ring.end)} != {int} \
                    or not 0 <= ring.start < max(ring.capacity, 1) \
                    or not 0 <= ring.end < max(ring.capacity, 1):
                return False
        return all(type(r) is bytearray and len(r) == record
                   for r in (*queues.inbox.records, *queues.outbox.records))

    # =================================================================== execution
    def step(self) -> None:
        """``bbzvm_step``: GC, then one instruction.

        A single step always collects (reference collector in stress mode, the compiled
        one in fast mode): code outside the VM may have changed the heap since the last
        instruction. The loops of :meth:`run` and :meth:`closure_call` skip collections
        they can prove changeless (see ``_SKIP_RULES``).
        """
        if self.state == State.READY:
            if self.tracer is not None:
                self.tracer(self)
            if self.stress_gc:
                gcmod.collect(self.heap, self.stack, self.stackptr)
            else:
                self.collect_fast()
            self.exec_instr()

    def exec_instr(self) -> None:
        offset = self.pc
        size = self.bcode_size
        if offset >= size:
            self.seterror(Error.PC)
            self.pc = offset
            return
        op = self.bcode[offset]
        self.instructions_executed += 1
        if op != 1:
            self.pc = offset + 1
        if op >= 35:
            if op > 46:
                self.seterror(Error.INSTR)
            elif self.pc + 2 > size:
                self.seterror(Error.PC)
            else:
                arg = self.bcode[self.pc] | (self.bcode[self.pc + 1] << 8)
                self.pc += 2
                _OPERAND_OPS[op - 35](self, arg)
        else:
            _SIMPLE_OPS[op](self)
        if self.state != State.READY:
            self.pc = offset

    def _assert_pc(self, idx: int) -> bool:
        if idx > self.bcode_size:
            self.seterror(Error.PC)
            return False
        return True

    # ---- simple instructions -------------------------------------------------------
    def op_nop(self) -> None:
        pass

    def op_done(self) -> None:
        self.state = State.DONE

    def op_pushnil(self) -> None:
        self.push(self.nil)

    def op_dup(self) -> None:
        n = self.stackptr + 1
        if not (0 < n < self.stack_size):
            self.seterror(Error.STACK)
            return
        h = self.heap
        try:
            idx = h.obj_alloc(USERDATA)
        except HeapFull:
            self.seterror(Error.MEM)
            return
        s = h.obj_size
        src = self.stack[self.stackptr] * s
        dst = idx * s
        h.data[dst:dst + s] = h.data[src:src + s]
        h.data[dst] = (h.data[dst] | VALID) & ~PERMANENT & 0xFF
        self.push(idx)

    def op_pop(self) -> None:
        self.pop()

    def op_ret0(self) -> None:
        self.ret0()
        if self.state == State.READY:
            self._assert_pc(self.pc)

    def op_ret1(self) -> None:
        self.ret1()
        if self.state == State.READY:
            self._assert_pc(self.pc)

    def _unwind(self) -> bool:
        h = self.heap
        self.stackptr = self.blockptr
        self.blockptr = h.int_value(self.stack[self.stackptr])
        self.pop()
        self.unmake_permanent(self.lsyms)
        darray_destroy(h, self.lsyms)
        self.lsyms = self.stack[self.stackptr]
        self.pop()
        return True

    def _compiled_ret(self, with_value: bool) -> bool:
        """``ret0``/``ret1`` of a host function by the instruction kernel's ``_ret`` (fast
        mode): its happy path, or False with nothing done (Python then runs it; ``_ret``
        also refuses a return pc past the code, which only ``op_ret*`` would check)."""
        if self.stress_gc or _KERNEL is None:
            return False
        regs = self._ret_registers
        regs[fastloop.R_NIL] = self.nil
        h = self.heap
        if not fastloop._ret(self._heap_view, self._stack_view, regs, with_value,
                             self.stackptr, self.blockptr, self.lsyms, self.bcode_size,
                             h.obj_size, h.elems):
            return False
        self.pc, self.stackptr, self.blockptr, _rtobj, _ltseg, self.lsyms = \
            regs[0:6].tolist()
        return True

    def ret0(self) -> None:
        if self._compiled_ret(False):
            return
        if not self.assert_stack(3):
            return
        self._unwind()
        if not self.assert_stack(1):
            return
        if not self.assert_type(self.stack[self.stackptr], INT):
            return
        self.pc = self.heap.u16(self.stack[self.stackptr])
        self.pop()
        self.push(self.nil)

    def ret1(self) -> None:
        if self._compiled_ret(True):
            return
        if not self.assert_stack(4):
            return
        ret = self.stack[self.stackptr]
        self._unwind()
        if not self.assert_type(self.stack[self.stackptr], INT):
            return
        self.pc = self.heap.u16(self.stack[self.stackptr])
        self.pop()
        self.push(ret)

    def _arith(self, kind: int) -> None:
        if not self.assert_stack(2):
            return
        h = self.heap
        rhs = self.stack[self.stackptr]
        lhs = self.stack[self.stackptr - 1]
        self.stackptr -= 2
        tl = h.obj_type(lhs)
        tr = h.obj_type(rhs)
        if not self.profile.float_ops:
            if tl == FLOAT or tr == FLOAT:
                self.seterror(Error.TYPE)
                return
            self._int_arith(kind, _s16(h.u16(lhs)), _s16(h.u16(rhs)), float_ops=False)
            return
        if tl == INT and tr == INT:
            self._int_arith(kind, h.int_value(lhs), h.int_value(rhs))
            return
        if tl not in (INT, FLOAT) or tr not in (INT, FLOAT):
            self.seterror(Error.MATH)
            self.push(self.nil)  # the C pushes the operator's nil result anyway
            return
        a = float(h.int_value(lhs)) if tl == INT else bbzfloat.to_float(h.u16(lhs))
        b = float(h.int_value(rhs)) if tr == INT else bbzfloat.to_float(h.u16(rhs))
        try:
            if kind == 0:
                r = a + b
            elif kind == 1:
                r = a - b
            elif kind == 2:
                r = a * b
            elif kind == 3:
                r = a / b if b != 0 else (math.copysign(math.inf, a) * math.copysign(1, b)
                                          if a != 0 else math.nan)
            elif kind == 4:
                if tl == INT:
                    a = float(h.u16(lhs))
                q = a / b if b != 0 else math.inf
                r = a - float(_s16(int(q))) * b if math.isfinite(q) else math.nan
            else:
                self.seterror(Error.MATH)
                self.push(self.nil)  # float '^': MATH, then push(nil) as the C does
                return
        except OverflowError:
            r = math.inf
        self.push_float(bbzfloat.from_float(r))

    def _int_arith(self, kind: int, a: int, b: int, float_ops: bool = True) -> None:
        if kind == 0:
            r = a + b
        elif kind == 1:
            r = a - b
        elif kind == 2:
            r = a * b
        elif kind == 3 or kind == 4:
            if b == 0:
                self.seterror(Error.MATH)
                return
            q = abs(a) // abs(b)
            if (a < 0) != (b < 0):
                q = -q
            r = q if kind == 3 else a - q * b
        else:
            if b >= 0:
                r = 1
                for _ in range(b):
                    r = _s32(r * a)
            elif a == 1:
                r = 1
            elif a == -1:
                r = -1
            else:
                self.seterror(Error.MATH)
                if float_ops:  # the float build returns nil and pushes it; the int build 0
                    self.push(self.nil)
                    return
                r = 0
        self.push_int(r)

    def op_add(self) -> None:
        self._arith(0)

    def op_sub(self) -> None:
        self._arith(1)

    def op_mul(self) -> None:
        self._arith(2)

    def op_div(self) -> None:
        self._arith(3)

    def op_mod(self) -> None:
        self._arith(4)

    def op_pow(self) -> None:
        self._arith(5)

    def op_unm(self) -> None:
        if not self.assert_stack(1):
            return
        h = self.heap
        o = self.stack[self.stackptr]
        t = h.obj_type(o)
        if t == INT:
            self.pop()
            self.push_int(-h.int_value(o))
        elif t == FLOAT:
            self.pop()
            self.push_float(bbzfloat.negate(h.u16(o)))
        else:
            self.seterror(Error.TYPE)

    def _truth(self, o: int) -> int:
        h = self.heap
        return 1 if h.obj_type(o) == INT and h.u16(o) != 0 else 0

    def _logic(self, kind: int) -> None:
        if not self.assert_stack(2):
            return
        rhs = self.stack[self.stackptr]
        lhs = self.stack[self.stackptr - 1]
        self.stackptr -= 2
        a = self._truth(lhs)
        b = self._truth(rhs)
        self.push_int((a & b) if kind == 0 else (a | b))

    def op_land(self) -> None:
        self._logic(0)

    def op_lor(self) -> None:
        self._logic(1)

    def op_band(self) -> None:
        self._logic(0)

    def op_bor(self) -> None:
        self._logic(1)

    def op_lnot(self) -> None:
        if not self.assert_stack(1):
            return
        o = self.stack[self.stackptr]
        self.pop()
        if self.heap.obj_type(o) in (NIL, INT):
            self.push_int(1 if self.heap.u16(o) != 0 else 0)
        else:
            self.seterror(Error.TYPE)

    def op_bnot(self) -> None:
        if not self.assert_stack(1):
            return
        o = self.stack[self.stackptr]
        self.pop()
        if self.heap.obj_type(o) in (NIL, INT):
            self.push_int(~self.heap.u16(o))
        else:
            self.seterror(Error.TYPE)

    def op_shift(self) -> None:
        self.seterror(Error.INSTR)

    def _cmp(self, kind: int) -> None:
        if not self.assert_stack(2):
            return
        rhs = self.stack[self.stackptr]
        lhs = self.stack[self.stackptr - 1]
        self.stackptr -= 2
        c = type_compare(self.heap, lhs, rhs)
        if kind == 0:
            r = c == 0
        elif kind == 1:
            r = c != 0
        elif kind == 2:
            r = c > 0
        elif kind == 3:
            r = c >= 0
        elif kind == 4:
            r = c < 0
        else:
            r = c <= 0
        self.push_int(1 if r else 0)

    def op_eq(self) -> None:
        self._cmp(0)

    def op_neq(self) -> None:
        self._cmp(1)

    def op_gt(self) -> None:
        self._cmp(2)

    def op_gte(self) -> None:
        self._cmp(3)

    def op_lt(self) -> None:
        self._cmp(4)

    def op_lte(self) -> None:
        self._cmp(5)

    def op_gload(self) -> None:
        self.gload()

    def gload(self) -> None:
        if not self.assert_stack(1):
            return
        s = self.stack[self.stackptr]
        if not self.assert_type(s, STRING):
            return
        self.pop()
        v = table_get(self.heap, self.gsyms, s)
        self.push(self.nil if v is None else v)

    def op_gstore(self) -> None:
        self.gstore()

    def gstore(self) -> None:
        if not self.assert_stack(2):
            return
        s = self.stack[self.stackptr - 1]
        o = self.stack[self.stackptr]
        if not self.assert_type(s, STRING):
            return
        self.stackptr -= 2
        try:
            table_set(self.heap, self.gsyms, s, o)
        except HeapFull:
            self.seterror(Error.MEM)

    def op_pusht(self) -> None:
        self.push(self.new_table_obj())

    def op_tput(self) -> None:
        self.tput()

    def tput(self) -> None:
        if not self.assert_stack(3):
            return
        h = self.heap
        v = self.stack[self.stackptr]
        k = self.stack[self.stackptr - 1]
        t = self.stack[self.stackptr - 2]
        if not self.assert_type(t, TABLE):
            return
        self.stackptr -= 3
        if self.state == State.ERROR:  # bbzvm_assert_state() after the pops
            return
        m = h.mdata(v)
        if (m & TYPE_MASK == CLOSURE and m & FLAG2 and h.data[v * h.obj_size + 2] != NO_ACTREC
                and not h.mdata(h.data[v * h.obj_size + 2]) & FLAG2):
            self._bind_method(t, k, v)
            return
        try:
            table_set(h, t, k, v)
        except HeapFull:
            self.seterror(Error.MEM)

    def _bind_method(self, t: int, k: int, v: int) -> None:
        """tput of a lambda created inside a function: bind self (spec §E.8)."""
        h = self.heap
        s = h.obj_size
        try:
            o = h.obj_alloc(USERDATA)
        except HeapFull:
            self.seterror(Error.MEM)
            return
        h.data[o * s:o * s + s] = h.data[v * s:v * s + s]
        h.set_mdata(o, h.mdata(o) | FLAG2)
        vm_ = h.mdata(v)
        try:
            d = h.obj_alloc(INT if vm_ & FLAG1 else USERDATA)
        except HeapFull:
            self.seterror(Error.MEM)
            return
        ar = h.data[v * s + 2]
        o2 = darray_get(h, self.flist, h.data[v * s + 1])
        if o2 is None:
            self.seterror(Error.FLIST)
            return
        h.data[d * s + 1:d * s + s] = h.data[o2 * s + 1:o2 * s + s]
        pos = darray_find(h, self.flist, d)
        if pos == darray_size(h, self.flist):
            try:
                darray_push(h, self.flist, d)
            except HeapFull:
                self.seterror(Error.MEM)
                return
        else:
            h.set_mdata(d, h.mdata(d) & ~VALID & 0xFF)
        idx, ok = lambda_alloc(h, ar)
        if idx >= 0:
            h.data[o * s + 2] = idx
        if not ok:
            self.seterror(Error.MEM)
            return
        h.set_mdata(idx, h.mdata(idx) | FLAG2)
        h.data[o * s + 1] = pos & 0xFF
        if not darray_set(h, idx, 0, t):
            self.seterror(Error.FLIST)
            return
        try:
            table_set(h, t, k, o)
        except HeapFull:
            self.seterror(Error.MEM)

    def op_tget(self) -> None:
        if not self.assert_stack(2):
            return
        k = self.stack[self.stackptr]
        t = self.stack[self.stackptr - 1]
        if not self.assert_type(t, TABLE):
            return
        self.stackptr -= 2
        v = table_get(self.heap, t, k)
        self.push(self.nil if v is None else v)

    def op_callc(self) -> None:
        self.callc()
        if self.state == State.READY:
            self._assert_pc(self.pc)

    def callc(self) -> None:
        h = self.heap
        s = h.obj_size
        if not self.assert_stack(1):
            return
        if not self.assert_type(self.stack[self.stackptr], INT):
            return
        argn = h.u16(self.stack[self.stackptr])
        self.pop()
        if not self.assert_stack(argn + 1):
            return
        c = self.stack[self.stackptr - argn]
        if not self.assert_type(c, CLOSURE):
            return
        cm = h.mdata(c)
        is_lambda = bool(cm & FLAG2)
        ref = h.data[c * s + 1]
        actrec = h.data[c * s + 2]
        if is_lambda and ref >= darray_size(h, self.flist):
            self.seterror(Error.FLIST)
            return
        old_lsyms = self.lsyms
        src = self.dflt_actrec if (not is_lambda or actrec == NO_ACTREC) else actrec
        try:
            self.lsyms = darray_clone(h, src)
        except CloneFailed as failed:  # the C has already stored the new index in lsyms
            self.lsyms = failed.index
            self.seterror(Error.MEM)
            return
        except HeapFull:
            self.seterror(Error.MEM)
            return
        self.make_permanent(self.lsyms)
        for i in range(argn, 0, -1):
            try:
                darray_push(h, self.lsyms, self.stack[self.stackptr - (i - 1)])
            except HeapFull:
                pass
        self.stackptr -= argn + 1
        if not is_lambda or actrec == NO_ACTREC or not h.mdata(actrec) & FLAG2:
            darray_set(h, self.lsyms, 0, self.stack[self.stackptr])
        self.pop()
        self.push_int(self.pc)
        if self.state != State.READY:
            return
        self.push(old_lsyms)
        if self.state != State.READY:
            return
        self.push_int(self.blockptr)
        if self.state != State.READY:
            return
        self.blockptr = self.stackptr
        if is_lambda:
            fo = darray_get(h, self.flist, ref)
            x = h.ptr_value(fo if fo is not None else 0)
        else:
            x = h.ptr_value(c)
        if cm & FLAG1:
            self.pc = x & 0xFFFF
        else:
            self._call_host_function(x)

    def _call_host_function(self, address: int) -> None:
        """The host function at ``address``, called in Python (NOTIMPL if none is)."""
        self.hosted = None
        call = self.host.lookup(address)
        if call is None:
            self.seterror(Error.NOTIMPL)
        else:
            call.function(self)

    def kernel_hosts(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """``fasthost``'s (hosts, outq, ctl, latch) for a kernel entered from Python: the
        ones of `hosted`, or none."""
        hosted = self.hosted
        if hosted is None:
            return fasthost.NO_HOST_ARGS
        return hosted[0], fasthost.NO_HOST_ARGS[1], fasthost.NO_HOST_ARGS[2], hosted[1]

    def op_calls(self) -> None:
        pass

    # ---- operand instructions --------------------------------------------------------
    def op_pushf(self, arg: int) -> None:
        self.push(self.new_float(arg))

    def op_pushi(self, arg: int) -> None:
        self.push(self.new_int(arg))

    def op_pushs(self, arg: int) -> None:
        self.push(self.new_string_obj(arg))

    def op_pushcn(self, arg: int) -> None:
        self.push_closure(arg, native=True)

    def op_pushcc(self, arg: int) -> None:
        self.push_closure(_s16(arg), native=False)

    def op_pushl(self, addr: int) -> None:
        h = self.heap
        s = h.obj_size
        try:
            o = h.obj_alloc(CLOSURE)
        except HeapFull:
            self.seterror(Error.MEM)
            return
        h.set_mdata(o, h.mdata(o) | FLAG1 | FLAG2)
        try:
            idx = h.obj_alloc(INT)
        except HeapFull:
            self.seterror(Error.MEM)
            return
        h.set_u16(idx, addr)
        pos = darray_find(h, self.flist, idx)
        if pos == darray_size(h, self.flist):
            try:
                darray_push(h, self.flist, idx)
            except HeapFull:
                self.seterror(Error.MEM)
                return
        else:
            h.set_mdata(idx, h.mdata(idx) & ~VALID & 0xFF)
        h.data[o * s + 1] = pos & 0xFF
        if self.lsyms:
            ar, ok = lambda_alloc(h, self.lsyms)
            if ar >= 0:
                h.data[o * s + 2] = ar
            if not ok:
                self.seterror(Error.MEM)
                return
        self.push(o)

    def op_lload(self, idx: int) -> None:
        v = darray_get(self.heap, self.lsyms, idx)
        if v is None:
            self.seterror(Error.LNUM)
            return
        self.push(v)

    def op_lstore(self, idx: int) -> None:
        h = self.heap
        o = self.stack[self.stackptr]
        size = darray_size(h, self.lsyms)
        while size <= idx:
            size += 1
            try:
                darray_push(h, self.lsyms, self.nil)
            except HeapFull:
                self.seterror(Error.MEM)
                return
        darray_set(h, self.lsyms, idx, o)
        self.pop()

    def op_lremove(self, num: int) -> None:
        for _ in range(num):
            if not darray_pop(self.heap, self.lsyms):
                self.seterror(Error.LNUM)
                return

    def op_jump(self, target: int) -> None:
        self.pc = target
        self._assert_pc(target)

    def _jump_cond(self, target: int, on_zero: bool) -> None:
        if not self.assert_stack(1):
            return
        h = self.heap
        o = self.stack[self.stackptr]
        if h.obj_type(o) not in (NIL, INT):
            self.seterror(Error.TYPE)
            return
        if (h.u16(o) == 0) == on_zero:
            self.pc = target
        if not self._assert_pc(self.pc):
            return
        self.pop()

    def op_jumpz(self, target: int) -> None:
        self._jump_cond(target, True)

    def op_jumpnz(self, target: int) -> None:
        self._jump_cond(target, False)

    # =================================================================== host calls
    def closure_call(self, argc: int) -> None:
        """``bbzvm_closure_call``: stack holds self, closure, args; result stays on top."""
        if self.state != State.READY:
            return
        self.push_int(argc)
        saved = self.blockptr
        if _KERNEL is None or self.stress_gc or self.state != State.READY:
            self.callc()
            self._loop(saved, self.instruction_budget)
        else:  # the kernel makes the call itself (or hands it back: CALL_IN_PYTHON)
            self._loop(saved, self.instruction_budget, call_first=True)

    def _host_call(self, closure: int, offset: int) -> None:
        """The end of a ``callc`` instruction at ``offset`` whose set-up the compiled kernel
        did: the C closure's host function, then ``op_callc``/``exec_instr``'s pc rules."""
        self._call_host_function(self.heap.ptr_value(closure))
        if self.state == State.READY:
            self._assert_pc(self.pc)
        if self.state != State.READY:
            self.pc = offset

    def function_call(self, sid: int, argc: int) -> None:
        """``bbzvm_function_call``: call the global ``sid`` with ``argc`` args on the stack."""
        if self.state == State.DONE:
            self.state = State.READY
        if self.state != State.READY:
            return
        self.push_string(sid)
        if self.state != State.READY:
            return
        self.gload()
        if not self.assert_type(self.stack[self.stackptr], CLOSURE):
            return
        if argc > 0:
            c = self.stack[self.stackptr]
            for i in range(argc):
                self.stack[self.stackptr - i] = self.stack[self.stackptr - i - 1]
            self.stack[self.stackptr - argc] = c
        self.closure_call(argc)

    def run(self, max_instructions: int | None = None) -> None:
        """Step until the VM is no longer READY (or the budget is exhausted)."""
        budget = max_instructions if max_instructions is not None else self.instruction_budget
        self._loop(None, budget)

    def kernel_registers(self, saved: int | None, budget: int | None,
                         call_first: bool = False) -> np.ndarray:
        """The registers the compiled kernels take, in ``fastloop``'s ``R_*`` order (one
        array per loop: host functions nest loops), and the bytecode view refreshed."""
        if self._bcode_of_view is not self.bcode:
            # a writable copy: the same numba type as the swarm step's views (fastviews),
            # so each kernel is compiled once, not once for read-only bytes as well
            self._bcode_view = np.frombuffer(bytearray(self.bcode), np.uint8)
            self._bcode_of_view = self.bcode
        heap = self.heap
        return np.array((
            self.pc, self.stackptr, self.blockptr, heap.rtobj, heap.ltseg, self.lsyms,
            heap.gc_runs, self.instructions_executed, 0, False, -1, heap.peak_used,
            self.nil, self.gsyms, fastloop.NONE if saved is None else saved,
            fastloop.NONE if budget is None else budget, self.profile.float_ops,
            self.stack_size, self.profile.gcmark_depth, self.flist, self.dflt_actrec,
            0, call_first, 0, 0, 0, -1, 0, int(heap.unsettled), int(heap.truncated),
            *_FRESH_TAIL), np.int64)

    def take_kernel_registers(self, regs: np.ndarray) -> tuple[int, bool, int]:
        """Copy a kernel's registers back into the VM and its heap; the loop's own
        (instructions counted, heap known fixed, pending mark) are returned."""
        heap = self.heap
        self._take_heap_flags(regs)
        (self.pc, self.stackptr, self.blockptr, heap.rtobj, heap.ltseg, self.lsyms,
         heap.gc_runs, self.instructions_executed, n, fixed, pending, heap.peak_used) = \
            regs[0:12].tolist()
        return n, bool(fixed), pending

    def _take_heap_flags(self, regs: np.ndarray) -> None:
        """Whether the kernel's last collection left the heap settled, and whether one ever
        stopped at the depth limit (``Heap.unsettled``, ``Heap.truncated``)."""
        heap = self.heap
        heap.unsettled = bool(regs[fastloop.R_UNSETTLED])
        heap.truncated = heap.truncated or bool(regs[fastloop.R_TRUNCATED])

    def _loop(self, saved: int | None, budget: int | None, call_first: bool = False,
              resume: tuple[int, np.ndarray] | None = None) -> None:
        """The step loop of ``run`` (``saved`` None: until not READY) and of
        ``closure_call`` (until blockptr drops to ``saved``), with the instruction budget.

        Stress mode steps exactly as ``bbzvm_step``. Fast mode skips the collections that
        ``_SKIP_RULES`` proves changeless (counted in ``gc_runs`` all the same); the
        first step of a loop always collects, since code outside it may have changed the
        heap. ``call_first``: fast mode only — ``closure_call``'s ``callc`` is still to
        be made (by the kernel, or by Python when the kernel hands it back).
        ``resume``: fast mode only — (status, registers) of a kernel that ran this loop's
        first steps (``fastinbox``: a listener call), already copied into the VM; the
        loop goes on from that status as if its own kernel call had returned it.
        """
        ready = State.READY
        n = 0
        if self.stress_gc:
            while saved is None or saved < self.blockptr:
                if self.state != ready:
                    return
                self.step()
                n += 1
                if budget is not None:
                    if saved is None:
                        if n >= budget and self.state == ready:
                            self.seterror(Error.BUDGET)
                    elif n > budget:
                        self.seterror(Error.BUDGET)
                        return
            return
        heap = self.heap
        data = heap.data
        s = heap.obj_size
        info = heap.gc_info
        objects = heap.objects
        collect = self.collect_fast
        execute = self.exec_instr
        bcode = self.bcode
        size = len(bcode)
        stack = self.stack
        rules = _SKIP_RULES
        fixed = False
        pending = -1  # byte offset of a new leaf whose mark the next collection sets
        kernel = _KERNEL
        if kernel is not None:
            if resume is None:
                regs = self.kernel_registers(saved, budget, call_first)
                fresh = True  # regs holds the VM's registers already
            else:
                resumed, regs = resume
                n, fixed, pending = (int(regs[fastloop.R_N]), bool(regs[fastloop.R_FIXED]),
                                     int(regs[fastloop.R_PENDING]))
                self._take_heap_flags(regs)
                # a callc the kernel handed back is still to be made: enter the loop
                call_first = resumed == fastloop.CALL_IN_PYTHON
                fresh = False
            kernel_args = (self._heap_view, self._stack_view, self._bcode_view, regs, info,
                           heap.gc_traversed, fastloop.RULES, s, heap.elems, heap.reserved)
            if self.hosted is not None:  # readings and computed host functions in place
                kernel = fasthost.run_hosted
                kernel_args += self.kernel_hosts()
        while call_first or saved is None or saved < self.blockptr:
            if self.state != ready:
                return
            if kernel is not None:
                # the compiled kernel runs steps until one it does not cover (fastloop.py)
                if resume is not None:
                    status = resumed
                    resume = None
                else:
                    if not fresh:
                        regs[0:12] = (self.pc, self.stackptr, self.blockptr, heap.rtobj,
                                      heap.ltseg, self.lsyms, heap.gc_runs,
                                      self.instructions_executed, n, fixed, pending,
                                      heap.peak_used)
                        regs[fastloop.R_VALID_BELOW] = 0  # Python ran: it may have freed
                        regs[fastloop.R_TWIN_END] = 0  # or made strings
                        regs[fastloop.R_UNSETTLED] = heap.unsettled  # or collected
                        regs[fastloop.R_TRUNCATED] = heap.truncated
                    fresh = False
                    status = kernel(*kernel_args)
                    n, fixed, pending = self.take_kernel_registers(regs)
                if status == fastloop.CALL_IN_PYTHON:
                    call_first = False
                    self.callc()
                    continue
                call_first = False
                if status == fastloop.EXIT or status == fastloop.SLICE:
                    continue
                if status == fastloop.BUDGET:
                    self.seterror(Error.BUDGET)
                    if saved is None:
                        continue
                    return
                if status == fastloop.HOST_CALL:  # callc set up: the host function's turn
                    pc = self.pc - 1
                    self._host_call(int(regs[fastloop.R_HOST]), pc)
                    if kernel is not _KERNEL:  # a host call in Python: no more in place
                        kernel = _KERNEL
                        kernel_args = kernel_args[:10]
                else:  # NEED_PYTHON: the step's collection is done; its instruction here
                    pc = self.pc
                    execute()
            else:
                if fixed:
                    # the skipped collection's only effect, done where it would have run
                    heap.gc_runs += 1
                    if pending >= 0:
                        data[pending] |= GC_MARK
                else:
                    collect()
                pc = self.pc
                execute()
            # Is the heap still a fixed point of the collector? (see _SKIP_RULES)
            rule = rules[bcode[pc]] if pc < size and self.state == ready else 0
            pending = -1
            if rule >= _PUSHED_OLD and stack[self.stackptr] >= objects:
                fixed = False  # an index past the heap (corrupt code): let the GC decide
            elif rule == _PUSHED_NEW:
                pending = stack[self.stackptr] * s
                t = data[pending] & TYPE_MASK
                prior = heap.prior_mdata
                fixed = t != TABLE and (t != CLOSURE or not data[pending] & FLAG2) and \
                    bool(prior & VALID or not prior & GC_MARK)
            elif rule == _PUSHED_OLD:
                top = stack[self.stackptr]
                if info[top] & 127 == fastgc.OWNED:  # on the stack too: its slot's alone no more
                    info[top] = 3 + fastgc.PERMANENT_PHASE + (info[top] & 128)
                m = data[top * s]
                t = m & TYPE_MASK
                if t != TABLE and (t != CLOSURE or not m & FLAG2):
                    fixed = bool(m & GC_MARK)
                else:
                    fixed = bool(info[top] & fastgc.PERMANENT_PHASE)
            else:
                fixed = rule == _PC_ONLY
            if heap.unsettled:
                fixed = False  # the last collection is not a fixed point (fastgc.UNSETTLED)
            n += 1
            if budget is not None:
                if saved is None:
                    if n >= budget and self.state == ready:
                        self.seterror(Error.BUDGET)
                elif n > budget:
                    self.seterror(Error.BUDGET)
                    return


def _s32(v: int) -> int:
    v &= 0xFFFFFFFF
    return v - 0x100000000 if v & 0x80000000 else v


#: Opcodes that change nothing but pc: nop, calls, jump.
_PC_ONLY_OPCODES = frozenset({0, 34, 44})
# Fast-mode skip rules (VM._loop). An instruction that starts on a fixed point of the
# collector (a heap a collection would leave unchanged: right after one, or after an
# instruction accepted here) keeps it — so the next collection may be skipped — when:
# * _PC_ONLY: it changed nothing but pc (nop, calls, jump);
# * _PUSHED_OLD: it pushed an existing object (pushnil, lload) that is a marked *leaf*
#   (anything but a table or a lambda closure: the marker never looks inside it, so its
#   new stack root changes no other mark), or a non-leaf the last collection first marked
#   from the permanent roots (``gc_info``): its stack root then finds it marked, a no-op;
# * _PUSHED_NEW: it pushed a new leaf (pushf, pushi, pushs — or a deduplicated, hence
#   marked, string —, pushcn, pushcc, dup of a leaf) in a slot the last collection did not
#   reach (the slot's mark bit before the allocation, ``Heap.prior_mdata``, is clear; the
#   marker marks free slots too, through stale references): the next collection would
#   only set its mark bit, which the loop sets in its place, at the start of the next step
#   (not before: a VM stopped between the two shows the unmarked object, as the
#   firmware). A free slot the marker did reach may have been a stale *table* whose
#   segments it walked: the leaf written over it changes that walk, so a collection runs
#   (a case the hypothesis test found: a rule without this check skipped it).
# None of these changes how non-leaves are traversed, so ``gc_info`` stays true. Every
# other instruction (pops, stores, calls, tables, lambdas) is followed by a collection.
#
# More rules only the compiled kernel applies (fastloop.run; this loop, running an
# instruction the kernel handed back, collects after them — always exact):
# * _REPLACED_TOP: gload replaced the top root (a name string) by a global's value; the
#   dropped root was first marked from the permanent roots (``gc_info``, exact for every
#   object a skipped step did not allocate: those have no fastgc.PERMANENT_PHASE), so as a stack
#   root it marked nothing, and the pushed value is accepted as by _PUSHED_OLD;
# * _POPPED_TWO_NEW: a two-operand operation dropped two such roots and pushed its new
#   result, a leaf accepted as by _PUSHED_NEW (pending mark included);
# * _POPPED_ONE (pop, jumpz, jumpnz), _POPPED_ONE_NEW (unm, lnot, bnot: their new result as
#   by _PUSHED_NEW), _POPPED_TWO_OLD (tget: the value as by _PUSHED_OLD): they dropped one or
#   two such roots;
# * _STORED_NEW_LOCAL: lstore moved a leaf from the stack into a new local of an activation
#   record the permanent roots reach (fastloop._stored_leaf_kept), or into a local whose
#   value was a permanent leaf (nil: ``var x = e`` declares x by ``pushnil; lstore``);
# * _STORED_GLOBAL: gstore replaced a global's value by a leaf; the value it dropped was the
#   same, a permanent leaf, or one only that global held (fastloop.OWNED: the skipped
#   collection frees it, as the fresh leaves below; fastloop._stored_global_kept).
# * _STORED_IN_TABLE: tput replaced the value of a key a table walked from the permanent
#   roots had by a leaf; the value it dropped was the same, a permanent leaf, or one only
#   that table's slot held (fastloop.OWNED again; fastloop._stored_in_table_kept).
# * _REMOVED_LOCALS: lremove took one or two locals whose values are permanent leaves or
#   OWNED (their one reference was the local's slot: freed), out of the frame's last
#   segment (no segment freed).
# The kernel also accepts, for every dropped root of these rules, a *fresh* leaf
# (fastloop.FRESH: a leaf a skipped step allocated in a slot the last collection did not
# reach, so its one reference was that stack slot; or a dup's copy of a table the permanent
# roots keep, which shares its marked segments): the skipped collection would free it,
# and the kernel does just that at the start of the next step (fastloop._free_dropped).
_PC_ONLY, _PUSHED_OLD, _PUSHED_NEW, _REPLACED_TOP, _POPPED_TWO_NEW = 1, 2, 3, 4, 5
_POPPED_ONE, _POPPED_ONE_NEW, _POPPED_TWO_OLD, _STORED_NEW_LOCAL = 6, 7, 8, 9
_STORED_GLOBAL, _STORED_IN_TABLE, _REMOVED_LOCALS = 10, 11, 12
_SKIP_RULES: list[int] = [0] * 256
for _op in _PC_ONLY_OPCODES:
    _SKIP_RULES[_op] = _PC_ONLY
for _op in (2, 41):
    _SKIP_RULES[_op] = _PUSHED_OLD
for _op in (3, 35, 36, 37, 38, 39):
    _SKIP_RULES[_op] = _PUSHED_NEW
_SKIP_RULES[28] = _REPLACED_TOP  # gload
for _op in (7, 8, 9, 10, 11, 12, 14, 15, 17, 18, 22, 23, 24, 25, 26, 27):
    _SKIP_RULES[_op] = _POPPED_TWO_NEW
for _op in (4, 45, 46):
    _SKIP_RULES[_op] = _POPPED_ONE
for _op in (13, 16, 19):
    _SKIP_RULES[_op] = _POPPED_ONE_NEW
_SKIP_RULES[32] = _POPPED_TWO_OLD
_SKIP_RULES[42] = _STORED_NEW_LOCAL
_SKIP_RULES[29] = _STORED_GLOBAL
_SKIP_RULES[31] = _STORED_IN_TABLE
_SKIP_RULES[43] = _REMOVED_LOCALS

#: the compiled instruction kernel, when numba is installed (else the Python loop alone)
_KERNEL: Callable[..., int] | None = fastloop.run if fastloop.COMPILED else None

_SIMPLE_OPS: list[Callable[[VM], None]] = [
    VM.op_nop, VM.op_done, VM.op_pushnil, VM.op_dup, VM.op_pop, VM.op_ret0, VM.op_ret1,
    VM.op_add, VM.op_sub, VM.op_mul, VM.op_div, VM.op_mod, VM.op_pow, VM.op_unm,
    VM.op_land, VM.op_lor, VM.op_lnot, VM.op_band, VM.op_bor, VM.op_bnot,
    VM.op_shift, VM.op_shift, VM.op_eq, VM.op_neq, VM.op_gt, VM.op_gte, VM.op_lt, VM.op_lte,
    VM.op_gload, VM.op_gstore, VM.op_pusht, VM.op_tput, VM.op_tget, VM.op_callc, VM.op_calls,
]
_OPERAND_OPS: list[Callable[[VM, int], None]] = [
    VM.op_pushf, VM.op_pushi, VM.op_pushs, VM.op_pushcn, VM.op_pushcc, VM.op_pushl,
    VM.op_lload, VM.op_lstore, VM.op_lremove, VM.op_jump, VM.op_jumpz, VM.op_jumpnz,
]
