"""Reverse stepping: going back re-executes to a state byte for byte the one seen going forward.

The property test draws small Buzz programs from a grammar of statements (arithmetic, calls, a
table, loops, `foreach` and `neighbors.foreach` closures, a listener, broadcasts, an LED),
runs each on a small Kilobot swarm (lockstep or asynchronous), steps one robot forward line by
line noting every robot's exact state at each stop (`Robot.comparable(snapshot())`: heap
bytes, stack, pc and the rest), then steps back and forward again and checks that every point
reached again shows the same swarm state. A seeded generator keeps the cases the same from
run to run; `CASES` of them keep the test a few seconds long.
"""

from __future__ import annotations

import random
from pathlib import Path

from bbzide.debugger import Breakpoint, SwarmDebugger
from bbzide.vm.robot import Robot
from tests.debugger.swarms import STEPPING_SCRIPT, swarm

#: programs drawn (each runs ~30 forward and back stops on a 3-robot swarm)
CASES = 5
SEED = 17


def statements(rng: random.Random, depth: int, names: list[int]) -> list[str]:
    """A few random statements of a `step` body (`names`: a counter for unique locals)."""
    indent = "  " * depth
    out: list[str] = []
    for _ in range(rng.randint(2, 4)):
        choice = rng.randrange(9 if depth < 3 else 6)
        n = rng.randint(1, 9)
        if choice == 0:
            out.append(f"{indent}a = (a + {n}) % 97")
        elif choice == 1:
            out.append(f"{indent}b = f(a) % {n + 40}")
        elif choice == 2:
            out.append(f"{indent}t[a % 4] = b + {n}")
        elif choice == 3:
            out.append(f'{indent}neighbors.broadcast("k", a % {n + 10})')
        elif choice == 4:
            out.append(f"{indent}led(b % 7)")
        elif choice == 5:
            out.append(f"{indent}foreach(t, function(k, v) {{")
            out.append(f"{indent}  b = (b + v) % {n + 30}")
            out.append(f"{indent}}})")
        elif choice == 6:
            out.append(f"{indent}if (a > {n * 9}) {{")
            out.extend(statements(rng, depth + 1, names))
            out.append(f"{indent}}} else {{")
            out.extend(statements(rng, depth + 1, names))
            out.append(f"{indent}}}")
        elif choice == 7:
            names[0] += 1
            i = f"i{names[0]}"
            out.append(f"{indent}var {i} = 0")
            out.append(f"{indent}while ({i} < {n % 3 + 1}) {{")
            out.extend(statements(rng, depth + 1, names))
            out.append(f"{indent}  {i} = {i} + 1")
            out.append(f"{indent}}}")
        else:
            out.append(f"{indent}neighbors.foreach(function(rid, data) {{")
            out.append(f"{indent}  a = (a + rid + {n}) % 89")
            out.append(f"{indent}}})")
    return out


def random_program(rng: random.Random) -> str:
    lines = ["var a = 0", "var b = 1", "var t = {}",
             "function f(x) {", "  var y = x + 1", "  return y * 2", "}",
             "function init() {", '  neighbors.listen("k", function(vid, value, rid) {',
             "    a = (a + value) % 83", "  })", "}", "function step() {"]
    lines.extend(statements(rng, 1, [0]))
    lines.append("}")
    return "\n".join(lines) + "\n"


def swarm_state(debugger: SwarmDebugger) -> list[bytes]:
    return [Robot.comparable(state.robot.snapshot()) + bytes(state.robot.vm.heap.data)
            for state in debugger.simulation.robots]


def key(stop) -> tuple[int, int, int]:
    return (stop.step, stop.robot, stop.instructions)


def test_reverse_then_forward_reproduces_every_state(tmp_path: Path) -> None:
    rng = random.Random(SEED)
    for case in range(CASES):
        script = random_program(rng)
        sim = swarm(tmp_path, script, robots=3, seed=case, asynchronous=case % 2 == 1,
                    name=f"case{case}.bzz")
        debugger = SwarmDebugger(sim)
        robot = rng.randrange(3)
        lines = sorted(debugger._main_map().code_lines)
        debugger.breakpoints = [Breakpoint(rng.choice([n for n in lines if n > 12]),
                                           robot=robot)]
        stop = debugger.run(4)
        debugger.breakpoints = []
        if stop is None:                      # the line is in a branch never taken
            stop = debugger.step_into(robot)
        seen = {key(stop): swarm_state(debugger)}
        for _ in range(rng.randint(8, 20)):
            stop = debugger.step_into(robot)
            seen[key(stop)] = swarm_state(debugger)
        for _ in range(rng.randint(3, 8)):    # back, checking each point reached again
            back = debugger.step_back(robot)
            assert back is not None, script
            assert key(back) in seen, script
            assert swarm_state(debugger) == seen[key(back)], script
        for _ in range(3):                    # and forward again
            stop = debugger.step_into(robot)
            assert swarm_state(debugger) == seen[key(stop)], script


def test_step_back_a_control_step_and_to_the_previous_hit(tmp_path: Path) -> None:
    debugger = SwarmDebugger(swarm(tmp_path, STEPPING_SCRIPT))
    debugger.breakpoints = [Breakpoint(15, robot=1)]
    states = {}
    for _ in range(4):
        stop = debugger.run(5)
        states[key(stop)] = (stop, swarm_state(debugger))
    assert [s.step for s, _ in states.values()] == [1, 1, 1, 1]  # one call per neighbour
    previous = debugger.run_back_to_previous_hit()
    earlier = list(states)[-2]
    assert key(previous) == earlier and previous.reason == "breakpoint"
    assert swarm_state(debugger) == states[earlier][1]
    assert debugger.hits(Breakpoint(15, robot=1)) == 3   # counts rewound too
    # one control step back: where robot 1's turn began in step 0
    first = debugger.step_back(1, unit="control_step")
    assert (first.step, first.line) == (0, 13)
    assert first.frames[0].function == "step"
    at_first = swarm_state(debugger)
    # nothing before the first hit: run back finds none and leaves the swarm as it was
    assert debugger.run_back_to_previous_hit() is None
    assert key(debugger.paused_at) == key(first)
    assert swarm_state(debugger) == at_first
