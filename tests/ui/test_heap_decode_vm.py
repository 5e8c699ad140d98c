"""The inspector's heap reader agrees with the VM room's heap (bbzide.vm.heap / tables).

Objects and segments are made by the VM's own allocator on the Kilobot and PC profiles; the
reader, given only `heap.data`, `rtobj` and `ltseg`, must list the same valid objects with the
same types, the same table entries in foreach order, the same darray elements, and the same
used/free split (ROP and LSP included).
"""

from __future__ import annotations

import pytest

from bbzide.ui.heap_decode import HeapGeometry, HeapReader
from bbzide.vm.heap import Heap
from bbzide.vm.profiles import PROFILES
from bbzide.vm.tables import darray_new, darray_push, table_items, table_set


@pytest.mark.parametrize("profile_name", ["kilobot", "pc"])
def test_reader_matches_the_vm_heap(profile_name: str) -> None:
    profile = PROFILES[profile_name]
    heap = Heap(profile)
    numbers = [heap.new_int(v) for v in (7, -3, 300)]
    names = [heap.new_string(i) for i in range(12)]
    table = heap.new_table()
    for name, number in zip(names, numbers * 4, strict=True):  # 12 keys: three segments
        assert table_set(heap, table, name, number)
    darray = darray_new(heap)
    for number in numbers * 4:  # 12 values: two segments
        darray_push(heap, darray, number)
    geometry = HeapGeometry(
        profile.heap_size, profile.obj_size, profile.rsv_actrec, profile.elems_per_tseg
    )
    reader = HeapReader(
        heap.data, geometry, heap.rtobj, heap.ltseg, strings=[f"s{i}" for i in range(12)]
    )
    decoded = reader.decode()
    rows = {row.index: row for row in decoded.objects}
    assert set(rows) == {i for i in range(heap.object_count) if heap.is_valid(i)}
    assert [rows[i].value for i in numbers] == ["7", "-3", "300"]
    assert rows[names[5]].value == "'s5'"
    assert reader.table_entries(table) == table_items(heap, table)
    assert rows[table].value == "table(12)" and rows[darray].value == "darray(12)"
    assert [v for _, v in reader.table_entries(darray)] == numbers * 4
    assert decoded.used_bytes == heap.used_bytes()
    assert decoded.free_bytes == heap.ltseg - heap.rtobj
    assert decoded.valid_segments == heap.segment_count == 5
    print(
        f"{profile_name}: {len(rows)} objects, {decoded.valid_segments} segments, "
        f"ROP {heap.rtobj} LSP {heap.ltseg} agree"
    )
