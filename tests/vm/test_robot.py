"""``Robot`` (the firmware loop the worlds drive): message exchange between robots, the two
loops, failures with source positions, the instruction budget, snapshots, and hostile input
(mutated bytecode, garbage messages) that must never raise."""

from __future__ import annotations

from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from bbzide.compiler import bittybuzz_string_table, compile_source
from bbzide.compiler.program import BittyBuzzProgram
from bbzide.vm.host import HostCall
from bbzide.vm.profiles import KILOBOT, PC, PROFILES
from bbzide.vm.robot import Robot

PINGPONG = """
heard = 0
function init() {
  neighbors.listen("ping", function(topic, value, rid) {
    heard = heard + value
    log("heard", value, rid)
  })
  v = stigmergy.create(1)
  if(id == 0) v.put("leader", 7)
}
function step() {
  neighbors.broadcast("ping", id + 1)
  log("step", heard, v.get("leader"), neighbors.count())
}
"""


def program(source: str, hosts: tuple[str, ...] = ("log",)) -> BittyBuzzProgram:
    table = bittybuzz_string_table(list(hosts))
    return compile_source(source, "test.bzz", string_table=table).to_bbo()


def logger(store: list) -> callable:
    def log(call: HostCall) -> None:
        store.append((call.robot_id, call.args))
    return log


def exchange(profile, steps: int = 3) -> tuple[list[Robot], list]:  # noqa: ANN001
    logs: list = []
    prog = program(PINGPONG)
    robots = [Robot(prog, profile, i, {"log": logger(logs)}) for i in range(2)]
    for r in robots:
        r.boot()
    for _ in range(steps):
        sent = [r.control_step() for r in robots]
        for i, r in enumerate(robots):
            for message in sent[1 - i]:
                r.receive(message, 10.0, 0.0, 0.0)
    return robots, logs


def test_two_robots_exchange_broadcasts_and_stigmergy() -> None:
    for profile in (KILOBOT, PC):
        robots, logs = exchange(profile)
        assert all(r.failure is None for r in robots)
        # robot 1 hears robot 0's value 1 and learns robot 0's stigmergy key
        assert (1, ["heard", 1, 0]) in logs
        assert (0, ["heard", 2, 1]) in logs
        last1 = [args for rid, args in logs if rid == 1 and args[0] == "step"][-1]
        assert last1[2] == 7 and last1[3] == 1


def test_wire_format_of_a_broadcast() -> None:
    robots, _ = exchange(KILOBOT, steps=1)
    sent = robots[1].control_step()
    # type 0, rid 1, topic id of "ping", int object (mdata with valid bit), value 2
    ping = robots[1].program.string_id("ping")
    bc = [m for m in sent if m[0] == 0][0]
    assert len(bc) == 8
    assert bc[1:3] == (1).to_bytes(2, "little")
    assert bc[3:5] == ping.to_bytes(2, "little")
    assert bc[5] & 0x0F == 0x09 and bc[6:8] == (2).to_bytes(2, "little")


def test_robot_loop_grows_the_stack_and_pop_loop_does_not() -> None:
    prog = program("function step() { x = 1 }")
    depths = {}
    for loop in ("pop", "robot"):
        r = Robot(prog, KILOBOT, 0, loop=loop)
        r.boot()
        for _ in range(5):
            r.control_step()
        depths[loop] = r.vm.stackptr + 1
    assert depths["pop"] == 0
    assert depths["robot"] == 5  # the 5 values step() returned (no init defined)


def test_robot_loop_ends_with_a_stack_error() -> None:
    r = Robot(program("function step() { x = 1 }"), KILOBOT, 0, loop="robot")
    r.boot()
    for _ in range(100):
        r.control_step()
    assert r.failure is not None and r.failure.reason == "STACK"
    assert r.control_step() == []  # a failed robot does nothing more


def test_error_points_at_the_source_line() -> None:
    # positions follow bzzparse: the token after the expression (here z, on line 3)
    src = "function step() {\n  t = {}\n  y = 1 + t z = 2\n}\n"
    r = Robot(program(src), PC, 0)
    r.boot()
    r.control_step()
    assert r.failure is not None and r.failure.reason == "MATH"
    assert r.failure.location is not None and r.failure.location.line == 3


def test_infinite_loop_hits_the_budget() -> None:
    r = Robot(program("function step() { while(1) { x = 1 } }"), KILOBOT, 0,
              instruction_budget=5000)
    r.boot()
    r.control_step()
    assert r.failure is not None and r.failure.reason == "BUDGET"
    assert r.failure.location is not None and r.failure.location.line == 1


def test_host_function_argument_count_and_exceptions() -> None:
    def led(call: HostCall) -> None:
        if call.expect_args(1):
            call.ret(None)

    def boom(call: HostCall) -> None:
        raise RuntimeError("host bug")

    r = Robot(program("function step() { led(1, 2) }", ("led",)), KILOBOT, 0, {"led": led})
    r.boot()
    r.control_step()
    assert r.failure is not None and r.failure.reason == "LNUM"
    r = Robot(program("function step() { boom() }", ("boom",)), KILOBOT, 0, {"boom": boom})
    r.boot()
    r.control_step()
    assert r.failure is not None and r.failure.reason == "HOST"


def test_snapshot_restore_replays_identically() -> None:
    robots, _ = exchange(PC, steps=2)
    r = robots[0]
    snap = r.snapshot()
    first = [r.control_step() for _ in range(4)]
    heap_after = bytes(r.vm.heap.data)
    r.restore(snap)
    again = [r.control_step() for _ in range(4)]
    assert again == first
    assert bytes(r.vm.heap.data) == heap_after


def test_incoming_queue_keeps_at_most_ten_messages() -> None:
    r = Robot(program(PINGPONG), PC, 5, {"log": lambda call: None})
    r.boot()
    ping = r.program.string_id("ping")
    for rid in range(20):
        r.receive(bytes([0, rid, 0, ping, 0, 0x09, 1, 0]), 1.0, 0.0, 0.0)
    assert r.vm.queues.inbox.size() == 10


# ---- hostile input: never a Python exception -------------------------------------------
_SCRIPT = program(PINGPONG)


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.lists(st.tuples(st.integers(0, len(_SCRIPT.bbo) - 1), st.integers(0, 255)),
                max_size=6),
       st.integers(2, len(_SCRIPT.bbo)), st.sampled_from(sorted(PROFILES)))
def test_mutated_bytecode_never_raises(edits, length, profile_name) -> None:  # noqa: ANN001
    code = bytearray(_SCRIPT.bbo)
    for pos, value in edits:
        code[pos] = value
    prog = BittyBuzzProgram(bbo=bytes(code[:length]), strings=_SCRIPT.strings,
                            debug_map={}, bo_to_bbo={}, warnings=[])
    r = Robot(prog, PROFILES[profile_name], 1, {"log": lambda call: None},
              instruction_budget=2000)
    r.boot()
    for _ in range(3):
        r.receive(b"\x00\x02\x00" + bytes(6), 1.0, 0.0, 0.0)
        r.control_step()
    assert r.failure is None or r.failure.reason != "HOST", r.failure


@settings(max_examples=80, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.lists(st.binary(max_size=14), max_size=12),
       st.sampled_from(["kilobot", "pc"]),
       st.floats(allow_nan=True, allow_infinity=True))
def test_garbage_messages_never_raise(payloads, profile_name, distance) -> None:  # noqa: ANN001
    r = Robot(_SCRIPT, PROFILES[profile_name], 3, {"log": lambda call: None},
              instruction_budget=20000)
    r.boot()
    for p in payloads:
        r.receive(p, distance, distance, 0.0)
    for _ in range(2):
        r.control_step()
    assert r.failure is None or r.failure.reason != "HOST", r.failure
