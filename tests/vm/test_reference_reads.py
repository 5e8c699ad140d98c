"""The reference mode's own table reads and first-fit scans, against the compiled ones.

Design: the reference mode (``heap.reference``, a VM with ``stress_gc=True``) is what the
fast mode is checked against, so it must not run the kernels it checks. `tables.py` and
`heap.py` walk chains and scan slots in plain Python there; these tests (1) run a whole
reference-mode robot with every compiled table read and scan made to fail, and (2) compare
each plain walk with its compiled twin on heaps of random bytes — stale payloads, corrupt and
cyclic chains, indices past the heap — where the two must agree on every result and leave
the same bytes behind (`darray_size` unlinks).
"""

from __future__ import annotations

import random

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from bbzide.compiler import bittybuzz_string_table, compile_source
from bbzide.vm import kernels
from bbzide.vm.heap import STRING, TABLE, Heap
from bbzide.vm.host import HostCall
from bbzide.vm.profiles import KILOBOT, PC, Profile
from bbzide.vm.robot import Robot
from bbzide.vm.tables import darray_get, darray_set, darray_size, table_get

SCRIPT = """
var t = {}
var d = {}
var n = 0
function init() {
  t.a = 1
  t["b"] = "x"
  d[0] = 5
  d[1] = {}
}
function step() {
  n = n + 1
  t[n % 7] = n
  foreach(t, function(k, v) { d[2] = v })
  log(size(t), t[3], d[0])
}
"""


def _robot(stress: bool, lines: list[str]) -> Robot:
    program = compile_source(SCRIPT, "tables.bzz",
                             string_table=bittybuzz_string_table(["log"])).to_bbo()

    def log(call: HostCall) -> None:
        lines.append(repr(call.args))

    robot = Robot(program, KILOBOT, 1, {"log": log}, stress_gc=stress)
    robot.boot()
    return robot


def test_reference_robot_runs_without_any_compiled_read(monkeypatch: pytest.MonkeyPatch) -> None:
    """Every kernel a table read or heap scan could call raises: the reference robot does not
    notice, and logs what the fast robot logs."""
    fast_lines: list[str] = []
    fast = _robot(False, fast_lines)
    for _ in range(12):
        fast.control_step()

    def refuse(*_args: object) -> int:
        raise AssertionError("the reference mode called a compiled kernel")

    for name in ("table_lookup", "darray_get", "darray_set", "darray_size"):
        monkeypatch.setattr(kernels.fasttables, name, refuse)
    for name in ("first_free", "first_free_segment"):
        monkeypatch.setattr(kernels.fastgc, name, refuse)
    lines: list[str] = []
    reference = _robot(True, lines)
    for _ in range(12):
        reference.control_step()
    assert reference.failure is None and fast.failure is None
    assert lines == fast_lines and len(lines) == 12
    assert Robot.comparable(reference.snapshot()) == Robot.comparable(fast.snapshot())


def _random_heap(profile: Profile, seed: int) -> tuple[Heap, Heap]:
    """Two heaps (reference, fast) over the same random bytes and pointers."""
    rng = random.Random(seed)
    reference, fast = Heap(profile, reference=True), Heap(profile)
    data = bytes(rng.getrandbits(8) for _ in range(profile.heap_size))
    objects = rng.randrange(reference.reserved, reference.objects)
    rtobj = objects * profile.obj_size
    segments = rng.randrange(0, (profile.heap_size - rtobj) // profile.tseg_size + 1)
    for heap in (reference, fast):
        heap.data[:] = data
        heap.rtobj, heap.ltseg = rtobj, profile.heap_size - segments * profile.tseg_size
    return reference, fast


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), profile=st.sampled_from([KILOBOT, PC]))
def test_plain_reads_equal_compiled_reads_on_random_heaps(seed: int, profile: Profile) -> None:
    reference, fast = _random_heap(profile, seed)
    rng = random.Random(seed ^ 0x5A5A)
    limit = reference.objects + 3  # indices past the heap too
    for _ in range(40):
        t, k, i = rng.randrange(limit), rng.randrange(limit), rng.randrange(-2, 40)
        assert table_get(reference, t, k) == table_get(fast, t, k)
        assert darray_get(reference, t, i) == darray_get(fast, t, i)
        v = rng.randrange(reference.objects)
        assert darray_set(reference, t, i, v) == darray_set(fast, t, i, v)
        assert darray_size(reference, t) == darray_size(fast, t)
        assert reference.data == fast.data


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), profile=st.sampled_from([KILOBOT, PC]))
def test_plain_scans_equal_compiled_scans_on_random_heaps(seed: int, profile: Profile) -> None:
    reference, fast = _random_heap(profile, seed)
    rng = random.Random(seed)
    for typ in (STRING, TABLE, STRING):
        sid = rng.randrange(0x10000) if rng.random() < 0.5 else rng.randrange(8)
        results = []
        for heap in (reference, fast):
            try:
                results.append(heap.obj_alloc(typ, sid))
            except Exception as error:  # noqa: BLE001 - HeapFull in both, compared by type
                results.append(type(error))
        assert results[0] == results[1]
        assert (reference.rtobj, reference.ltseg) == (fast.rtobj, fast.ltseg)
        assert reference.data == fast.data
