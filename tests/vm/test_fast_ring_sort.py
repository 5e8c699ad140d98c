"""The compiled ring sort (``fastring.sort_ring_by_type``) puts the records where the model's
``RingBuffer.sort_by_type`` puts them: every ring size the profiles use, every head
position, queues sorted but for their last record (an append) and queues in any order."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from bbzide.vm.compiled.fastring import sort_ring_by_type
from bbzide.vm.messages import RingBuffer

#: record bytes: the type, then a serial number that tells equal types apart (stability)
RECORD = 3
#: ring slots: the profiles' 11 (capacity 10) and 256 (255), and sizes between; a ring of
#: more than 128 slots that does not divide 256 would read wrong records (profiles.py)
SLOTS = (2, 3, 11, 64, 128, 256)


def _sorted_both_ways(slots: int, start: int, types: list[int]) -> tuple[list, list]:
    """The ring's records after the model's sort and after the compiled one."""
    records = [bytes((0xEE, 0xEE, 0xEE))] * (slots + 1)  # the last one is scratch
    ring: RingBuffer[bytes] = RingBuffer(list(records), slots)
    ring.start = start
    ring.end = (start + len(types)) % slots
    for i, typ in enumerate(types):
        ring.records[ring.index_at(i)] = bytes((typ, i & 0xFF, i >> 8))
    packed = np.frombuffer(b"".join(ring.records), np.uint8).copy()
    ring.sort_by_type()
    sort_ring_by_type(packed, ring.start, ring.end, slots, RECORD, packed[:0])
    compiled = [bytes(packed[k * RECORD:(k + 1) * RECORD]) for k in range(slots + 1)]
    return ring.records, compiled


@settings(max_examples=300, deadline=None)
@given(st.sampled_from(SLOTS), st.data())
def test_a_queue_in_any_order_is_sorted_as_the_model_sorts_it(slots: int,
                                                                data: st.DataObject) -> None:
    start = data.draw(st.integers(0, slots - 1))
    types = data.draw(st.lists(st.integers(0, 3), max_size=slots - 1))
    model, compiled = _sorted_both_ways(slots, start, types)
    assert compiled == model


@settings(max_examples=200, deadline=None)
@given(st.sampled_from(SLOTS), st.data())
def test_an_append_to_a_sorted_queue_moves_only_to_its_place(slots: int,
                                                             data: st.DataObject) -> None:
    start = data.draw(st.integers(0, slots - 1))
    head = sorted(data.draw(st.lists(st.integers(0, 4), max_size=slots - 2)))
    types = head + [data.draw(st.integers(0, 4))]
    model, compiled = _sorted_both_ways(slots, start, types)
    assert compiled == model
    queued = [compiled[(start + i) % slots][0] for i in range(len(types))]
    assert queued == sorted(types)


def test_a_full_256_slot_ring_that_wraps_keeps_equal_types_in_arrival_order() -> None:
    types = [2, 1] * 127 + [0]
    model, compiled = _sorted_both_ways(256, 200, types)
    assert compiled == model
    queued = [compiled[(200 + i) % 256] for i in range(len(types))]
    assert [r[0] for r in queued] == [0] + [1] * 127 + [2] * 127
    ones = [r[1] | r[2] << 8 for r in queued if r[0] == 1]
    assert ones == sorted(ones)
