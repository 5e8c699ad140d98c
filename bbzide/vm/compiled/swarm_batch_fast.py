"""The compiled path of `swarm_batch.control_steps`: a whole swarm step in one machine-code call.

`swarm_batch` is the contract and its reference implementation (each robot's
``receive_all``, then ``control_step``). This is the same step with the Python around the VM
removed for the robots the compiled kernel covers — a plain `Robot` in the fast mode
(not ``stress_gc``), booted, not failed, READY. One call of :func:`fastbatch.swarm_step`
runs :func:`fastbatch.robot_step` for each of them in index order: it receives the robot's
rows of the deliveries (an XTREME ring of floats receives through ``receive_all`` first;
a heap profile's receive the kernel cannot finish is a ``P_RECEIVE`` hand-over), runs
its in-queue, ``step`` and out-queue on its packed queues (:mod:`packed_queues`: they
stay packed between steps) and writes what it sent straight
into the outbox columns. The per-robot arrays reach the kernel by address and length
(:mod:`fastviews`), recorded once per swarm (:class:`_SwarmTables`, rebuilt when
``packed_queues.GENERATION`` says a VM changed an array); the registers Python keeps as
attributes go in and out as one matrix (``dynamic``). Every other robot (a recorder's
wrapper, the stress mode, a failed or unbooted robot) takes the reference calls.

Order. The kernel's part of a robot's step touches only that robot (its VM, its packed
queues, its outbox rows, its latch slots), never the world: so it may run for every robot
before any Python of the step. Then, in robot index order, Python runs what is left: the
robots the kernel does not take (``control_step``) and the **hand-overs** — a robot whose
kernel call stopped in a phase it does not cover (``fastbatch.P_*``) is finished by the
reference routines (``Robot.finish_compiled_step``, the model's side) from exactly there
(its in-queue loop resumed, ``VM._loop`` resumed inside a call, ``step``'s pop, the
out-queue), under the same guard as
``Robot.control_step`` (a Python exception becomes the robot's HOST failure). So host
functions that touch the world run in the reference's order; a robot's receive before its
own step is equivalent to all receives first (a receive touches only its own robot: see
`swarm_batch`). Outbox rows added by Python are put back in robot order (a stable sort).

Readings (``host.ReadingHostFunction``) are read for each robot the kernel takes just before
the kernel, into the robot's reading rows: the kernel part of its step comes before any
Python of the step, so they are what a Python call would read there.

Latched host functions (``host.LatchedHostFunction``) the kernel ran are applied right
after the kernel, grouped by their ``apply``: before any Python code of the step, so a
robot's later Python call of the same function (a hand-over) stores after it, as in the
reference; the latched state is the robot's own and no host function reads it during a
step (the contract of a latched function), so applying the others' early changes nothing.
"""

from __future__ import annotations

from collections.abc import Sequence
from concurrent.futures import ThreadPoolExecutor
from operator import is_
from typing import Any

import numpy as np

from bbzide.vm.compiled import fastbatch, fasthost, fastloop, fastviews, packed_queues
from bbzide.vm.compiled.fastbatch import (
    F_POP,
    F_RECEIVE,
    F_STEP,
    IO_ADDED,
    IO_RECEIVED,
    IO_SLOTS,
    P_RECEIVE,
)
from bbzide.vm.compiled.packed_queues import DRAWN_ROWS, LATCH_ARGS, LATCH_SLOTS, READ_TAKEN
from bbzide.vm.message_layout import PAYLOAD_SIZE
from bbzide.vm.packed_messages import PackedMessages, StepResult
from bbzide.vm.states import State

#: the host functions a kernel entered from Python may run in place (``VM.hosted``): they
#: touch no queue (the queues are Python's then) and latch nothing
_IN_PLACE_FROM_PYTHON = (fasthost.HOST_READ_INT, fasthost.HOST_READ_RECORD,
                         fasthost.HOST_DISTANCE, fasthost.HOST_LOOKUP)

#: outbox rows allocated beyond what the kernel's drains can write (each robot at most its
#: out-queue's capacity, ``_SwarmTables.max_out``): room for a few Python rows before the
#: first growth (`_Outbox.room` grows it for the rest)
_SPARE_ROWS = 4


def covered(robot: Any, robot_type: type) -> bool:
    """Does the compiled step take this robot now? (See the module comment.) ``robot_type``:
    `robot.Robot`, passed in by `swarm_batch` (the model imports the kernels, not back)."""
    return type(robot) is robot_type and robot.failure is None and robot.booted \
        and not robot.vm.stress_gc and robot.vm.state == State.READY


def _receives_compiled(robot: Any) -> bool:
    """The kernel receives for the XTREME ring with u8 data and for the heap's neighbor
    data (``fastreceive.neighbors_add_heap``); not for an XTREME ring of floats."""
    p = robot.profile
    return not (p.xtreme and p.neighbors_floats)


class _Outbox:
    """The outbox columns being filled (rows in robot order)."""

    def __init__(self, rows: int) -> None:
        self.payloads = np.zeros((rows, PAYLOAD_SIZE), np.uint8)
        self.lengths = np.zeros(rows, np.int64)
        self.robots = np.zeros(rows, np.int64)
        self.cursor = np.zeros(1, np.int64)

    def room(self, rows: int) -> None:
        """At least ``rows`` free rows after the cursor."""
        used = int(self.cursor[0])
        if used + rows <= len(self.lengths):
            return
        grown = max(2 * len(self.lengths), used + rows)
        for name in ("payloads", "lengths", "robots"):
            old = getattr(self, name)
            new = np.zeros((grown, *old.shape[1:]), old.dtype)
            new[:used] = old[:used]
            setattr(self, name, new)

    def extend(self, other: _Outbox) -> None:
        """Another outbox's rows after these."""
        n = int(other.cursor[0])
        self.room(n)
        row = int(self.cursor[0])
        self.payloads[row:row + n] = other.payloads[:n]
        self.lengths[row:row + n] = other.lengths[:n]
        self.robots[row:row + n] = other.robots[:n]
        self.cursor[0] = row + n

    def add(self, index: int, sent: list[bytes]) -> None:
        """Payloads a robot sent through Python."""
        self.room(len(sent))
        row = int(self.cursor[0])
        for payload in sent:
            head = payload[:PAYLOAD_SIZE]
            self.payloads[row, :len(head)] = np.frombuffer(bytes(head), np.uint8)
            self.lengths[row] = len(payload)
            self.robots[row] = index
            row += 1
        self.cursor[0] = row

    def packed(self, sort: bool) -> PackedMessages:
        """The rows as an outbox; ``sort``: rows were added out of robot order (Python
        after the kernel): a stable sort by robot keeps each robot's queue order."""
        n = int(self.cursor[0])
        robots, payloads, lengths = self.robots[:n], self.payloads[:n], self.lengths[:n]
        if sort:
            order = np.argsort(robots, kind="stable")
            robots, payloads, lengths = robots[order], payloads[order], lengths[order]
        else:
            robots, payloads, lengths = robots.copy(), payloads.copy(), lengths.copy()
        zeros = np.zeros(n, np.float64)
        return PackedMessages(robots, payloads, lengths, robots, zeros, zeros, zeros)


class _SwarmTables:
    """Per-robot arrays of one robots sequence by address and length (what
    :func:`fastbatch.swarm_step` makes its views from: :mod:`fastviews`), with each
    robot's constant registers, heap geometry and latch groups. Valid while the robots
    are the same objects and no VM changed an array or constant
    (``packed_queues.GENERATION``)."""

    def __init__(self, robots: Sequence[Any], robot_type: type) -> None:
        self.robots = list(robots)
        count = len(robots)
        #: each robot's arrays (fastbatch.A_* order) by address and length (rows for the
        #: 2-D ones); ``kept`` holds them alive while the table is used
        self.addresses = np.zeros((count, fastbatch.ARRAYS), np.int64)
        self.sizes = np.zeros((count, fastbatch.ARRAYS), np.int64)
        self.kept: list[np.ndarray] = []
        self.geometry = np.zeros((count, 3), np.int64)
        self.registers = np.zeros((count, fastloop.REGISTERS), np.int64)
        self.groups = np.zeros((count, LATCH_SLOTS), np.int64)
        self.targets = np.zeros((count, LATCH_SLOTS), np.int64)
        #: one ``apply`` per latch group (equal applies share a group), and its argc
        self.applies: list[Any] = []
        self.argcs: list[int] = []
        self.max_out = 1
        #: (VM, heap, robot) of each robot the kernel may take (None for the others)
        self.machines: list[tuple[Any, Any, Any] | None] = []
        #: (latch array, readings) of each robot with readings (``host.ReadingHostFunction``)
        self.readings: list[tuple[np.ndarray, list[Any]] | None] = [None] * count
        #: (latch array, drawn functions and their first rows) of each robot with drawn host
        #: functions (``host.DrawnHostFunction``)
        self.drawn: list[tuple[np.ndarray, list[tuple[int, Any]]] | None] = [None] * count
        #: ``VM.hosted`` of each robot with readings while Python finishes its step
        self.hosted: list[tuple[np.ndarray, np.ndarray] | None] = [None] * count
        for i, robot in enumerate(robots):
            if type(robot) is not robot_type or robot.vm.stress_gc or not robot.booted:
                self.machines.append(None)
                continue
            vm = robot.vm
            h = vm.heap
            self.machines.append((vm, h, robot))
            packed = vm.packed()
            hosts = robot.compiled_hosts()
            slots = hosts.latched
            if hosts.readings:
                self.readings[i] = (packed.latch, hosts.readings)
                in_place = np.isin(hosts.table[:, fasthost.H_KIND], _IN_PLACE_FROM_PYTHON)
                self.hosted[i] = (np.ascontiguousarray(hosts.table[in_place]), packed.latch)
            if hosts.drawn:
                self.drawn[i] = (packed.latch, hosts.drawn)
            arrays = (h.view, vm._stack_view, np.frombuffer(vm.bcode, np.uint8), h.gc_info,
                      h.gc_traversed, packed.inq, packed.outq, packed.ring, packed.ctl,
                      packed.latch, np.ascontiguousarray(hosts.table, np.int64), packed.vstig)
            self.kept.extend(arrays)
            self.addresses[i] = [fastviews.address_of(array) for array in arrays]
            self.sizes[i] = [len(array) for array in arrays]
            self.geometry[i] = (h.obj_size, h.elems, h.reserved)
            self.registers[i] = vm.kernel_registers(None, None)
            for slot, fn in enumerate(slots):
                if fn is None:
                    continue
                if fn.apply not in self.applies:
                    self.applies.append(fn.apply)
                    self.argcs.append(fn.argc)
                self.groups[i, slot] = self.applies.index(fn.apply)
                self.targets[i, slot] = fn.target
            self.max_out = max(self.max_out, robot.profile.out_queue_cap + 1)
        # after the packings above: each robot's arrays were taken after its own
        self.generation = packed_queues.GENERATION[0]

    def valid_for(self, robots: Sequence[Any]) -> bool:
        return self.generation == packed_queues.GENERATION[0] \
            and len(robots) == len(self.robots) and all(map(is_, robots, self.robots))


#: the tables of the swarms stepped last (a few: tests and tools step several swarms)
_TABLES: list[_SwarmTables] = []
_TABLES_KEPT = 4


def _tables_for(robots: Sequence[Any], robot_type: type) -> _SwarmTables:
    for tables in _TABLES:
        if tables.valid_for(robots):
            return tables
    tables = _SwarmTables(robots, robot_type)
    _TABLES.insert(0, tables)
    del _TABLES[_TABLES_KEPT:]
    return tables


def control_steps(robots: Sequence[Any], deliveries: PackedMessages,
                  stepping: np.ndarray, robot_type: type) -> StepResult:
    """`swarm_batch.control_steps`, compiled where covered (see the module comment);
    ``robot_type``: `robot.Robot` (a wrapper of another type takes the reference calls)."""
    count = len(robots)
    failed_before = [r is not None and r.failure is not None for r in robots]
    ready = State.READY
    is_covered = [type(r) is robot_type and r.failure is None and r.booted
                  and not (vm := r.vm).stress_gc and vm.state is ready for r in robots]
    bounds = deliveries.bounds(count)
    starts = bounds.tolist()
    deferred = np.zeros(count, dtype=bool)  # receives the compiled step will make
    for index in np.flatnonzero(np.diff(bounds)).tolist():
        robot = robots[index]
        if robot is None:
            continue
        if is_covered[index] and _receives_compiled(robot):
            deferred[index] = True
        else:
            robot.receive_all(deliveries.tuples_of(starts[index], starts[index + 1]))
            is_covered[index] = covered(robot, robot_type)  # a receive may fail the robot
    stepping = np.asarray(stepping, dtype=bool)
    covered_mask = np.array(is_covered, dtype=bool)
    todo = np.flatnonzero(covered_mask & (stepping | deferred))
    for index in todo.tolist():  # first: a packing may allocate larger arrays
        vm = robots[index].vm
        if not vm._packed_live:
            vm.packed()
    tables = _tables_for(robots, robot_type) if len(todo) else None
    if tables is not None and any(tables.machines[i] is None for i in todo.tolist()):
        # a robot the tables left out is covered now (e.g. its stress mode switched off
        # without a new VM): build them again
        _TABLES.remove(tables)
        tables = _tables_for(robots, robot_type)
    outbox = _Outbox(len(todo) * (tables.max_out if tables else 1) + _SPARE_ROWS)
    phases = np.zeros(count, np.int64)
    ios = np.zeros((count, IO_SLOTS), np.int64)
    if tables is not None:
        _run_compiled(robots, tables, todo, stepping, deferred, deliveries, bounds, outbox,
                      phases, ios)
    # ---- Python, in robot order: hand-overs and the robots the kernel does not take
    python = np.flatnonzero((stepping | (phases == P_RECEIVE))
                            & (~covered_mask | (phases != 0)))
    for index in python.tolist():
        robot = robots[index]
        if robot is None:
            continue
        if not is_covered[index]:
            outbox.add(index, robot.control_step())
        elif phases[index] == P_RECEIVE:  # the rest of its receive, then its whole step
            robot.receive_all(deliveries.tuples_of(int(ios[index, IO_RECEIVED]),
                                                   starts[index + 1]))
            if stepping[index]:
                outbox.add(index, robot.control_step())
        else:
            vm = robot.vm
            vm.hosted = tables.hosted[index]  # its readings stand until a Python host call
            try:
                outbox.add(index, robot.finish_compiled_step(
                    int(phases[index]), tables.registers[index], ios[index]))
            finally:
                vm.hosted = None
    failed = np.array([r is not None and r.failure is not None and not was
                       for r, was in zip(robots, failed_before, strict=True)], dtype=bool)
    return StepResult(outbox.packed(sort=len(python) > 0), failed)


def _run_compiled(robots: Sequence[Any], tables: _SwarmTables, todo: np.ndarray,
                  stepping: np.ndarray, deferred: np.ndarray, deliveries: PackedMessages,
                  bounds: np.ndarray, outbox: _Outbox, phases: np.ndarray,
                  ios: np.ndarray) -> None:
    """The robots ``todo`` through :func:`fastbatch.swarm_step`: their registers in and
    out, latches applied, ``steps_done`` counted for those it finished."""
    chosen = [tables.machines[i] for i in todo.tolist()]
    none = fastloop.NONE
    values: list[int] = []  # the registers in one flat list (no tuple per robot)
    add = values.extend
    for vm, h, _robot in chosen:
        budget = vm.instruction_budget
        add((vm.pc, vm.stackptr, vm.blockptr, h.rtobj, h.ltseg, vm.lsyms, h.gc_runs,
             vm.instructions_executed, h.peak_used, none if budget is None else budget,
             h.truncated))
    before = np.array(values, np.int64).reshape(len(chosen), fastbatch.DYNAMIC)
    dynamic = np.empty((len(robots), fastbatch.DYNAMIC), np.int64)
    dynamic[todo] = before
    readings, drawn = tables.readings, tables.drawn
    steps = todo[stepping[todo]].tolist()
    for index in steps:  # only a step runs Buzz code
        if (mine := readings[index]) is not None:  # the reading rows, read now
            latch, functions = mine
            latch[LATCH_SLOTS:LATCH_SLOTS + len(functions)] = [f.row() for f in functions]
        if (draws := drawn[index]) is not None:  # the next calls' results, drawn ahead
            latch, functions = draws
            for first, fn in functions:
                latch[first:first + DRAWN_ROWS] = fn.rows(DRAWN_ROWS)
    pops = [robot.loop == "pop" for _vm, _h, robot in chosen]
    flags = np.zeros(len(robots), np.int64)
    flags[todo] = np.where(deferred[todo], F_RECEIVE, 0) | np.where(stepping[todo], F_STEP, 0) \
        | np.where(pops, F_POP, 0)
    kernel_args = (tables.addresses, tables.sizes, tables.geometry, tables.registers,
                   dynamic)
    # the kernel's argument types (no copy when the columns already are: the radio's are)
    rest = (flags, fastloop.RULES, np.ascontiguousarray(deliveries.payloads, np.uint8),
            np.ascontiguousarray(deliveries.lengths, np.int64),
            np.ascontiguousarray(deliveries.distances, np.float64),
            np.ascontiguousarray(deliveries.azimuths, np.float64),
            np.ascontiguousarray(deliveries.elevations, np.float64),
            np.ascontiguousarray(bounds, np.int64))
    chunks = _chunks(todo)
    outboxes = [outbox] + [_Outbox(len(part) * tables.max_out + _SPARE_ROWS)
                          for part in chunks[1:]]
    latched = [np.zeros((len(part) * LATCH_SLOTS, fastbatch.L_ARGS + LATCH_ARGS), np.int64)
               for part in chunks]

    def run(k: int) -> int:
        box = outboxes[k]
        return fastbatch.swarm_step(
            *kernel_args, chunks[k], *rest, box.payloads, box.lengths, box.robots,
            box.cursor, ios, phases, tables.groups, tables.targets, latched[k])

    if len(chunks) == 1:
        counts = [run(0)]
    else:  # the other chunks on worker threads (the kernels release the GIL), then in order
        futures = [_pool().submit(run, k) for k in range(1, len(chunks))]
        counts = [run(0)] + [f.result() for f in futures]
        for box in outboxes[1:]:
            outbox.extend(box)
    for index in steps:  # the streams moved on by the drawn rows the calls took
        if (draws := drawn[index]) is not None:
            latch, functions = draws
            for first, fn in functions:
                taken = int(np.count_nonzero(latch[first:first + DRAWN_ROWS, 0] == READ_TAKEN))
                if taken:
                    fn.skip(taken)
    rows_latched = np.concatenate([rows[:n] for rows, n in zip(latched, counts, strict=True)])
    n_latched = len(rows_latched)
    _write_back(chosen, before, dynamic[todo])
    finished = todo[(phases[todo] == 0) & stepping[todo]]
    for index in finished.tolist():
        robots[index].steps_done += 1
    # heap neighbor entries added (receive) less removed (data GC): the u8 count is Python's
    for index in np.flatnonzero(ios[:, IO_ADDED]).tolist():
        neighbors = tables.machines[index][0]._neighbors  # not `neighbors`: no unpacking
        neighbors.count = (neighbors.count + int(ios[index, IO_ADDED])) & 0xFF
    if n_latched:
        for group, apply in enumerate(tables.applies):
            mine = rows_latched[rows_latched[:, fastbatch.L_GROUP] == group]
            if len(mine):
                argc = tables.argcs[group]
                apply(mine[:, fastbatch.L_TARGET].copy(),
                      mine[:, fastbatch.L_ARGS:fastbatch.L_ARGS + argc].copy())


#: where each ``dynamic`` column (``fastbatch.D_*``) lives: (0 the VM, 1 its heap; attribute)
#: (the budget, column 9, is not the kernel's to change: None)
_REGISTER_HOMES = ((0, "pc"), (0, "stackptr"), (0, "blockptr"), (1, "rtobj"), (1, "ltseg"),
                   (0, "lsyms"), (1, "gc_runs"), (0, "instructions_executed"),
                   (1, "peak_used"), None, (1, "truncated"))


def _write_back(chosen: list[tuple[Any, Any, Any]], before: np.ndarray,
                after: np.ndarray) -> None:
    """The registers the kernel changed, back into the VMs and heaps of ``chosen`` (rows
    of ``before``/``after`` in its order; the budget is not the kernel's to change). Column
    by column and only where a value changed: after a whole step most robots' pc, stack and
    block pointers are what they were, and each attribute written is a store into an object
    the kernel's work has pushed out of the cache (a whole row per robot was ~1.6 µs)."""
    changed = after != before
    for column in np.flatnonzero(changed.any(axis=0)).tolist():
        place = _REGISTER_HOMES[column]
        if place is None:
            continue
        home, name = place
        rows = np.flatnonzero(changed[:, column])
        values = after[rows, column].tolist()
        if column == fastbatch.D_TRUNCATED:
            values = [bool(value) for value in values]
        for row, value in zip(rows.tolist(), values, strict=True):
            setattr(chosen[row][home], name, value)


#: threads of a swarm step's kernel part (robots' kernel parts are independent, so a swarm
#: split in contiguous index ranges gives the same result whatever the threads' timing).
#: 1 by default: a gain only when a core is free (on a shared 2-core machine two threads
#: lost wall time at load ~2.9 and gained at ~1), so it is the user's choice, `--threads`
#: (`set_threads`): a multi-core desktop has cores to spare; `world_bench.py` prints both.
THREADS = 1
#: the fewest robots per thread worth a thread's hand-off: the hand-off costs about one
#: robot's kernel step (~20 µs), so at 32 robots a part it is ~3 % of the part (100 gradient
#: Kilobots on 2 threads: ~1.45x the steps per second of one thread, +3-7 % CPU)
MIN_ROBOTS_PER_THREAD = 32
_POOL: list[ThreadPoolExecutor] = []


def set_threads(count: int) -> None:
    """Run the kernel part of every later swarm step on ``count`` (>= 1, checked by
    ``swarm_batch.set_threads``) threads: this one and ``count - 1`` pool threads; the pool
    is made again for a new count."""
    global THREADS
    if count != THREADS:
        for pool in _POOL:
            pool.shutdown(wait=True)
        _POOL.clear()
    THREADS = count


def _pool() -> ThreadPoolExecutor:
    if not _POOL:
        _POOL.append(ThreadPoolExecutor(max_workers=max(1, THREADS - 1),
                                        thread_name_prefix="swarm-step"))
    return _POOL[0]


def _chunks(todo: np.ndarray) -> list[np.ndarray]:
    """``todo`` in contiguous parts, one per thread (fewer for a small swarm)."""
    parts = max(1, min(THREADS, len(todo) // MIN_ROBOTS_PER_THREAD))
    return np.array_split(todo, parts)
