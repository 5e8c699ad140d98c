"""Message queues and the wire format of BittyBuzz (spec §F.4; ``bbzringbuf.c``,
``bbzinmsg.c``, ``bbzoutmsg.c``, ``bbzmsg.c``).

Design: the firmware keeps each queue as a ring buffer of ``CAP + 1`` slots (one always
unused) over an array of ``CAP + 2`` message records, the extra record being scratch
space. The records are a packed C union, so a record reused for another message type keeps
stale bytes of the previous one; and the out-queue has an overflow bug that copies stale
scratch bytes over the last queued message. To reproduce both faithfully a record is a
``bytearray`` laid out like the packed union:

    byte 0 type · 1-2 rid · broadcast: 3-4 topic, 5.. value object (S bytes)
                          · vstig:     3 lamport, 4-5 key, 6.. data object (S bytes)

and :class:`RingBuffer` moves whole records exactly as the C code does (``makeslot``,
``pop``, the insertion sort by type after every append). Wire payloads are at most 9 bytes
(Kilobot ``message_t.data[9]``; every BittyBuzz platform sends 9): ``type u8, rid u16``,
then broadcast ``topic u16, mdata u8, value u16`` or vstig ``key u16, mdata u8, value u16,
lamport u8``; little-endian (BittyBuzz defines ``htons`` as the identity).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Generic, TypeVar

from bbzide.vm.message_layout import (  # noqa: F401 - the wire format's names, re-exported
    BC_TOPIC,
    BC_VALUE,
    BROADCAST,
    PAYLOAD_RING_CAPACITY,
    PAYLOAD_SIZE,
    RID,
    SWARM,
    TYPE,
    VS_DATA,
    VS_KEY,
    VS_LAMPORT,
    VSTIG_PUT,
    VSTIG_QUERY,
)

if TYPE_CHECKING:
    pass

R = TypeVar("R")




def record_size(obj_size: int) -> int:
    """``sizeof(bbzmsg_t)``: the vstig member is the largest (6 bytes + one object)."""
    return VS_DATA + obj_size


class RingBuffer(Generic[R]):
    """``bbzringbuf_t`` over records: ``capacity`` slots, ``start``/``end`` as u8 indices."""

    def __init__(self, records: list[R], capacity: int) -> None:
        self.records = records      # at least capacity + 1 records (the last is scratch)
        self.capacity = capacity
        self.start = 0
        self.end = 0

    def clear(self) -> None:
        self.start = self.end = 0

    def size(self) -> int:
        if self.end >= self.start:
            return self.end - self.start
        return self.capacity - (self.start - self.end)

    def full(self) -> bool:
        return self.size() + 1 == self.capacity

    def empty(self) -> bool:
        return self.start == self.end

    def raw_index(self, idx: int) -> int:
        """``bbzringbuf_rawat``: wrap by repeated subtraction (u8 index) — the remainder."""
        return (idx & 0xFF) % self.capacity

    def index_at(self, i: int) -> int:
        """``bbzringbuf_at``: the u8 sum ``start + i`` wrapped."""
        return ((i + self.start) & 0xFF) % self.capacity

    def at(self, i: int) -> R:
        return self.records[((i + self.start) & 0xFF) % self.capacity]

    def indices(self) -> list[int]:
        """Raw indices of the queued records, head first (``index_at(0..size-1)``)."""
        start, cap = self.start, self.capacity
        return [((i + start) & 0xFF) % cap for i in range(self.size())]

    def pop(self) -> bool:
        if self.empty():
            return False
        self.start = self.raw_index(self.start + 1)
        return True

    def makeslot(self) -> int:
        slot = self.end
        if not self.full():
            self.end = self.raw_index(self.end + 1)
        else:
            self.end = self.start
            self.start = self.raw_index(self.start + 1)
        return slot

    def swap(self, i: int, j: int) -> None:
        """``bbzutil_swapArrays`` of the records at logical positions i and j (exchanging
        the list items is the same as swapping their bytes: nobody keeps a reference to a
        record in the ring across a swap)."""
        a, b = self.index_at(i), self.index_at(j)
        self.records[a], self.records[b] = self.records[b], self.records[a]

    def sort_by_type(self) -> None:
        """``bbzmsg_sort_priority``: stable insertion sort by message type. An insertion
        sort that swaps while the left neighbour is strictly greater is a stable sort, so
        the records are put in ``sorted`` order (Python's sort is stable) — and left alone
        when already in order, the common case (always so for 0 or 1 record: a Kilobot's
        out-queue after its one broadcast of a step)."""
        if self.end == self.start or ((self.start + 1) & 0xFF) % self.capacity == self.end:
            return
        where = self.indices()
        records = self.records
        queued = [records[k] for k in where]
        types = [r[TYPE] for r in queued]  # type: ignore[index]
        if types == sorted(types):
            return
        order = sorted(range(len(queued)), key=types.__getitem__)
        for k, j in zip(where, order, strict=True):
            records[k] = queued[j]


@dataclass
class MessageQueues:
    """``vm->inmsgs`` / ``vm->outmsgs``: CAP+2 records each, rings of CAP+1 slots."""

    in_capacity: int
    out_capacity: int
    obj_size: int = 9
    inbox: RingBuffer[bytearray] = field(init=False)
    outbox: RingBuffer[bytearray] = field(init=False)

    def __post_init__(self) -> None:
        n = record_size(self.obj_size)
        self.inbox = RingBuffer([bytearray(n) for _ in range(self.in_capacity + 2)],
                                self.in_capacity + 1)
        self.outbox = RingBuffer([bytearray(n) for _ in range(self.out_capacity + 2)],
                                 self.out_capacity + 1)

    def clear(self) -> None:
        self.inbox.clear()
        self.outbox.clear()

    # ---- decoded views (inspector) -------------------------------------------------------
    def in_messages(self) -> list[bytes]:
        """Queued incoming messages, head first, as wire payloads."""
        return [serialize(self.inbox.at(i), self.obj_size) for i in range(self.inbox.size())]

    def out_messages(self) -> list[bytes]:
        """Queued outgoing messages, head first, as the payloads they will be sent as."""
        return [serialize(self.outbox.at(i), self.obj_size) for i in range(self.outbox.size())]


# ---- record fields --------------------------------------------------------------------
def _u16(rec: bytearray, off: int) -> int:
    return rec[off] | (rec[off + 1] << 8)


def _set_u16(rec: bytearray, off: int, value: int) -> None:
    rec[off] = value & 0xFF
    rec[off + 1] = (value >> 8) & 0xFF


def rec_type(rec: bytearray) -> int:
    return rec[TYPE]


def rec_rid(rec: bytearray) -> int:
    return _u16(rec, RID)


def rec_topic(rec: bytearray) -> int:
    return _u16(rec, BC_TOPIC)


def rec_key(rec: bytearray) -> int:
    return _u16(rec, VS_KEY)


def rec_lamport(rec: bytearray) -> int:
    return rec[VS_LAMPORT]


def rec_value(rec: bytearray, obj_size: int) -> bytes:
    """The object copy (S bytes) a broadcast or vstig record carries."""
    off = BC_VALUE if rec[TYPE] == BROADCAST else VS_DATA
    return bytes(rec[off:off + obj_size])


# ---- serialisation (bbzoutmsg_queue_first) ---------------------------------------------
def serialize(rec: bytearray, obj_size: int) -> bytes:
    """The payload the firmware sends for a record (a table value stops after the rid)."""
    t = rec[TYPE]
    out = bytearray([t, rec[RID], rec[RID + 1]])
    if t == BROADCAST:
        value = rec[BC_VALUE:BC_VALUE + obj_size]
        if value[0] & 7 == 4:  # bbztype_istable: only type, rid are sent
            return bytes(out)
        out += rec[BC_TOPIC:BC_TOPIC + 2] + value[:3]
    elif t in (VSTIG_PUT, VSTIG_QUERY):
        data = rec[VS_DATA:VS_DATA + obj_size]
        if data[0] & 7 == 4:
            return bytes(out)
        out += rec[VS_KEY:VS_KEY + 2] + data[:3] + bytes([rec[VS_LAMPORT]])
    return bytes(out)


# ---- in-queue (bbzinmsg_queue_append / extract) ----------------------------------------
def _read_object(m: bytearray, at: int, payload: bytes) -> None:
    """The serialised object at payload byte 5 (metadata, then 2 payload bytes when the
    message holds them) into record bytes ``at`` ...; the object is marked valid (0x08)."""
    m[at] = payload[5]
    if len(payload) >= 8:
        m[at + 1:at + 3] = payload[6:8]
    m[at] |= 0x08


def inmsg_append(queues: MessageQueues, payload: bytes) -> bool:
    """Decode ``payload`` into the scratch record and queue it; False when dropped.

    Truncated payloads and unknown or disabled types (SWARM: swarm-list broadcasts are
    disabled in every reference configuration) are dropped, as the firmware does. The
    decoded object gets its valid bit forced on; its bytes beyond the 2 payload bytes keep
    whatever the scratch record held (stale, as on the robot).
    """
    q = queues.inbox
    payload = payload[:PAYLOAD_RING_CAPACITY - 1]
    m = q.records[q.capacity]
    n = len(payload)
    m[TYPE] = 0
    if n < 1:
        return False
    m[TYPE] = payload[0]
    if n < 3:
        return False
    m[RID:RID + 2] = payload[1:3]
    t = payload[0]
    if t == BROADCAST:
        if n < 5:
            return False
        m[BC_TOPIC:BC_TOPIC + 2] = payload[3:5]
        if n < 6:
            return False
        _read_object(m, BC_VALUE, payload)
        if n < 8:
            return False
    elif t in (VSTIG_PUT, VSTIG_QUERY):
        if n < 5:
            return False
        m[VS_KEY:VS_KEY + 2] = payload[3:5]
        if n < 6:
            return False
        _read_object(m, VS_DATA, payload)
        if n < 9:
            return False
        m[VS_LAMPORT] = payload[8]
    else:
        return False
    if t == BROADCAST:
        records = q.records
        key = m[TYPE:BC_TOPIC + 2]  # type, rid, topic: contiguous (TYPE = 0 ... 4)
        for k in q.indices():
            rec = records[k]
            if rec[TYPE:BC_TOPIC + 2] == key:
                rec[:] = m
                return True
    if q.full():
        q.records[q.raw_index(q.end - 1 + q.capacity)][:] = m
    else:
        q.records[q.raw_index(q.makeslot())][:] = m
    q.sort_by_type()
    return True


def inmsg_extract(queues: MessageQueues) -> bytearray:
    """Copy the head into the scratch record, pop it, return the scratch record."""
    q = queues.inbox
    scratch = q.records[q.capacity]
    scratch[:] = q.at(0)
    q.pop()
    return scratch


# ---- out-queue (bbzoutmsg_queue_append_*) ----------------------------------------------
def _out_template(queues: MessageQueues) -> bytearray:
    """``outmsg_queue_append_template``, overflow bug included (spec §F.4)."""
    q = queues.outbox
    m = q.records[q.raw_index(q.end)]
    if q.full():
        q.records[q.raw_index(q.end - 1 + q.capacity)][:] = m
    else:
        q.makeslot()
    return m


def outmsg_append_broadcast(queues: MessageQueues, rid: int, topic: int,
                            value_obj: bytes) -> None:
    m = _out_template(queues)
    m[TYPE] = BROADCAST
    _set_u16(m, RID, rid)
    _set_u16(m, BC_TOPIC, topic)
    m[BC_VALUE:BC_VALUE + len(value_obj)] = value_obj
    queues.outbox.sort_by_type()


def outmsg_append_vstig(queues: MessageQueues, typ: int, rid: int, key: int,
                        value_obj: bytes, lamport: int) -> None:
    m = _out_template(queues)
    m[TYPE] = typ
    _set_u16(m, RID, rid)
    m[VS_LAMPORT] = lamport & 0xFF
    _set_u16(m, VS_KEY, key)
    m[VS_DATA:VS_DATA + len(value_obj)] = value_obj
    queues.outbox.sort_by_type()


def outmsg_first(queues: MessageQueues) -> bytes:
    """``bbzoutmsg_queue_first``: the head serialised (call only when not empty)."""
    return serialize(queues.outbox.at(0), queues.obj_size)


def outmsg_next(queues: MessageQueues) -> None:
    queues.outbox.pop()


def drain_outbox(queues: MessageQueues) -> list[bytes]:
    """Send everything queued, head first (what a platform's transmit loop does)."""
    sent = []
    while not queues.outbox.empty():
        sent.append(outmsg_first(queues))
        outmsg_next(queues)
    return sent
