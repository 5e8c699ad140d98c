"""Breakpoints, stepping and pause on error on a real swarm (tests/debugger/swarms.py).

Each test checks where the swarm stopped (robot, control step, line, frames and locals as the
script computes them) and, for the pause semantics, what the other robots have done by then.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from bbzide.debugger import Breakpoint, DebuggerError, SwarmDebugger
from bbzide.vm.inspector import neighbor_entries
from tests.debugger.swarms import ERROR_SCRIPT, STEPPING_SCRIPT, swarm


def functions(stop) -> list[tuple[str, int | None]]:
    return [(frame.function, frame.line) for frame in stop.frames]


def test_breakpoint_any_robot_stops_at_the_first_robot_in_turn_order(tmp_path: Path) -> None:
    debugger = SwarmDebugger(swarm(tmp_path, STEPPING_SCRIPT))
    debugger.breakpoints = [Breakpoint(13)]
    stop = debugger.run(5)
    assert (stop.robot, stop.step, stop.line, stop.reason) == (0, 0, 13, "breakpoint")
    assert functions(stop) == [("step", 13)]
    # going on: the next robot's turn reaches the line in the same control step
    again = debugger.run(5)
    assert (again.robot, again.step, again.line) == (1, 0, 13)
    assert debugger.hits(Breakpoint(13)) == 2


def test_breakpoint_for_one_robot_with_a_hit_count(tmp_path: Path) -> None:
    sim = swarm(tmp_path, STEPPING_SCRIPT)
    debugger = SwarmDebugger(sim)
    debugger.breakpoints = [Breakpoint(13, robot=3, hit_count=3)]
    stop = debugger.run(10)
    # robot 3 reaches line 13 once per control step: the third hit is in step 2
    assert (stop.robot, stop.step, stop.line) == (3, 2, 13)
    # the robots before robot 3 finished step 2, the ones after did not start it
    assert [state.robot.steps_done for state in sim.robots] == [3, 3, 3, 2, 2]


def test_breakpoint_condition_is_evaluated_in_the_robots_context(tmp_path: Path) -> None:
    debugger = SwarmDebugger(swarm(tmp_path, STEPPING_SCRIPT))
    # `value` is the listener's parameter (a local), `seen` a global of the robot
    debugger.breakpoints = [Breakpoint(9, condition="value == 4 and seen > 2")]
    stop = debugger.run(10)
    assert stop.line == 9 and stop.locals["value"] == "4"
    assert debugger.evaluate(stop.robot, "seen") > 2
    assert debugger.evaluate(stop.robot, "value * 10 + size(neighbors)") >= 40


def test_step_into_over_and_out_of_a_function(tmp_path: Path) -> None:
    debugger = SwarmDebugger(swarm(tmp_path, STEPPING_SCRIPT))
    debugger.breakpoints = [Breakpoint(13, robot=3)]
    debugger.run(5)
    debugger.breakpoints = []
    into = debugger.step_into(3)
    assert functions(into) == [("add", 4), ("step", 13)] and into.locals == {"x": "3"}
    over = debugger.step_over(3)
    assert over.line == 5 and over.locals == {"x": "3", "doubled": "6"}
    out = debugger.step_out(3)
    # back in `step`, on the caller's next line (the rest of line 13 ran)
    assert functions(out) == [("step", 14)]
    assert debugger.evaluate(3, "total") == 7


def test_step_through_a_foreach_closure(tmp_path: Path) -> None:
    debugger = SwarmDebugger(swarm(tmp_path, STEPPING_SCRIPT))
    debugger.breakpoints = [Breakpoint(14, robot=2)]
    debugger.run(5)
    at_foreach = debugger.run(5)  # step 1: robot 2 has heard its neighbours by now
    assert (at_foreach.step, at_foreach.line) == (1, 14)
    debugger.breakpoints = []
    into = debugger.step_into(2)
    assert functions(into) == [("lambda at line 14", 15), ("neighbors.foreach", 14),
                                ("step", 14)]
    assert set(into.locals) == {"rid", "data"}
    # out of the closure: foreach calls it for every neighbour, then line 17
    out = debugger.step_out(2)
    assert functions(out) == [("step", 17)]
    neighbours = len(neighbor_entries(debugger.simulation.robots[2].robot.vm))
    assert neighbours >= 2
    assert debugger.evaluate(2, "total") == 2 * 2 + 1 + neighbours


def test_step_over_inside_a_foreach_closure_visits_each_call(tmp_path: Path) -> None:
    debugger = SwarmDebugger(swarm(tmp_path, STEPPING_SCRIPT))
    debugger.breakpoints = [Breakpoint(15, robot=2)]
    stop = debugger.run(5)
    debugger.breakpoints = []
    calls = []
    while stop.line == 15:
        calls.append(stop.locals["rid"])
        stop = debugger.step_over(2)
    assert functions(stop) == [("step", 17)]
    assert len(calls) == len(neighbor_entries(debugger.simulation.robots[2].robot.vm))
    assert len(set(calls)) == len(calls) and "2" not in calls


def test_step_over_a_foreach_line_and_host_calls(tmp_path: Path) -> None:
    debugger = SwarmDebugger(swarm(tmp_path, STEPPING_SCRIPT))
    debugger.breakpoints = [Breakpoint(14, robot=1)]
    debugger.run(5)
    debugger.run(5)
    debugger.breakpoints = []
    broadcast = debugger.step_over(1)
    assert (broadcast.step, functions(broadcast)) == (1, [("step", 17)])
    led = debugger.step_over(1)            # neighbors.broadcast: one step
    assert (led.step, led.line) == (1, 18)
    sent_before = debugger.simulation.robots[1].robot.vm.queues.outbox
    assert sent_before is not None
    after = debugger.step_over(1)          # led, then `step` returns: robot 1's next line
    assert after.step == 2 and after.line in (9, 13)


def test_step_over_through_a_listener(tmp_path: Path) -> None:
    debugger = SwarmDebugger(swarm(tmp_path, STEPPING_SCRIPT))
    debugger.breakpoints = [Breakpoint(9, robot=4)]
    first = debugger.run(5)
    assert functions(first) == [("lambda at line 8", 9)] and first.step == 1
    debugger.breakpoints = []
    # each message calls the listener again: step over lands on its line, the next call
    seen = [first.locals["rid"]]
    stop = debugger.step_over(4)
    while stop.line == 9:
        seen.append(stop.locals["rid"])
        stop = debugger.step_over(4)
    assert seen == ["0", "1", "2", "3"]
    assert functions(stop) == [("step", 13)] and stop.step == 1


def test_step_out_of_a_listener_and_of_a_foreach_closure(tmp_path: Path) -> None:
    """Out of a listener (the firmware calls it for each message): its other calls run
    through, then `step` starts; out of a `foreach` closure: the line after the `foreach`
    call; out of `step`: the next function the firmware calls, in the next control step."""
    debugger = SwarmDebugger(swarm(tmp_path, STEPPING_SCRIPT))
    debugger.breakpoints = [Breakpoint(9, robot=4)]
    heard = debugger.run(5)
    assert functions(heard) == [("lambda at line 8", 9)] and heard.locals["rid"] == "0"
    debugger.breakpoints = []
    out = debugger.step_out(4)
    assert functions(out) == [("step", 13)] and out.step == heard.step
    assert debugger.evaluate(4, "seen") == 0 + 1 + 2 + 3  # every message was heard
    debugger.breakpoints = [Breakpoint(15, robot=4)]
    inside = debugger.run(5)
    assert functions(inside)[0] == ("lambda at line 14", 15) and inside.step == out.step
    debugger.breakpoints = []
    after = debugger.step_out(4)
    assert functions(after) == [("step", 17)] and after.step == inside.step
    next_step = debugger.step_out(4)
    assert functions(next_step) == [("lambda at line 8", 9)]
    assert next_step.step == after.step + 1


def test_step_instruction_moves_one_pc(tmp_path: Path) -> None:
    debugger = SwarmDebugger(swarm(tmp_path, STEPPING_SCRIPT))
    debugger.breakpoints = [Breakpoint(17, robot=0)]
    stop = debugger.run(5)
    debugger.breakpoints = []
    nxt = debugger.step_instruction(0)
    assert nxt.instructions == stop.instructions + 1 and nxt.pc > stop.pc
    assert nxt.line == 17


def test_pause_on_error_names_the_failing_line(tmp_path: Path) -> None:
    sim = swarm(tmp_path, ERROR_SCRIPT)
    debugger = SwarmDebugger(sim)
    stop = debugger.run(10)
    assert (stop.robot, stop.step, stop.line, stop.reason) == (2, 2, 8, "error")
    assert "TYPE" in stop.error
    assert [state.robot.steps_done for state in sim.robots] == [3, 3, 3, 2, 2]
    # going on finishes the step; the failed robot stays failed, nothing stops again
    assert debugger.run(3) is None
    assert sim.step_count == 5 and sim.robots[2].failure is not None  # steps 2, 3, 4 ended


def test_bad_breakpoints_are_one_line_errors(tmp_path: Path) -> None:
    debugger = SwarmDebugger(swarm(tmp_path, STEPPING_SCRIPT))
    with pytest.raises(DebuggerError, match="no such line"):
        debugger.breakpoints = [Breakpoint(99)]
    with pytest.raises(DebuggerError, match="no code on this line .the next line with code "
                                            "is 13"):
        debugger.breakpoints = [Breakpoint(12)]
    with pytest.raises(DebuggerError, match="runs only when the robots boot .the top level"):
        debugger.breakpoints = [Breakpoint(1)]
    with pytest.raises(DebuggerError, match="does not compile"):
        debugger.breakpoints = [Breakpoint(13, condition="total >")]
    with pytest.raises(DebuggerError, match="no such robot"):
        debugger.breakpoints = [Breakpoint(13, robot=42)]
    assert debugger.breakpoints == ()


def test_no_breakpoint_runs_the_fast_path_to_the_same_state(tmp_path: Path) -> None:
    plain = swarm(tmp_path, STEPPING_SCRIPT)
    plain.run(6)
    debugged_sim = swarm(tmp_path, STEPPING_SCRIPT)
    debugger = SwarmDebugger(debugged_sim)
    debugger.breakpoints = [Breakpoint(15)]
    debugger.run(3)                     # stops inside step 1 ...
    debugger.breakpoints = []
    debugger.close()                    # ... which ends ...
    assert debugger.paused_at is None and debugged_sim.step_count == 2
    assert debugger.run(4) is None      # ... then 4 fast steps
    assert debugged_sim.step_count == 6
    for a, b in zip(plain.robots, debugged_sim.robots, strict=True):
        assert a.robot.snapshot() == b.robot.snapshot()
