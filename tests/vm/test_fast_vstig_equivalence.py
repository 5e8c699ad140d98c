"""The compiled stigmergy loop (``bbzide/vm/compiled/fastvstig.py``) against the reference.

A robot in the fast mode processes the virtual-stigmergy records of its in-queue in compiled
code and hands what the kernel does not cover (a conflict with an ``onconflict`` handler, a
heap without room) back to Python; a robot in the reference mode (``stress_gc=True``) runs
``vstig.process_vstig`` only. Both get the same messages: newer puts replacing entries,
queries answered with a newer entry, unknown keys appended, repeats, equal timestamps from
other robots (with and without a handler), broadcasts before them, an out-queue left to
overflow, a heap filled until it is full. After each round every observable must be equal:
heap bytes and pointers, collections counted, the stigmergy entries, both queues' records.
"""

from __future__ import annotations

import dataclasses
import random
from collections.abc import Iterator
from contextlib import contextmanager

import pytest

from bbzide.compiler import bittybuzz_string_table, compile_source
from bbzide.vm import inmsgs
from bbzide.vm.compiled import fastvstig
from bbzide.vm.heap import FLOAT, INT, STRING, TABLE, VALID
from bbzide.vm.messages import BROADCAST, VSTIG_PUT, VSTIG_QUERY, drain_outbox
from bbzide.vm.profiles import KILOBOT, PC, Profile
from bbzide.vm.robot import Robot
from bbzide.vm.states import Error, State

#: three local entries ("ka", "kb", "kc": timestamp 1, robot 1), optionally a handler
SOURCE = """
function init() {
  v = stigmergy.create(1)
  v.put("ka", 11)
  v.put("kb", 22)
  v.put("kc", 33)
  HANDLER
}
function step() {
  if (v.size() > 6) { x = v.get("kb") }
}
"""
#: the remote value wins every conflict (a Buzz call: the kernel hands these to Python)
HANDLER = "v.onconflict(function(key, local, remote) { return remote })"
KEYS = ["ka", "kb", "kc"]
#: queues long enough for a round's messages, an out-queue that fills up in two rounds; a
#: heap profile (its neighbors table keeps the string of the onconflict key, so the conflict
#: finds that string) and an XTREME one (the conflict makes the string, a collection frees it)
QUEUES = {"in_queue_cap": 40, "out_queue_cap": 8, "msg_in_proc_max": 40}
PROFILES = [dataclasses.replace(PC, **QUEUES), dataclasses.replace(KILOBOT, **QUEUES)]
IDS = ["pc", "kilobot"]
ROBOT = 1


def _pair(handler: bool, profile: Profile) -> tuple[Robot, Robot, dict[str, int]]:
    source = SOURCE.replace("HANDLER", HANDLER if handler else "")
    program = compile_source(source, "vstig.bzz",
                             string_table=bittybuzz_string_table(KEYS)).to_bbo()
    robots = []
    for stress in (True, False):
        robot = Robot(program, profile, ROBOT, {}, stress_gc=stress)
        robot.boot()
        assert robot.failure is None
        drain_outbox(robot.vm.queues)  # the init's puts: sent
        robots.append(robot)
    keys = {name: e.key for name, e in zip(KEYS, robots[0].vm.vstig.entries, strict=True)}
    return robots[0], robots[1], keys


def _message(typ: int, rid: int, key: int, value: int, lamport: int,
             mdata: int = INT | VALID) -> bytes:
    """A stigmergy payload as sent: type, rid, key, the object's mdata and 2 bytes, lamport."""
    return bytes([typ, rid & 0xFF, rid >> 8, key & 0xFF, key >> 8, mdata, value & 0xFF,
                  value >> 8, lamport & 0xFF])


def _observe(robot: Robot) -> tuple:
    vm = robot.vm
    q = vm.queues
    h = vm.heap
    return (vm.state, vm.error, list(vm.error_events), str(robot.failure), bytes(h.data),
            h.rtobj, h.ltseg, h.gc_runs, h.peak_used, bytes(vm.stack), vm.stackptr,
            vm.instructions_executed, vm.vstig.hpos,
            [dataclasses.astuple(e) for e in vm.vstig.entries],
            [bytes(r) for r in q.inbox.records], q.inbox.start, q.inbox.end,
            [bytes(r) for r in q.outbox.records], q.outbox.start, q.outbox.end)


@contextmanager
def _kernel_calls() -> Iterator[list[tuple[int, int]]]:
    """Each call of the kernel as (status, messages it extracted)."""
    calls: list[tuple[int, int]] = []
    kernel = fastvstig.process_vstigs

    def counted(*args: object) -> int:
        status = kernel(*args)
        state = args[9]
        calls.append((status, int(state[fastvstig.V_EXTRACTED])))  # type: ignore[index]
        return status

    fastvstig.process_vstigs = counted
    try:
        yield calls
    finally:
        fastvstig.process_vstigs = kernel


def _feed(pair: tuple[Robot, Robot], payloads: list[bytes]) -> None:
    """The same messages queued in both, then their in-queue processed (no ``step``, no
    transmission: what the out-queue gets stays there)."""
    for robot in pair:
        for payload in payloads:
            robot.receive(payload, 1.0, 0.0, 0.0)
        inmsgs.process_inmsgs(robot.vm)
    assert _observe(pair[0]) == _observe(pair[1])


@pytest.mark.parametrize("profile", PROFILES, ids=IDS)
def test_each_branch_in_the_kernel_and_the_out_queue_overflowing(profile: Profile) -> None:
    reference, fast, keys = _pair(False, profile)
    ka, kb, kc = keys["ka"], keys["kb"], keys["kc"]
    with _kernel_calls() as calls:  # (the in-queue's sort by type puts the queries last)
        _feed((reference, fast), [
            _message(VSTIG_PUT, 3, ka, 500, 5),           # newer: replaces ka (robot 3, ts 5)
            _message(VSTIG_QUERY, 4, kb, 0, 0),           # older query: answered with kb
            _message(VSTIG_PUT, 5, 300, 7, 7),            # unknown key: appended
            _message(VSTIG_QUERY, 6, 301, 0, 2, STRING | VALID),  # unknown, by a query
            _message(VSTIG_PUT, 5, 300, 7, 7),            # a repeat: nothing done
            _message(VSTIG_PUT, 0, kc, 9, 1),             # conflict, lower id: local kept
            _message(VSTIG_PUT, 9, kc, 10, 1, FLOAT | VALID),  # conflict, higher id: adopted
            _message(VSTIG_PUT, 2, ka, 12, 5),            # conflict with robot 3: kept
        ])
    assert calls == [(fastvstig.DONE, 8)]  # all of them in one call, none handed back
    entries = {e.key: (e.timestamp, e.robot) for e in fast.vm.vstig.entries}
    assert entries == {ka: (5, 3), kb: (1, ROBOT), kc: (1, 9), 300: (7, 5), 301: (2, 6)}
    assert fast.vm.queues.outbox.size() == 7  # every message but the repeat queued a PUT
    # more PUTs than the out-queue holds: its overflow (the last record overwritten)
    with _kernel_calls() as calls:
        _feed((reference, fast), [_message(VSTIG_PUT, 7, 400 + k, k, 3) for k in range(5)])
    assert calls == [(fastvstig.DONE, 5)]
    assert fast.vm.queues.outbox.full()
    # a table-typed copy (its stale segment index walked by the collector), and a newer
    # value whose copy may take the slot the old one left
    _feed((reference, fast), [_message(VSTIG_PUT, 8, ka, 1, 6, TABLE | VALID),
                              _message(VSTIG_PUT, 8, 300, 1, 8)])


@pytest.mark.parametrize("profile", PROFILES, ids=IDS)
def test_a_conflict_with_a_handler_goes_to_python(profile: Profile) -> None:
    reference, fast, keys = _pair(True, profile)
    with _kernel_calls() as calls:
        _feed((reference, fast), [
            _message(VSTIG_PUT, 3, keys["ka"], 500, 5),   # newer: in the kernel
            _message(VSTIG_PUT, 0, keys["kb"], 77, 1),    # conflict: the handler, in Python
            _message(VSTIG_PUT, 4, 300, 7, 7),            # after it: the kernel again
        ])
    assert calls == [(fastvstig.PYTHON_MESSAGE, 1), (fastvstig.DONE, 1)]
    # the handler ran: the remote value won though its robot id is the lower one
    kb = next(e for e in fast.vm.vstig.entries if e.key == keys["kb"])
    assert kb.robot == 0 and fast.vm.heap.int_value(kb.value) == 77


@pytest.mark.parametrize("profile", PROFILES, ids=IDS)
def test_broadcasts_then_stigmergy_share_the_collections(profile: Profile) -> None:
    """A broadcast to a topic nobody listens to ends without a collection: the broadcast
    kernel collects for the first stigmergy message and hands it over, and the stigmergy
    kernel goes on from its extraction (``taken``)."""
    reference, fast, keys = _pair(False, profile)
    with _kernel_calls() as calls:
        _feed((reference, fast), [bytes([BROADCAST, 2, 0, 40, 0, INT | VALID, 1, 0]),
                                  _message(VSTIG_PUT, 3, keys["ka"], 5, 9),
                                  _message(VSTIG_PUT, 3, keys["ka"], 5, 9)])
    assert calls and calls[0][1] == 2


@pytest.mark.parametrize("profile", PROFILES, ids=IDS)
def test_appends_until_the_heap_is_full(profile: Profile) -> None:
    """Unknown keys fill a small heap with permanent copies, one a round, each followed by
    a conflict adopting a remote value (a string, on the XTREME profile, and a copy): the
    kernel hands the first message without room to Python, where an allocation fails
    (error MEM; on the heap profile the conflict's string exists and its copy takes the
    slot the old value left, so it is the next append)."""
    reference, fast, _keys = _pair(False, profile)
    handed = 0
    for round_ in range(400):
        with _kernel_calls() as calls:
            _feed((reference, fast), [_message(VSTIG_PUT, 2, 1000 + round_, round_, 1),
                                      _message(VSTIG_PUT, 5, 999 + round_, round_, 1)])
        handed += sum(status == fastvstig.PYTHON_MESSAGE for status, _ in calls)
        if reference.vm.state == State.ERROR:
            break
    assert reference.vm.state == State.ERROR and reference.vm.error == Error.MEM
    assert handed >= 1


@pytest.mark.parametrize("profile", PROFILES, ids=IDS)
@pytest.mark.parametrize("handler", [False, True], ids=["no-handler", "handler"])
def test_random_traffic_over_control_steps(handler: bool, profile: Profile) -> None:
    """Random puts and queries on a few keys, timestamps near each other and across the u8
    wrap, from several robots, values of every type; whole control steps (``step`` reads
    the store; the out-queue is sent) on both robots."""
    rng = random.Random(7)
    reference, fast, keys = _pair(handler, profile)
    pool = [*keys.values(), 300, 301, 302]
    stamps = [0, 1, 2, 3, 4, 5, 60, 250, 254, 255]
    kinds = [INT | VALID, FLOAT | VALID, STRING | VALID, TABLE | VALID, VALID]
    extracted = 0
    for step in range(120):
        payloads = [_message(rng.choice([VSTIG_PUT, VSTIG_PUT, VSTIG_QUERY]),
                             rng.randrange(0, 6), rng.choice(pool), rng.randrange(0, 65536),
                             rng.choice(stamps), rng.choice(kinds))
                    for _ in range(rng.randrange(0, 14))]
        if rng.random() < 0.3:
            payloads.append(bytes([BROADCAST, 2, 0, 40, 0, INT | VALID, 1, 0]))
        with _kernel_calls() as calls:
            for robot in (reference, fast):
                for payload in payloads:
                    robot.receive(payload, 1.0, 0.0, 0.0)
                robot.control_step()
        extracted += sum(n for _, n in calls)
        assert _observe(reference) == _observe(fast), step
    assert extracted > 100  # (a handler run soon fills a Kilobot heap: MEM, on both)
