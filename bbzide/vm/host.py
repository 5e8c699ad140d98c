"""Host (C-closure) functions: Python callables that stand for BittyBuzz C functions
(spec §E.2 closure objects, §E.8 calls).

A C closure in the heap stores a function *address* in its pointer-sized payload. To be
byte-faithful on the PC profile the model stores exactly the addresses the reference host
build stored (corpus ``bbz/pc_cfunctions.tsv``: the library closures of the x86-64
harness, linked -no-pie). On other profiles the same numbers are stored truncated to the
pointer width; the corpus masks C-closure payloads anyway (README §5 level (a)).

A host function is called as ``fn(vm)`` from ``callc``, exactly where the firmware calls the
C function: the activation record (``vm.lsyms``) holds self at 0 and the arguments at
1..n. It reads them with ``vm.lload(i)`` / ``vm.lsym(i)``, may allocate through the VM
helpers (``vm.push_int`` ...), raises an error with ``vm.seterror(Error.X)`` and must end
with ``vm.ret0()`` or ``vm.ret1()`` (ret1 returns the top of the stack).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from bbzide.compiler import bbzfloat
from bbzide.vm.heap import CLOSURE, FLOAT, INT, STRING, TABLE
from bbzide.vm.heap import NIL as TNIL
from bbzide.vm.kernels import fasthost, kernels_now, packed_queues
from bbzide.vm.states import Error

if TYPE_CHECKING:
    from bbzide.vm.vm import VM

HostFunction = Callable[["VM"], None]

#: Addresses of the BittyBuzz library functions in the reference PC harness.
LIBRARY_ADDRESSES: dict[str, int] = {
    "h_print": 0x401ADD, "h_ret0": 0x401B8E, "h_ret0_a0": 0x401B9F, "h_ret0_a1": 0x401BD6,
    "h_ret0_a2": 0x401C0D, "h_ret0_a3": 0x401C44, "h_retnil": 0x401C7B, "h_rand": 0x401C96,
    "h_min": 0x401CD4, "h_reti": 0x401D94,
    "bbzneighbors_broadcast": 0x4080A4, "bbzneighbors_listen": 0x408137,
    "bbzneighbors_ignore": 0x40822D, "bbzneighbors_foreach": 0x408351,
    "bbzneighbors_map": 0x4085E6, "bbzneighbors_filter": 0x408678,
    "bbzneighbors_reduce": 0x40874F, "bbzneighbors_get": 0x408AC3,
    "bbzneighbors_count": 0x408B79,
    "table_foreach": 0x409BBF, "table_map": 0x409EDC, "table_filter": 0x409F62,
    "table_reduce": 0x40A045, "table_size": 0x40A179,
    "bbzvstig_create": 0x40E106, "bbzvstig_onconflict": 0x40E20F,
    "bbzvstig_onconflictlost": 0x40E2B1, "bbzvstig_get": 0x40E353, "bbzvstig_put": 0x40E59D,
    "bbzvstig_size": 0x40EAC7,
    "bbzswarm_create": 0x40EEB9, "bbzswarm_id": 0x40EF53, "bbzswarm_join": 0x40F08B,
    "bbzswarm_leave": 0x40F0FE, "bbzswarm_in": 0x40F171, "bbzswarm_select": 0x40F2E7,
    "bbzswarm_unselect": 0x40F328, "bbzswarm_exec": 0x40F369,
}

#: First address handed to host functions that have no reference address.
_FIRST_FREE_ADDRESS = 0x500000


@dataclass
class RegisteredHostFunction:
    """One registered host function: its symbol, the address stored in the heap, the code."""

    symbol: str
    address: int
    function: HostFunction


class HostRegistry:
    """Address ↔ host function map of one VM (addresses masked to the pointer width)."""

    def __init__(self, ptr_size: int) -> None:
        self.ptr_size = ptr_size
        self.mask = (1 << (8 * ptr_size)) - 1
        self.by_address: dict[int, RegisteredHostFunction] = {}
        self.by_symbol: dict[str, RegisteredHostFunction] = {}
        self._next_free = _FIRST_FREE_ADDRESS
        #: bumped by every registration (``Robot.compiled_hosts`` caches on it)
        self.version = 0
        #: `register_all`'s last answer per tuple of functions, with the version it was for
        self._registered_all: dict[tuple[tuple[str, HostFunction], ...],
                                  tuple[int, np.ndarray]] = {}
        #: host functions a kernel computes in place, by symbol: (``fasthost.HOST_*`` kind,
        #: argument count); see `computed_rows`
        self.computed: dict[str, tuple[int, int]] = {}
        #: a computed host function's table of values, by symbol (`LookupHostFunction`)
        self._tables: dict[str, np.ndarray] = {}
        self._computed_rows: tuple[int, np.ndarray] | None = None

    def register(self, symbol: str, function: HostFunction, address: int | None = None) -> int:
        """Register ``function`` under ``symbol``; returns the address to store in the heap."""
        if address is None:
            address = LIBRARY_ADDRESSES.get(symbol)
        if address is None:
            address = self._next_free
            self._next_free += 0x40
        address &= self.mask
        known = self.by_address.get(address)
        if known is not None and known.symbol == symbol and known.function is function \
                and self.by_symbol.get(symbol) is known:
            # the same registration again (every neighbors.map/filter adds the library's
            # closures to the table it returns): nothing changes, so the caches built on
            # `version` and the compiled swarm step's tables stay valid
            return address
        call = RegisteredHostFunction(symbol, address, function)
        self.by_address[address] = call
        self.by_symbol[symbol] = call
        self.version += 1
        packed_queues.arrays_changed()
        return address

    def register_all(self, functions: tuple[tuple[str, HostFunction], ...]) -> np.ndarray:
        """`register` each (symbol, function) in turn; their addresses as int64. Registering
        the same functions again changes nothing, so while `version` holds (no registration
        since) the last answer for the same tuple is the answer (a library that adds its
        methods to every table it returns asks for it on every call)."""
        known = self._registered_all.get(functions)
        if known is not None and known[0] == self.version:
            return known[1]
        addresses = np.array([self.register(symbol, function) for symbol, function in functions],
                             np.int64)
        self._registered_all[functions] = (self.version, addresses)
        return addresses

    def lookup(self, address: int) -> RegisteredHostFunction | None:
        return self.by_address.get(address & self.mask)

    def mark_computed(self, symbol: str, kind: int, argc: int,
                      values: np.ndarray | None = None) -> None:
        """The host function registered as ``symbol`` is one a kernel computes itself
        (``fasthost`` kind ``kind``, ``argc`` arguments): e.g. a `RoundedDistanceHostFunction`;
        ``values``: a `LookupHostFunction`'s table (int64, kept here while marked)."""
        self.computed[symbol] = (kind, argc)
        if values is not None:
            self._tables[symbol] = values
        self._computed_rows = None

    def computed_rows(self) -> np.ndarray:
        """``fasthost``'s ``hosts`` rows (address, pointer size, kind, 0, argument count)
        of the marked host functions as registered now: the ones a kernel may run in place
        even with the queues unpacked, since they touch none. Cached until a registration."""
        cached = self._computed_rows
        if cached is not None and cached[0] == self.version:
            return cached[1]
        no_keys = (-1,) * (fasthost.HOST_COLUMNS - fasthost.H_KEYS - 1)
        rows = []
        for symbol, (kind, argc) in self.computed.items():
            call = self.by_symbol.get(symbol)
            if call is None or self.by_address.get(call.address) is not call:
                continue
            # a table's address in the slot column and its length in the first key column
            table = self._tables.get(symbol)
            address, length = (0, -1) if table is None else (table.ctypes.data, len(table))
            rows.append((call.address, self.ptr_size, kind, address, argc, length, *no_keys))
        table = np.array(rows, np.int64).reshape(-1, fasthost.HOST_COLUMNS)
        self._computed_rows = (self.version, table)
        return table


NIL = None  # the Buzz nil as a decoded argument / return value


class HostCall:
    """The contract-level view of one C-closure call (ARCHITECTURE.md "vm → worlds, ui").

    Wraps the VM inside ``callc``: decoded arguments, ``expect_args`` (LNUM), ``ret`` and
    ``fail``. ``ret`` must be called at most once; when never called, ``finish`` does ret0.
    """

    def __init__(self, vm: VM, strings: list[str] | None = None) -> None:
        self.vm = vm
        self.robot_id = vm.robot
        self.strings = strings or []
        self._done = False

    @property
    def arg_count(self) -> int:
        from bbzide.vm.tables import darray_elements

        return len(darray_elements(self.vm.heap, self.vm.lsyms)) - 1

    def arg_index(self, i: int) -> int:
        """Heap index of argument i (1-based; 0 = self)."""
        return self.vm.lsym(i)

    def arg(self, i: int) -> object:
        """Argument i decoded: None, int, float, string name, or ("table"/"closure", index)."""
        h = self.vm.heap
        o = self.vm.lsym(i)
        t = h.obj_type(o)
        if t == TNIL:
            return None
        if t == INT:
            return h.int_value(o)
        if t == FLOAT:
            return bbzfloat.to_float(h.u16(o))
        if t == STRING:
            sid = h.u16(o)
            return self.strings[sid] if sid < len(self.strings) else sid
        if t == TABLE:
            return ("table", o)
        if t == CLOSURE:
            return ("closure", o)
        return ("userdata", o)

    @property
    def args(self) -> list[object]:
        return [self.arg(i) for i in range(1, self.arg_count + 1)]

    def expect_args(self, n: int) -> bool:
        return self.vm.assert_lnum(n)

    def ret(self, value: object = None) -> None:
        vm = self.vm
        self._done = True
        if value is None:
            vm.push_nil()
        elif isinstance(value, bool | int):
            vm.push_int(int(value))
        elif isinstance(value, float):
            vm.push_float(bbzfloat.from_float(value))
        elif isinstance(value, dict):
            if not self._int_record_compiled(value):
                t = vm.push_table()
                for k, v in value.items():
                    key = vm.new_string_obj(self.strings.index(k))
                    val = vm.new_int(v) if isinstance(v, int) \
                        else vm.new_float(bbzfloat.from_float(v))
                    vm.table_put_raw(t, val, key)
        else:
            vm.push_nil()
        vm.ret1()

    def _int_record_compiled(self, record: dict[str, Any]) -> bool:
        """The table of a dict of ints pushed by a kernel (``fasthost.push_int_record``:
        the same allocations and puts) in the fast mode; False, with nothing done, when
        Python must build it (a float, no room, the reference mode)."""
        vm = self.vm
        if not kernels_now(vm) or not all(isinstance(v, int) for v in record.values()):
            return False
        sids = np.array([self.strings.index(k) for k in record], np.int64)
        values = np.array([int(v) & 0xFFFF for v in record.values()], np.int64)
        heap = vm.heap
        regs = vm.kernel_registers(None, None)
        if not fasthost.push_int_record(heap.view, vm._stack_view, regs, sids, values,
                                        heap.obj_size, heap.elems, heap.reserved):
            return False
        vm.take_kernel_registers(regs)
        return True

    def ret_object(self, index: int) -> None:
        """Return an existing heap object (by index) unchanged, as ``bbzvm_push(x); ret1``."""
        self._done = True
        self.vm.push(index)
        self.vm.ret1()

    def fail(self, kind: str) -> None:
        self._done = True
        self.vm.seterror(Error[kind])

    def finish(self) -> None:
        if not self._done and self.vm.state.name == "READY":
            self.vm.ret0()


@dataclass(frozen=True)
class LatchedHostFunction:
    """A world host function whose **only effect is to store its int arguments as state of
    its own robot** that no host function reads during a control step (a Kilobot's ``led``:
    the colour of its LED). Called from Python it is ``function`` as usual. A compiled
    swarm step (``swarm_batch``) may instead, on its happy path — exactly ``argc`` int
    arguments —, latch the arguments in the robot's VM and ``ret0`` without leaving
    machine code (``fasthost``); after the step it calls ``apply(targets, values)`` once
    for every robot whose latch was written (``targets``: their ``target`` values;
    ``values``: int64[k, argc], each robot's last call), and it applies a robot's latch
    before that robot runs any Python code of the same step, so the order of stores is
    the order of calls. Anything unusual (another argument count, a non-int, an int not
    ``below`` its bound) is Python's: ``function`` then reports it as it always does. A
    function each of whose calls counts, not only the last (an M300's ``set_role``: the
    world counts role changes), is latched ``once``: the kernel hands a second call of the
    same step to Python, after the first call's latch is applied. A reading of the state it
    stores (an M300's ``arrived()`` reads what ``goto`` stores) names it in its
    ``stale_after``.

    Why it is exact: a store of the last call's arguments, applied before anything else
    of that robot could store or read the same state, leaves the state ``function``
    would have left; latched once, the one call is applied as ``function`` would do it.
    """

    function: Callable[[HostCall], None]
    argc: int
    #: what ``apply`` gets for this robot (the world's index of the robot)
    target: int
    apply: Callable[[Any, Any], None]
    #: every argument's exclusive upper bound on the kernel's path (the lower one is 0;
    #: None: any int): for a function that fails some ints (a recording, which replays a
    #: latched call as its ``ret0``, takes such a function as an ordinary one)
    below: int | None = None
    #: at most one call a step is latched (a second one goes to Python)
    once: bool = False

    def __call__(self, call: HostCall) -> None:
        self.function(call)


@dataclass(frozen=True)
class RoundedDistanceHostFunction:
    """A world host function ``distance(x1, y1, x2, y2)`` returning
    ``round(hypot(x1 - x2, y1 - y2))``, nothing else (an M300's, in decimetres). Called from
    Python it is ``function`` as usual; a kernel (``fasthost``, kind ``HOST_DISTANCE``) may
    instead compute it in place on its happy path — four int arguments, a result within an
    int16, room for it — and hand anything else to ``function``, which reports it as it
    always does. Exact because the result is a function of the arguments alone, computed
    in integers (``fasthost.rounded_distance``), and ``ret1`` of a fresh int is what
    ``HostCall.ret`` does with it.
    """

    function: Callable[[HostCall], None]
    #: its arguments: x1, y1, x2, y2
    argc: int = 4

    def __call__(self, call: HostCall) -> None:
        self.function(call)


#: what a reading reads: an int, nil (None), or a record's ints in its `keys` order
Reading = int | tuple[int, ...] | None


@dataclass(frozen=True)
class ReadingHostFunction:
    """A world host function of no arguments that returns a **reading of its own robot's
    state** — an int, nil, or a record of ints under fixed field names (an M300's
    ``clock()``, ``position()``, ``camera()``) — which nothing changes during a control
    step before that robot's first host call made in Python. Called from Python it pushes
    ``read()`` as ``HostCall.ret`` does (a record as the dict of ``keys`` and values). A
    compiled swarm step (``swarm_batch``) instead calls ``read()`` for the robot just before
    its kernel part (`row`), and the kernel (``fasthost``) pushes that value in place; any
    call with arguments, or a reading `row` could not encode, goes to Python.

    Why it is exact: the kernel part of a robot's step runs before any Python code of that
    step (a hand-over finishes it in Python), so the value read before it is the value the
    Python call would read at that moment — the contract above.
    """

    #: the reading now (no effect of its own: it may be called more than once a step)
    read: Callable[[], Reading]
    #: the record's field names, in the order ``HostCall.ret`` puts them (empty: an int)
    keys: tuple[str, ...] = ()
    #: the latched host functions (``LatchedHostFunction``, by name) that store what it
    #: reads: once one of them is called in a step, the kernel leaves this reading to
    #: Python, which runs after that call's latch is applied (and once the latch is
    #: applied its row is emptied, for a step that goes on in Python)
    stale_after: tuple[str, ...] = ()

    def __call__(self, call: HostCall) -> None:
        value = self.read()
        if self.keys and value is not None:
            call.ret(dict(zip(self.keys, value, strict=True)))  # type: ignore[arg-type]
        else:
            call.ret(value)

    def row(self) -> tuple[int, ...]:
        """The reading as a robot's reading row (``packed_queues.READ_*`` and up to
        ``LATCH_ARGS`` values masked to 16 bits, as ``VM.new_int`` stores them); no reading
        when ``read`` fails or answers what this function does not return as declared
        (Python's call then does what it always does)."""
        width = packed_queues.LATCH_ARGS
        try:
            value = self.read()
        except Exception:  # noqa: BLE001 -- the Python call raises it again, guarded
            return (packed_queues.READ_NONE,) + (0,) * width
        if value is None:
            return (packed_queues.READ_NIL,) + (0,) * width
        if not self.keys and type(value) is int:
            return (packed_queues.READ_VALUE, value & 0xFFFF) + (0,) * (width - 1)
        if self.keys and type(value) is tuple and len(value) == len(self.keys) \
                and all(type(v) is int for v in value):
            return (packed_queues.READ_VALUE, *(v & 0xFFFF for v in value)) \
                + (0,) * (width - len(value))
        return (packed_queues.READ_NONE,) + (0,) * width


@dataclass(frozen=True)
class DrawnHostFunction:
    """A world host function of no arguments whose result is a **record of ints drawn from
    its robot's own random stream**, and nothing else (an M300's ``random_goal()``: a
    uniform point of the field and its belief cell). Called from Python it is ``function``
    as usual, which draws. A compiled swarm step (``swarm_batch``) instead writes the
    results of the next ``packed_queues.DRAWN_ROWS`` calls as the robot's drawn rows before
    its kernel part (``ahead``: computed by the same code, the stream left as it was); the
    kernel (``fasthost``) pushes one per call, in order, and marks it taken; after that
    part the swarm step moves the stream on as that many calls would (``skip``), before the
    robot runs any Python code of the step. A call past the last row goes to Python.

    Why it is exact: the kernel's calls return the values the same calls would have drawn,
    in order, and the stream ends where those calls would have left it.
    """

    function: Callable[[HostCall], None]
    #: the record's field names, in the order ``HostCall.ret`` puts them
    keys: tuple[str, ...]
    #: the next `count` calls' results (each the record's ints in `keys` order), the
    #: stream left as it is; the same object while the stream has not moved
    ahead: Callable[[int], tuple[tuple[int, ...], ...]]
    #: the stream moved on as `count` calls move it
    skip: Callable[[int], None]
    #: the last results `rows` turned into rows, and those rows
    _rows: list[Any] = field(default_factory=lambda: [None, None], compare=False)

    def __call__(self, call: HostCall) -> None:
        self.function(call)

    def rows(self, count: int) -> np.ndarray:
        """The next `count` calls' results as drawn rows (``packed_queues.READ_VALUE`` and
        the ints masked to 16 bits, as ``VM.new_int`` stores them)."""
        results = self.ahead(count)
        if self._rows[0] is not results:
            rows = np.zeros((count, 1 + packed_queues.LATCH_ARGS), np.int64)
            rows[:, 0] = packed_queues.READ_VALUE
            rows[:, 1:1 + len(self.keys)] = np.array(results, np.int64).reshape(
                count, len(self.keys)) & 0xFFFF
            self._rows[:] = results, rows
        return self._rows[1]


@dataclass(frozen=True)
class LookupHostFunction:
    """A world host function of one number whose result, for every int argument ``a``, is
    ``values[min(max(a, 0), len(values) - 1)]``, an int within an int16, and nothing else
    (an M300's ``prior(cell)``: the belief map's percentages; ``missed(flown)``: the miss
    probability, a table long enough to reach its limit). Called from Python it is
    ``function`` as usual; a kernel (``fasthost``, kind ``HOST_LOOKUP``) may instead look
    the value up in place on its happy path — one int argument, room for the result — and
    hand anything else (a float, another argument count) to ``function``. Exact because
    the world builds ``values`` from the very computation ``function`` makes for ints.
    """

    function: Callable[[HostCall], None]
    #: int64, C-contiguous, never changed (a kernel reads it by address)
    values: np.ndarray
    argc: int = 1

    def __call__(self, call: HostCall) -> None:
        self.function(call)
