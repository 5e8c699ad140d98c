"""Heap, table, darray and GC facts from the spec (§E.2-E.9), checked on the model."""

from __future__ import annotations

from hypothesis import given, settings
from hypothesis import strategies as st

from bbzide.vm.gc import collect
from bbzide.vm.heap import GC_MARK, INT, STRING, VALID, Heap, HeapFull
from bbzide.vm.profiles import KILOBOT, PC, get_profile
from bbzide.vm.tables import (
    darray_new,
    darray_pop,
    darray_push,
    darray_size,
    table_get,
    table_items,
    table_set,
)
from bbzide.vm.vm import VM, State


def test_object_sizes_follow_pointer_width() -> None:
    assert PC.obj_size == 9 and KILOBOT.obj_size == 3
    assert get_profile("crazyflie").obj_size == 5 and get_profile("zooids").obj_size == 5
    assert PC.tseg_size == 22


def test_objects_start_after_reserved_records_and_segments_at_the_end() -> None:
    h = Heap(PC)
    assert h.rtobj == 28 * 9 and h.ltseg == 3264
    i = h.new_int(5)
    assert i == 28 and h.rtobj == 29 * 9
    t = h.new_table()
    assert h.u16(t) == 0 and h.ltseg == 3264 - 22
    assert h.seg_mdata(0) == 0xFFFF  # new segment: valid + marked + no next


def test_string_dedupe_only_before_first_free_slot() -> None:
    h = Heap(PC)
    a = h.new_string(7)
    assert h.new_string(7) == a
    x = h.new_int(1)
    h.new_string(7)
    h.set_mdata(x, h.mdata(x) & ~VALID)  # free slot before... after a
    assert h.new_string(7) == a  # a is found before the free slot
    h.set_mdata(a, h.mdata(a) & ~VALID)
    b = h.new_string(9)
    assert b == a  # first free slot is reused


def test_table_grows_a_segment_after_five_pairs_and_removes_emptied_one() -> None:
    h = Heap(PC)
    t = h.new_table()
    keys = [h.new_int(k) for k in range(6)]
    for k in keys:
        table_set(h, t, k, k)
    assert h.seg_next(h.u16(t)) == 1
    assert [k for k, _ in table_items(h, t)] == keys
    probe = h.new_int(5)
    assert table_get(h, t, probe) == keys[5]
    nil = h.obj_alloc(0)
    table_set(h, t, keys[5], nil)
    assert h.seg_next(0) == 0x3FFF and h.seg_mdata(1) == 0


def test_darray_pop_leaves_empty_trailing_segment_and_size_unlinks() -> None:
    h = Heap(PC)
    d = darray_new(h)
    for v in range(11):
        darray_push(h, d, v)
    assert darray_size(h, d) == 11
    darray_pop(h, d)
    assert h.seg_next(h.u16(d)) != 0x3FFF  # emptied trailing segment still linked
    assert darray_size(h, d) == 10
    darray_pop(h, d)  # p = 0 in the trailing segment: drop it, unlink it
    assert h.seg_next(h.u16(d)) == 0x3FFF
    assert not h.seg_mdata(1) & 0x8000
    assert darray_size(h, d) == 9


def test_gc_depth_limit_frees_deep_objects() -> None:
    h = Heap(PC)
    tables = [h.new_table() for _ in range(10)]
    key = h.new_int(0)
    for a, b in zip(tables, tables[1:], strict=False):
        table_set(h, a, key, b)
    h.set_mdata(tables[0], h.mdata(tables[0]) | 0x10)  # permanent root at level 2
    collect(h, [], -1)
    # root at level 2 .. level 8 = 7 tables survive, the rest are freed
    assert [h.is_valid(t) for t in tables] == [True] * 7 + [False] * 3
    assert h.mdata(tables[0]) & GC_MARK


def test_out_of_memory_is_heap_full() -> None:
    h = Heap(KILOBOT)
    try:
        while True:
            h.new_int(1)
    except HeapFull:
        pass
    assert h.rtobj + h.obj_size > h.ltseg


@settings(max_examples=150, deadline=None)
@given(st.binary(min_size=0, max_size=120), st.sampled_from(["pc", "kilobot"]))
def test_arbitrary_bytecode_never_raises(code: bytes, profile: str) -> None:
    vm = VM(get_profile(profile))
    vm.construct()
    vm.set_bcode(code)
    vm.run(max_instructions=2000)
    assert vm.state in (State.DONE, State.ERROR)
    if vm.state == State.ERROR:
        assert vm.error_events


def test_error_puts_pc_back_on_failing_instruction() -> None:
    vm = VM(PC)
    vm.construct()
    # 2-byte header, nop, then: pop (empty stack) -> STACK at pc 3
    vm.set_bcode(bytes([0, 0, 0, 4, 1]))
    vm.run(max_instructions=10)
    assert vm.state == State.ERROR and vm.error.name == "STACK" and vm.pc == 3


def test_string_type_constant() -> None:
    assert (STRING, INT) == (3, 1)
