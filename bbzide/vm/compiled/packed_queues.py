"""A robot's message queues, XTREME neighbor ring and stigmergy entries as arrays, for the
compiled swarm step.

The reference routines (:mod:`messages`, :mod:`neighbors`) keep a queue as a list of
``bytearray`` records and the neighbor ring as a list of ``NeighborEntry`` objects: easy to
read, but a compiled routine cannot touch them, and packing them into arrays for every call
and copying them back cost more than the machine code they fed (measured: ~30 µs of a
Kilobot's ~160 µs VM step). :class:`PackedQueues` holds the same state as arrays that the
compiled swarm step (:mod:`fastbatch`) works on in place, and **only one of the two forms
holds the truth at a time**:

* ``VM.packed()`` makes the arrays the truth (packing the Python records if they were);
  the compiled step then reads and writes them across control steps with no copying;
* any Python access to ``vm.queues``, ``vm.neighbors`` or ``vm.vstig`` (a reference
  routine a robot hands back to, the inspector, a snapshot) first unpacks the arrays into
  the Python records and makes those the truth again (``VM`` properties); the next
  compiled step packs again.

So every observer sees exactly the state the reference routines would have left, and a
swarm nobody inspects never converts. Layouts (``ctl`` slots below): ``inq``/``outq`` are a
queue's ``CAP + 2`` records concatenated (record ``k`` at ``k * record``, the last one the
scratch record); ``ring`` has a row per neighbor slot (``fastreceive.NB_*`` columns);
``ctl`` holds the ring indices (the first six in :mod:`fastreceive`'s ``rings`` order, so
its routines work on ``ctl`` directly) and the scalars of ``NeighborsState`` the step reads.
Only an XTREME profile's ring rows are packed (the compiled step touches no other ring:
those profiles keep their neighbor data in the heap, where the compiled receive writes it;
``NeighborsState.count``, their u8 counter, stays Python's: the step adds its adds).
``vstig`` has a row per ``VstigStore`` entry (``VSTIG_COLUMNS``) and free rows after them
(``VSTIG_SPARE``) for the entries the compiled stigmergy loop learns.
"""

from __future__ import annotations

from array import array
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from bbzide.vm.messages import MessageQueues
    from bbzide.vm.neighbors import NeighborsState
    from bbzide.vm.profiles import Profile
    from bbzide.vm.vstig import VstigStore

# ``ctl`` slots: fastreceive's six ring slots first, then ours.
IN_START, IN_END, IN_SLOTS, NB_START, NB_END, NB_SLOTS = range(6)
OUT_START, OUT_END, OUT_SLOTS = 6, 7, 8
CLEAR_COUNTER, LISTENERS, ROBOT, RECORD = 9, 10, 11, 12
#: the profile's constants the step reads (set once: msg_in_proc_max, neighbors_mark_time,
#: neighbors_clr_period, xtreme, neighbors_floats)
MSG_MAX, MARK_TIME, CLEAR_PERIOD, XTREME, FLOATS = 13, 14, 15, 16, 17
#: ``neighbors.hpos``, the ``neighbors`` table (read by a heap profile's compiled receive)
HPOS = 18
#: the profile's ``lamport_threshold`` (set once), ``vstig.hpos`` (the stigmergy table),
#: the rows of ``vstig`` in use
LAMPORT, VSTIG_HPOS, VSTIG_ROWS = 19, 20, 21
#: ``vstig``'s address and rows, for a compiled ``v.get``/``v.put`` (``fasthost``:
#: ``fastviews``), and the profile's ``vstig_cap`` (set once: a local put's limit)
VSTIG_ADDRESS, VSTIG_CAPACITY, VSTIG_CAP = 22, 23, 24
#: slots in ``ctl``
CTL_SLOTS = 25

#: columns of a ``vstig`` row: ``VstigEntry``'s fields (key, value, timestamp, robot) —
#: fastvstig.ENTRY_COLUMNS
VSTIG_COLUMNS = 4
#: free ``vstig`` rows kept beyond the entries when packing: one step's in-queue of new
#: keys fits (a full table hands the message to Python, which packs a larger one next)
VSTIG_SPARE = 32

#: columns of a ring row: NeighborEntry's fields (robot, distance, azimuth, elevation,
#: mark) — fastreceive.RING_COLUMNS (not imported: fastreceive imports the VM's modules)
RING_COLUMNS = 5

#: the most arguments a latched host function may take (HostRegistry: LatchedHostFunction)
LATCH_ARGS = 4
#: latch slots of one robot (distinct latched host functions it registers)
LATCH_SLOTS = 4
#: rows of one drawn host function (``host.DrawnHostFunction``): the results of its next
#: calls, one a row. Eight: an M300's search draws up to eight random goals in a step
#: (examples/sar/sar.bzz ``next_goal``); a ninth call goes to Python.
DRAWN_ROWS = 8
#: reading slots of one robot (``host.ReadingHostFunction``: the rows after the latch
#: slots; a drawn function takes DRAWN_ROWS of them). Fourteen: an M300 reads five
#: (clock, position, flying, arrived, camera) and draws one (random_goal), one to spare;
#: each row costs a robot 40 bytes.
READING_SLOTS = 14
#: column 0 of a reading row: no reading (the kernel hands the call to Python), an int or a
#: record in columns 1..LATCH_ARGS, nil, or a drawn row a call has taken
READ_NONE, READ_VALUE, READ_NIL, READ_TAKEN = 0, 1, 2, 3


#: bumped whenever an array or constant register a compiled swarm step may have cached
#: for some VM can change (a VM built, its code set, a restore, a host registration, a
#: ring re-allocated): ``swarm_batch_fast`` rebuilds its per-swarm tables then
GENERATION = [0]


def arrays_changed() -> None:
    """Invalidate every compiled swarm step's cached per-robot tables."""
    GENERATION[0] += 1


class PackedQueues:
    """One robot's queues and neighbor ring as arrays (see the module comment)."""

    __slots__ = ("inq", "outq", "ring", "ctl", "latch", "vstig", "record", "xtreme",
                 "_packed_inq", "_packed_outq", "_packed_vstig")

    def __init__(self, profile: Profile, record: int) -> None:
        self.record = record
        #: only an XTREME ring is the compiled step's to touch (receive, data GC): the
        #: others' ring entries stay Python's and are neither packed nor unpacked
        self.xtreme = profile.xtreme
        self.inq = np.zeros((profile.in_queue_cap + 2) * record, np.uint8)
        self.outq = np.zeros((profile.out_queue_cap + 2) * record, np.uint8)
        self._packed_inq = self.inq.copy()
        self._packed_outq = self.outq.copy()
        self.ring = np.zeros((profile.neighbors_cap + 1, RING_COLUMNS), np.int64)
        self.ctl = np.zeros(CTL_SLOTS, np.int64)
        self.ctl[MSG_MAX:HPOS] = (profile.msg_in_proc_max, profile.neighbors_mark_time,
                                  profile.neighbors_clr_period, profile.xtreme,
                                  profile.neighbors_floats)
        self.ctl[LAMPORT] = profile.lamport_threshold
        self.ctl[VSTIG_CAP] = profile.vstig_cap
        #: the virtual stigmergy's entries (``VSTIG_COLUMNS``), rows ``ctl[VSTIG_ROWS]`` on
        #: free; and the rows as packed (`vstig_changes` compares)
        self._allocate_vstig(VSTIG_SPARE)
        self._packed_vstig = self.vstig[:0].copy()
        #: per latch slot: [set, arg 1 ... arg LATCH_ARGS] (the robot's latched functions);
        #: then per reading slot: [READ_*, value 1 ... value LATCH_ARGS] (its readings,
        #: written by the compiled swarm step before each kernel call)
        self.latch = np.zeros((LATCH_SLOTS + READING_SLOTS, 1 + LATCH_ARGS), np.int64)

    def pack(self, queues: MessageQueues, neighbors: NeighborsState, robot: int) -> None:
        """The Python records into the arrays (they become the truth)."""
        inbox, outbox, ring = queues.inbox, queues.outbox, neighbors.ring
        self.inq[:] = np.frombuffer(bytearray().join(inbox.records), np.uint8)
        self.outq[:] = np.frombuffer(bytearray().join(outbox.records), np.uint8)
        #: the records as packed: `unpack` writes back only the records that differ (an
        #: M300's 2 x 257 records one by one cost ~0.2 ms a hand-over; a step changes few)
        self._packed_inq = self.inq.copy()
        self._packed_outq = self.outq.copy()
        if self.xtreme:
            flat: list[int] = []
            for e in ring.records:
                flat += (e.robot, e.distance, e.azimuth, e.elevation, e.mark)
            if len(ring.records) != len(self.ring):
                self.ring = np.zeros((len(ring.records), RING_COLUMNS), np.int64)
                arrays_changed()
            self.ring[:] = np.frombuffer(array("q", flat), np.int64).reshape(-1, RING_COLUMNS)
        self.ctl[:MSG_MAX] = (inbox.start, inbox.end, inbox.capacity, ring.start, ring.end,
                              ring.capacity, outbox.start, outbox.end, outbox.capacity,
                              neighbors.clear_counter, neighbors.listeners, robot,
                              self.record)
        self.ctl[HPOS] = neighbors.hpos

    def pack_vstig(self, store: VstigStore) -> None:
        """The stigmergy entries into ``vstig`` (they become the truth with the queues)."""
        self.ctl[VSTIG_HPOS] = store.hpos
        if not store.entries and not len(self._packed_vstig):  # (most robots: no stigmergy)
            self.ctl[VSTIG_ROWS] = 0
            return
        rows = [(e.key, e.value, e.timestamp, e.robot) for e in store.entries]
        if len(rows) + VSTIG_SPARE > len(self.vstig):
            self._allocate_vstig(len(rows) + 2 * VSTIG_SPARE)
            arrays_changed()
        if rows:
            self.vstig[:len(rows)] = rows
        self._packed_vstig = self.vstig[:len(rows)].copy()
        self.ctl[VSTIG_ROWS] = len(rows)

    def _allocate_vstig(self, rows: int) -> None:
        """A new ``vstig`` of ``rows`` rows, its address and rows noted in ``ctl``."""
        self.vstig = np.zeros((rows, VSTIG_COLUMNS), np.int64)
        self.ctl[VSTIG_ADDRESS] = self.vstig.ctypes.data
        self.ctl[VSTIG_CAPACITY] = rows

    def vstig_in_use(self) -> np.ndarray:
        """The rows of ``vstig`` that hold entries (in ``VstigStore.entries`` order)."""
        return self.vstig[:int(self.ctl[VSTIG_ROWS])]

    def vstig_changes(self) -> tuple[list[tuple[int, list[int]]], list[list[int]]]:
        """What the compiled steps changed in the stigmergy entries since `pack_vstig`:
        (index, row) of each entry whose row differs, and the rows appended."""
        known = len(self._packed_vstig)
        if not known and not self.ctl[VSTIG_ROWS]:
            return [], []
        now = self.vstig[:known]
        changed = np.flatnonzero((now != self._packed_vstig).any(axis=1)).tolist()
        return ([(k, now[k].tolist()) for k in changed], self.vstig_in_use()[known:].tolist())

    def unpack(self, queues: MessageQueues, neighbors: NeighborsState) -> None:
        """The arrays back into the Python records (they become the truth again)."""
        n = self.record
        for now, packed, records in ((self.inq, self._packed_inq, queues.inbox.records),
                                     (self.outq, self._packed_outq, queues.outbox.records)):
            # the Python records still hold what was packed: only the changed ones move
            changed = np.flatnonzero((now != packed).reshape(-1, n).any(axis=1))
            for k in changed.tolist():
                records[k][:] = now[k * n:(k + 1) * n].tobytes()
        if self.xtreme:
            for e, row in zip(neighbors.ring.records, self.ring.tolist(), strict=True):
                e.robot, e.distance, e.azimuth, e.elevation, e.mark = row
        (queues.inbox.start, queues.inbox.end, neighbors.ring.start, neighbors.ring.end,
         queues.outbox.start, queues.outbox.end, neighbors.clear_counter) = self.indices()

    def indices(self) -> tuple[int, int, int, int, int, int, int]:
        """What `unpack` writes back besides the records: (inbox start, inbox end, ring
        start, ring end, outbox start, outbox end, the neighbors' clear counter)."""
        ctl = self.ctl.tolist()
        return (ctl[IN_START], ctl[IN_END], ctl[NB_START], ctl[NB_END], ctl[OUT_START],
                ctl[OUT_END], ctl[CLEAR_COUNTER])
