"""Message queues (spec §F.4): ring-buffer arithmetic, the in-queue's replacement and
priority rules, truncated payloads, and the out-queue overflow bug of the firmware."""

from __future__ import annotations

from bbzide.vm import messages
from bbzide.vm.messages import MessageQueues, RingBuffer

INT_OBJ = bytes([0x09, 5, 0]) + bytes(6)  # an int object (valid), value 5, 9-byte slot


def bc(rid: int, topic: int, value: int = 5) -> bytes:
    return bytes([0, rid, 0, topic, 0, 0x09, value, 0])


def vput(rid: int, key: int, lamport: int = 1) -> bytes:
    return bytes([1, rid, 0, key, 0, 0x09, 7, 0, lamport])


def test_ring_keeps_one_slot_free_and_drops_the_oldest_when_full() -> None:
    ring = RingBuffer([0] * 4, 4)
    for value in range(3):
        ring.records[ring.makeslot()] = value
    assert ring.size() == 3 and ring.full()
    ring.records[ring.raw_index(ring.makeslot())] = 3
    assert ring.size() == 3
    assert [ring.at(i) for i in range(3)] == [1, 2, 3]


def test_in_queue_replaces_a_broadcast_of_the_same_robot_and_topic() -> None:
    q = MessageQueues(10, 10)
    assert messages.inmsg_append(q, bc(1, 50, value=5))
    assert messages.inmsg_append(q, bc(2, 50, value=6))
    assert messages.inmsg_append(q, bc(1, 50, value=9))
    assert q.in_messages() == [bc(1, 50, value=9), bc(2, 50, value=6)]


def test_in_queue_is_ordered_by_type() -> None:
    q = MessageQueues(10, 10)
    messages.inmsg_append(q, vput(3, 51))
    messages.inmsg_append(q, bc(1, 50))
    assert [m[0] for m in q.in_messages()] == [0, 1]


def test_truncated_and_unknown_payloads_are_dropped() -> None:
    q = MessageQueues(10, 10)
    assert not messages.inmsg_append(q, bc(1, 50)[:7])
    assert not messages.inmsg_append(q, vput(1, 50)[:8])
    assert not messages.inmsg_append(q, bytes([3, 1, 0, 1, 0, 1]))  # swarm: disabled
    assert not messages.inmsg_append(q, b"")
    assert q.inbox.size() == 0


def test_full_in_queue_overwrites_its_last_message() -> None:
    q = MessageQueues(10, 10)
    for rid in range(10):
        messages.inmsg_append(q, bc(rid, 50))
    messages.inmsg_append(q, bc(99, 50))
    rids = [m[1] for m in q.in_messages()]
    assert len(rids) == 10 and rids[-1] == 99 and 9 not in rids


def test_out_queue_overflow_loses_the_new_message_and_corrupts_the_last() -> None:
    """``outmsg_queue_append_template``: when full, the stale unused slot is copied over the
    last queued message and the new message is written to the unused slot (lost)."""
    q = MessageQueues(10, 10)
    for topic in range(10):
        messages.outmsg_append_broadcast(q, 0, 60 + topic, INT_OBJ)
    assert q.outbox.size() == 10
    messages.outmsg_append_broadcast(q, 0, 99, INT_OBJ)
    sent = messages.drain_outbox(q)
    topics = [m[3] for m in sent]
    assert len(sent) == 10
    assert 99 not in topics and 69 not in topics  # the 11th is lost, the 10th overwritten
    assert topics[:9] == list(range(60, 69))


def test_serialised_broadcast_and_vstig_layout() -> None:
    q = MessageQueues(10, 10)
    messages.outmsg_append_broadcast(q, 0x0102, 0x0304, INT_OBJ)
    messages.outmsg_append_vstig(q, messages.VSTIG_PUT, 7, 0x33, INT_OBJ, 300)
    b, v = messages.drain_outbox(q)
    assert b == bytes([0, 2, 1, 4, 3, 0x09, 5, 0])
    assert v == bytes([1, 7, 0, 0x33, 0, 0x09, 5, 0, 300 & 0xFF])
    table_obj = bytes([0x0C, 1, 0]) + bytes(6)
    messages.outmsg_append_broadcast(q, 1, 50, table_obj)
    assert messages.drain_outbox(q) == [bytes([0, 1, 0])]  # a table sends only type and rid
