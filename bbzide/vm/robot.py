"""``Robot``: the firmware loop around one BittyBuzz VM — what the worlds drive.

It mirrors ``bbzkilo_start`` (spec §F.5; corpus README "Run loop"):

    boot():          construct → set_bcode → register host functions → top-level code
                     (until ``done``) → state := READY → call ``init``
    receive(...):    one wire payload (≤ 9 bytes) + situated data: a BROADCAST first feeds
                     ``bbzneighbors_add`` (as the Kilobot receive handler does), then the
                     payload is queued (``bbzinmsg_queue_append``)
    control_step():  ``process_inmsgs`` → call ``step`` → ``process_outmsgs`` → drain the
                     out-queue; returns the payloads sent, in queue order

Loops: ``loop="pop"`` (default) pops the value ``init``/``step`` return, as BittyBuzz's
``testswarm.c`` does; ``loop="robot"`` leaves it on the stack exactly like the Kilobot and
Crazyflie firmware, so the stack grows one slot per step until a STACK error (~step 90 on a
96-entry stack): the inspector shows that growth.

Errors never escape as Python exceptions: a VM error (and our ``BUDGET``, when one entry
into Buzz code — the top level, ``init``, ``step``, one listener — exceeds
``instruction_budget`` instructions) stops the robot and sets ``failure`` (reason, pc,
source location through the program's debug map, message). A host function that raises is a
``HOST`` failure; malformed bytecode and garbage messages end in a VM error or are dropped
like on the robot. Once failed, the robot does nothing more (like the firmware, which stops
calling ``step`` in state ERROR).

Determinism (for replay): a Robot is a pure function of its program, profile, robot id and
the sequence of calls made on it. The only inputs from outside are the arguments of
``receive`` (message bytes, distance, azimuth, elevation) and what host functions return
(``HostCall.ret``); the VM has no clock, no randomness and no other I/O. So
``restore(snapshot)`` followed by the same logged ``receive`` calls, the same
``control_step`` calls and host functions that return the logged values re-executes a
robot exactly.
"""

from __future__ import annotations

import pickle
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from bbzide.compiler import bbzfloat
from bbzide.compiler.program import BittyBuzzProgram
from bbzide.diagnostics import SourceLocation
from bbzide.vm import inmsgs, messages, neighbors, snapshot_layout, table_library, vstig
from bbzide.vm.host import (
    DrawnHostFunction,
    HostCall,
    LatchedHostFunction,
    LookupHostFunction,
    ReadingHostFunction,
    RoundedDistanceHostFunction,
)
from bbzide.vm.kernels import (
    fastbatch,
    fasthost,
    fastinbox,
    fastloop,
    fastreceive,
    kernels_now,
    packed_queues,
)
from bbzide.vm.profiles import Profile
from bbzide.vm.tables import table_get
from bbzide.vm.vm import VM, Error, State

HostFunction = Callable[[HostCall], None]

#: Instructions one entry into Buzz code may execute. A Kilobot (8 MHz AVR) runs in the
#: order of 50,000 BittyBuzz instructions per second and steps at about 30 Hz, so a real
#: step is a few thousand instructions; 100,000 is ~2 s of robot time — a loop that long
#: is a bug (an infinite loop) rather than a computation.
DEFAULT_BUDGET = 100_000

STR_INIT, STR_STEP = 4, 5

ERROR_MESSAGES = {
    "INSTR": "unknown or unsupported instruction",
    "STACK": "VM stack overflow or underflow",
    "LNUM": "wrong number of arguments or local symbol",
    "PC": "program counter out of range",
    "FLIST": "function list index out of range",
    "TYPE": "wrong operand type",
    "OUTOFRANGE": "index out of range",
    "NOTIMPL": "not implemented",
    "RET": "wrong return value",
    "STRING": "unknown string",
    "SWARM": "swarm id out of range (0..7)",
    "VSTIG": "virtual stigmergy full",
    "MEM": "out of heap memory",
    "MATH": "arithmetic error",
    "BUDGET": "instruction budget exhausted (infinite loop?)",
    "HOST": "host function raised an exception",
}


@dataclass(frozen=True)
class RobotFailure:
    """Why a robot stopped: ``reason`` is the BittyBuzz error name (``MEM``, ``TYPE``, ...)
    or ``BUDGET``/``HOST``; ``pc`` is the failing instruction's offset in the ``.bbo``."""

    reason: str
    pc: int
    location: SourceLocation | None
    message: str

    def __str__(self) -> str:
        where = f"{self.location}: " if self.location else ""
        return f"{where}{self.reason} at pc {self.pc}: {self.message}"


@dataclass(frozen=True)
class CompiledHosts:
    """What `Robot.compiled_hosts` gives the compiled swarm step."""

    #: ``fasthost``'s ``hosts`` rows
    table: np.ndarray
    #: the latched function of each latch slot
    latched: list[LatchedHostFunction]
    #: the reading of each reading slot (``packed_queues.READING_SLOTS``)
    readings: list[ReadingHostFunction]
    #: each drawn host function and the latch row of its first drawn row (its
    #: ``packed_queues.DRAWN_ROWS`` rows follow the readings')
    drawn: list[tuple[int, DrawnHostFunction]]


class Robot:
    """One robot: a VM, its host functions and the firmware loop (ARCHITECTURE.md contract)."""

    def __init__(self, program: BittyBuzzProgram, profile: Profile, robot_id: int,
                 host_functions: Mapping[str, HostFunction] | None = None, loop: str = "pop",
                 instruction_budget: int | None = DEFAULT_BUDGET,
                 host_symbols: Mapping[str, str] | None = None, stress_gc: bool = False) -> None:
        if loop not in ("pop", "robot"):
            raise ValueError(f"loop must be 'pop' or 'robot', not {loop!r}")
        self.program = program
        self.profile = profile
        self.robot_id = robot_id
        self.host_functions = dict(host_functions or {})
        #: optional C symbol per host-function name (its heap address and ``[cc:NAME]``)
        self.host_symbols = dict(host_symbols or {})
        self.loop = loop
        self.instruction_budget = instruction_budget
        self.vm = VM(profile, robot=robot_id, stress_gc=stress_gc)
        self.vm.instruction_budget = instruction_budget
        self.failure: RobotFailure | None = None
        self.booted = False
        self.steps_done = 0
        self.init_defined = False
        #: host-function names not in the program's string table (the script cannot use them)
        self.skipped_host_functions: list[str] = []
        #: called with (phase label) after each boot phase; the harness dumps there
        self.on_phase: Callable[[str], None] | None = None
        #: latched host functions by C symbol (host.LatchedHostFunction), and the table of
        #: host functions a compiled swarm step runs in place (compiled_hosts), cached
        self._latched: dict[str, LatchedHostFunction] = {}
        self._drawn: dict[str, DrawnHostFunction] = {}
        self._readings: dict[str, ReadingHostFunction] = {}
        self._hosts: tuple[int, CompiledHosts] | None = None
        self._latching = True

    # ---- boot --------------------------------------------------------------------------
    def boot(self) -> None:
        """construct, set_bcode, host functions, top-level code, ``init``."""
        self._guard(self._boot)

    def _boot(self) -> None:
        vm = self.vm
        self.booted = True
        vm.construct(self.robot_id)
        vm.set_bcode(self.program.bbo)
        self._phase("construct+set_bcode")
        if self._check():
            return
        self.register_host_functions()
        self._phase("setup")
        if self._check():
            return
        vm.run(self.instruction_budget)
        self._phase("script")
        if self._check():
            return
        vm.state = State.READY
        self.init_defined = self.call_global(STR_INIT)
        self._phase("init")
        self._check()

    def _phase(self, label: str) -> None:
        if self.on_phase is not None:
            self.on_phase(label)

    def register_host_functions(self) -> None:
        """``--reg`` order: plain names as globals; consecutive ``tbl.field`` as one table."""
        vm = self.vm
        items = list(self.host_functions.items())
        i = 0
        while i < len(items):
            name, fn = items[i]
            table, dot, _field = name.partition(".")
            if not dot:
                sid = self.program.string_id(name)
                if sid is None:
                    self.skipped_host_functions.append(name)
                else:
                    vm.function_register(sid, self._symbol(name), self._wrap(fn))
                    self._note_kernel_kind(self._symbol(name), fn)
                i += 1
                continue
            group = []
            while i < len(items) and items[i][0].partition(".")[0] == table \
                    and "." in items[i][0]:
                group.append(items[i])
                i += 1
            tsid = self.program.string_id(table)
            if tsid is None:
                self.skipped_host_functions.extend(n for n, _ in group)
                continue
            t = vm.push_table()
            for full, f in group:
                fsid = self.program.string_id(full.partition(".")[2])
                if fsid is None:
                    self.skipped_host_functions.append(full)
                    continue
                vm.add_function(t, fsid, self._symbol(full), self._wrap(f))
                self._note_kernel_kind(self._symbol(full), f)
            vm.gsym_register(tsid, t)
            vm.pop()

    def _note_kernel_kind(self, symbol: str, fn: HostFunction) -> None:
        """A host function a kernel runs in place: latched (the compiled swarm step stores
        its arguments), a reading (it writes the value before the kernel) or computed
        (``HostRegistry.mark_computed``)."""
        if isinstance(fn, LatchedHostFunction):
            self._latched[symbol] = fn
        elif isinstance(fn, ReadingHostFunction):
            self._readings[symbol] = fn
        elif isinstance(fn, DrawnHostFunction):
            self._drawn[symbol] = fn
        elif isinstance(fn, RoundedDistanceHostFunction):
            self.vm.host.mark_computed(symbol, fasthost.HOST_DISTANCE, fn.argc)
        elif isinstance(fn, LookupHostFunction):
            self.vm.host.mark_computed(symbol, fasthost.HOST_LOOKUP, fn.argc, fn.values)

    def _symbol(self, name: str) -> str:
        return self.host_symbols.get(name, name)

    @property
    def latch_host_calls(self) -> bool:
        """Whether a compiled swarm step may run this robot's latched host functions in
        machine code (True) or must call them in Python like any other (False: e.g. while a
        recorder logs every host call). Either way the robot ends in the same state."""
        return self._latching

    @latch_host_calls.setter
    def latch_host_calls(self, value: bool) -> None:
        self._latching = bool(value)
        self._hosts = None
        packed_queues.arrays_changed()

    def compiled_hosts(self) -> CompiledHosts:
        """The host functions a compiled swarm step runs in place (:mod:`fasthost`): rows
        (address, pointer size, kind, slot, argument count, a record's field names, a latch's
        bound and once flag, a reading's stale-after slots) for the closure address of
        ``neighbors.broadcast``, of a stigmergy's ``get`` and ``put``, of the table library's
        ``foreach`` (walked in place: ``fasthost.run_walking``), of each latched host
        function, of each reading, of each drawn one and of each one the kernel computes
        (``HostRegistry.computed_rows``), as the VM's registry maps them now; the latched
        function of each latch slot; the reading of each reading slot; the drawn functions
        and their rows. Cached until the registry changes."""
        registry = self.vm.host
        cached = self._hosts
        if cached is not None and cached[0] == registry.version:
            return cached[1]
        ptr = self.profile.ptr_size
        rows: list[tuple[int, ...]] = []
        slots: list[LatchedHostFunction] = []
        slot_of: dict[str, int] = {}
        readings: list[ReadingHostFunction] = []

        def row(address: int, kind: int, slot: int, argc: int, keys: Sequence[int] = (),
                below: int = -1, once: int = 0, stale_after: int = 0) -> tuple[int, ...]:
            # fasthost.H_* columns: the record's field names, then the latch's and the
            # reading's own
            no_keys = (-1,) * (packed_queues.LATCH_ARGS - len(keys))
            return (address, ptr, kind, slot, argc, *keys, *no_keys, below, once, stale_after)

        def current(symbol: str) -> Any:
            # the call registered as `symbol`, unless another registration took its address
            call = registry.by_symbol.get(symbol)
            return call if call is not None and registry.by_address.get(call.address) is call \
                else None

        def field_ids(names: Sequence[str]) -> list[int] | None:
            # a record's field names as string ids; None when the program lacks one (Python's
            # call reports it) or they are too many for a row
            ids = [self.program.string_id(name) for name in names]
            return None if len(ids) > packed_queues.LATCH_ARGS or None in ids else ids

        for address, call in registry.by_address.items():
            if call.function is neighbors.neighbors_broadcast:
                rows.append(row(address, fasthost.HOST_BROADCAST, 0, 2))
            elif call.function is vstig.vstig_get:
                rows.append(row(address, fasthost.HOST_VSTIG_GET, 0, 1))
            elif call.function is vstig.vstig_put:
                rows.append(row(address, fasthost.HOST_VSTIG_PUT, 0, 2))
            elif call.function is table_library.table_foreach:
                rows.append(row(address, fasthost.HOST_TABLE_FOREACH, 0, 2))
        for symbol, fn in self._latched.items() if self._latching else ():
            call = current(symbol)
            if call is None or len(slots) >= packed_queues.LATCH_SLOTS \
                    or not 0 <= fn.argc <= packed_queues.LATCH_ARGS:
                continue
            rows.append(row(call.address, fasthost.HOST_LATCH, len(slots), fn.argc,
                            below=-1 if fn.below is None else fn.below, once=int(fn.once)))
            slot_of[symbol] = len(slots)
            slots.append(fn)
        for symbol, reading in self._readings.items() if self._latching else ():
            call = current(symbol)
            keys = field_ids(reading.keys)
            if call is None or keys is None or len(readings) >= packed_queues.READING_SLOTS:
                continue
            # (a storer not latched hands the step to Python, whose readings are Python's)
            stale_after = sum(1 << slot_of[name] for name in reading.stale_after
                              if name in slot_of)
            kind = fasthost.HOST_READ_RECORD if keys else fasthost.HOST_READ_INT
            rows.append(row(call.address, kind, packed_queues.LATCH_SLOTS + len(readings), 0,
                            keys, stale_after=stale_after))
            readings.append(reading)
        drawn: list[tuple[int, DrawnHostFunction]] = []
        used = len(readings)
        for symbol, fn in self._drawn.items() if self._latching else ():
            call = current(symbol)
            keys = field_ids(fn.keys)
            if call is None or keys is None \
                    or used + packed_queues.DRAWN_ROWS > packed_queues.READING_SLOTS:
                continue
            first_row = packed_queues.LATCH_SLOTS + used
            rows.append(row(call.address, fasthost.HOST_DRAWN, first_row, 0, keys))
            drawn.append((first_row, fn))
            used += packed_queues.DRAWN_ROWS
        rows.extend(map(tuple, registry.computed_rows().tolist()))
        table = np.array(rows, np.int64).reshape(-1, fasthost.HOST_COLUMNS)
        hosts = CompiledHosts(table, slots, readings, drawn)
        self._hosts = (registry.version, hosts)
        return hosts

    def _wrap(self, fn: HostFunction) -> Callable[[VM], None]:
        strings = self.program.strings

        def call(vm: VM) -> None:
            c = HostCall(vm, strings)
            fn(c)
            c.finish()

        return call

    def call_global(self, sid: int) -> bool:
        """``bbzkilo_func_call``: look the global up (pushs, pop) and call it with self nil;
        in ``pop`` mode the returned value is popped. False when it is not defined."""
        vm = self.vm
        if fastinbox.COMPILED and not vm.stress_gc and vm.state == State.READY:
            defined = _call_global_compiled(vm, sid)
            if defined is not None:
                if defined and self.loop == "pop" and vm.state == State.READY:
                    vm.pop()
                return defined
        vm.push(vm.new_string_obj(sid))
        name = vm.stack[vm.stackptr] if vm.stackptr >= 0 else vm.nil
        vm.pop()
        c = table_get(vm.heap, vm.gsyms, name)
        if c is None:
            return False
        vm.push_nil()
        vm.push(c)
        vm.closure_call(0)
        if self.loop == "pop" and vm.state == State.READY:
            vm.pop()
        return True

    # ---- running -----------------------------------------------------------------------
    def receive(self, message: bytes, distance: float = 0.0, azimuth: float = 0.0,
                elevation: float = 0.0) -> None:
        """One received payload (at most 9 bytes are read) with its situated data."""
        if self.failure is not None or not self.booted:
            return
        try:  # _guard inlined (one call per received message: a hot path)
            self._receive(bytes(message[:messages.PAYLOAD_SIZE]), distance, azimuth,
                          elevation)
        except Exception as exc:  # noqa: BLE001 - the robot must never raise (contract)
            self._fail_host(exc)

    def receive_all(self, deliveries: Sequence[tuple[Any, bytes, float, float, float]]
                    ) -> None:
        """``receive`` of each ``(sender, payload, distance, azimuth, elevation)`` in turn
        (the engine's deliveries of a step). A Kilobot in the fast mode takes them in one
        compiled call (:mod:`fastreceive`: its receive path cannot touch the VM)."""
        vm = self.vm
        p = self.profile
        if self.failure is None and self.booted and p.xtreme and not p.neighbors_floats \
                and fastreceive.COMPILED and not vm.stress_gc and vm.state != State.ERROR:
            try:
                if fastreceive.receive_messages(vm, deliveries):
                    return
            except Exception as exc:  # noqa: BLE001 - the robot must never raise (contract)
                self._fail_host(exc)
                return
        for _sender, message, distance, azimuth, elevation in deliveries:
            self.receive(message, distance, azimuth, elevation)

    def _receive(self, payload: bytes, distance: float, azimuth: float,
                 elevation: float) -> None:
        if len(payload) >= 3 and payload[0] == messages.BROADCAST:
            rid = payload[1] | (payload[2] << 8)
            neighbors.add(self.vm, self.neighbor_entry(rid, distance, azimuth, elevation))
        messages.inmsg_append(self.vm.queues, payload)
        self._check()

    def neighbor_entry(self, rid: int, distance: float, azimuth: float,
                       elevation: float) -> neighbors.NeighborEntry:
        """Situated data as the build stores it: bbzfloat bits, or u8 (rounded, clamped)."""
        conv = _to_bbzfloat if self.profile.neighbors_floats else _to_u8
        return neighbors.NeighborEntry(rid & 0xFFFF, conv(distance), conv(azimuth),
                                       conv(elevation))

    def control_step(self) -> list[bytes]:
        """process_inmsgs, ``step``, process_outmsgs; the payloads sent this step."""
        if self.failure is not None or not self.booted:
            return []
        sent: list[bytes] = []

        def run() -> None:
            vm = self.vm
            inmsgs.process_inmsgs(vm)
            if vm.state != State.ERROR:
                self.call_global(STR_STEP)
            neighbors.process_outmsgs(vm)
            sent.extend(messages.drain_outbox(vm.queues))
            self.steps_done += 1
            self._check()

        self._guard(run)
        return sent

    def finish_compiled_step(self, phase: int, regs: np.ndarray, io: np.ndarray) -> list[bytes]:
        """The rest of a control step the compiled swarm step (``swarm_batch_fast``) stopped
        in ``phase`` (``fastbatch.P_*``), by the reference routines (``control_step``'s,
        from that point; its ``_guard`` too); the payloads sent this step."""
        vm = self.vm
        sent: list[bytes] = []
        try:
            io_status = int(io[fastbatch.IO_STATUS])
            saved, budget = int(regs[fastloop.R_SAVED]), vm.instruction_budget
            if phase == fastbatch.P_INMSGS:
                count = int(io[fastbatch.IO_COUNT])
                if io_status == fastinbox.IN_CALL:
                    vm._loop(saved, budget, resume=(int(io[fastbatch.IO_INNER]), regs))
                    vm.pop()
                    vm.gc()
                    inmsgs.go_on_inmsgs(vm, count, True)
                else:  # PYTHON_MESSAGE: message `count` collected, its extraction is next
                    inmsgs.go_on_inmsgs(vm, count, bool(io[fastbatch.IO_COLLECTED]),
                                        taken=True)
                if vm.state != State.ERROR:
                    self.call_global(STR_STEP)
            elif phase == fastbatch.P_STEP:
                if io_status == fastinbox.PYTHON_MESSAGE:
                    self.call_global(STR_STEP)
                else:
                    if io_status >= fastinbox.CALL_UNDER_WAY:
                        vm._loop(saved, budget,
                                 resume=(io_status - fastinbox.CALL_UNDER_WAY, regs))
                    if io_status != fastinbox.NOT_DEFINED and self.loop == "pop" \
                            and vm.state == State.READY:
                        vm.pop()
            # P_OUTMSGS (and after the above): the countdown is still to do
            sent = self._end_of_step_packed()
            if sent is None:
                neighbors.process_outmsgs(vm)
                sent = messages.drain_outbox(vm.queues)
            self.steps_done += 1
            self._check()
        except Exception as exc:  # noqa: BLE001 - the robot must never raise (contract)
            self._fail_host(exc)
        return sent

    def _end_of_step_packed(self) -> list[bytes] | None:
        """``process_outmsgs`` and ``drain_outbox`` by the compiled swarm step's own end of a
        step (``fastbatch.end_of_step``), on the packed queues while they still hold the
        truth: when the part of the step Python ran touched none of them (a hand-over to a
        table walk and back, say), unpacking them for the end and packing them again for the
        next step cost more than the rest of that part. None, with nothing done, when Python
        must do it (a heap data GC the kernel does not cover, a VM not READY)."""
        vm = self.vm
        if not vm._packed_live or not kernels_now(vm):
            return None
        packed, heap = vm._packed, vm.heap
        rows = self.profile.out_queue_cap + 1  # the out-queue's records at most
        payloads = np.zeros((rows, messages.PAYLOAD_SIZE), np.uint8)
        lengths = np.zeros(rows, np.int64)
        io = np.zeros(fastbatch.IO_SLOTS, np.int64)
        regs = vm.kernel_registers(None, None)
        if not fastbatch.end_of_step(heap.view, regs, heap.obj_size, heap.elems, heap.reserved,
                                     packed.outq, packed.ring, packed.ctl, 0, payloads, lengths,
                                     np.zeros(rows, np.int64), io):
            return None
        vm.take_kernel_registers(regs)
        if removed := -int(io[fastbatch.IO_ADDED]):  # a heap data GC's deleted entries
            vm._neighbors.count = (vm._neighbors.count - removed) & 0xFF
        return [payloads[k, :lengths[k]].tobytes() for k in range(int(io[fastbatch.IO_ROWS]))]

    # ---- failure -------------------------------------------------------------------------
    def _check(self) -> bool:
        """Record a failure when the VM is in ERROR; True when failed."""
        vm = self.vm
        if self.failure is None and vm.state == State.ERROR:
            reason = vm.error.name
            self.failure = RobotFailure(reason, vm.pc, self.program.location_of(vm.pc),
                                        ERROR_MESSAGES.get(reason, reason))
        return self.failure is not None

    def _guard(self, action: Callable[[], None]) -> None:
        """Run ``action``; a Python exception (a host function's, or a model bug on
        hostile input) becomes a failure instead of escaping."""
        try:
            action()
        except Exception as exc:  # noqa: BLE001 - the robot must never raise (contract)
            self._fail_host(exc)

    def _fail_host(self, exc: Exception) -> None:
        """A Python exception escaped the VM: the robot is errored with reason HOST."""
        vm = self.vm
        vm.state = State.ERROR
        if self.failure is None:
            self.failure = RobotFailure("HOST", vm.pc, self.program.location_of(vm.pc),
                                        f"{ERROR_MESSAGES['HOST']}: {exc!r}")

    # ---- state ---------------------------------------------------------------------------
    def snapshot(self) -> bytes:
        """The whole robot state (VM heap and records, loop bookkeeping) as bytes: the flat
        layout of `snapshot_layout` for a state of the usual shape, else pickled."""
        flat = snapshot_layout.robot_bytes(self, RobotFailure)
        if flat is not None:
            return flat
        return pickle.dumps((self.vm.snapshot(), self.failure, self.steps_done, self.booted))

    def pickled_snapshot(self) -> bytes:
        """The robot state in the pickled layout only (recordings of formats 2 and 3)."""
        return pickle.dumps((self.vm.pickled_snapshot(), self.failure, self.steps_done,
                             self.booted))

    @staticmethod
    def decode_snapshot(snapshot: bytes) -> tuple[Any, RobotFailure | None, int, bool]:
        """A `snapshot()` of either layout as (VM state tuple, failure, steps done, booted)."""
        if snapshot.startswith(snapshot_layout.ROBOT_MAGIC):
            vm_state, failure, steps_done, booted = snapshot_layout.decode_robot(snapshot)
            return (vm_state, None if failure is None else RobotFailure(*failure),
                    steps_done, booted)
        if not snapshot.startswith(b"\x80"):  # not a pickle of ours (protocol 2+)
            raise snapshot_layout.SnapshotError("neither a flat nor a pickled robot snapshot")
        vm_snapshot, failure, steps_done, booted = pickle.loads(snapshot)
        return VM.decode_snapshot(vm_snapshot), failure, steps_done, booted

    @staticmethod
    def comparable(snapshot: bytes) -> bytes:
        """A `snapshot()` decoded and pickled again the plain way, for comparing two robots'
        states: equal states give equal bytes here whatever layout or encoding the
        snapshots used (an earlier pickled version picked a list layout by
        `sys.getrefcount`, so equal states could differ in snapshot bytes). The heap's two
        flags are left out: they are the fast mode's note of which collections it may skip
        (`Heap.unsettled`, `Heap.truncated`), which the reference mode never sets, not state
        the robot's program sees."""
        vm_state, *rest = Robot.decode_snapshot(snapshot)
        heap, *registers = vm_state
        return pickle.dumps(((heap[:5], *registers), *rest))

    def restore(self, snapshot: bytes) -> None:
        """Restore a snapshot (either layout) of a robot with the same program, profile and
        host functions. (A never-booted robot boots first so its host-function registry
        exists.) A flat snapshot that does not decode is a `SnapshotError`."""
        if not self.booted:
            self.boot()
        vm_state, failure, steps_done, booted = self.decode_snapshot(snapshot)
        self.vm.restore_state(vm_state)
        self.failure, self.steps_done, self.booted = failure, steps_done, booted

    @property
    def error(self) -> Error:
        return self.vm.error


def _call_global_compiled(vm: VM, sid: int) -> bool | None:
    """``call_global``'s lookup and ``closure_call(0)`` by :func:`fastinbox.call_global`
    (fast mode), a call it leaves under way finished by ``VM._loop`` (``resume``); None
    when it did nothing (no room: the caller then does it all in Python)."""
    saved, budget = vm.blockptr, vm.instruction_budget
    regs = vm.kernel_registers(saved, budget)
    h = vm.heap
    status = fastinbox.call_global(h.view, vm._stack_view, vm._bcode_view, regs, h.gc_info,
                                   h.gc_traversed, fastloop.RULES, h.obj_size, h.elems,
                                   h.reserved, sid, *vm.kernel_hosts(), False)
    if status == fastinbox.PYTHON_MESSAGE:
        return None
    vm.take_kernel_registers(regs)
    if status >= fastinbox.CALL_UNDER_WAY:
        vm._loop(saved, budget, resume=(status - fastinbox.CALL_UNDER_WAY, regs))
    return status != fastinbox.NOT_DEFINED


def _to_bbzfloat(x: float) -> int:
    """A situated value as bbzfloat bits (builds with float neighbor data)."""
    return bbzfloat.from_float(float(x))


def _to_u8(x: float) -> int:
    """A situated value as the u8 the XTREME/int builds store: rounded, clamped to 0..255."""
    try:
        return min(255, max(0, round(x)))
    except (ValueError, OverflowError):  # NaN, inf
        return 255
