"""Automatic checks of the lessons: run a student's script in the lesson's scenario, headless,
and say whether it does what the lesson asks, and if not, what to look at.

Design: `run_check(lesson, script)` compiles the script for the lesson's world (a compile error
is a failed check that shows the compiler's message), builds the lesson's scenario with every
robot group running that script, and hands the `Simulation` to the lesson's check function
(`CHECKS[slug]`). A check steps the swarm itself (some watch every step), reads robots' LEDs,
poses and script globals, and returns a `Verdict`: pass/fail, one summary line, and lines
naming the robots and values to look at. A robot that stops with a VM error fails every check,
with the error and its source line (the same text `bbzide run` prints).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np

from bbzide.diagnostics import UserError
from bbzide.lessons.catalog import Lesson
from bbzide.worlds.commands import describe_failure
from bbzide.worlds.radio import hop_counts, pairs_within_range
from bbzide.worlds.scenario import Scenario

#: How many robots a failed check names before "and N more": enough to see the pattern,
#: short enough for a terminal.
SHOWN_ROBOTS = 5

RED, GREEN, BLUE, OFF = (1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0), (0.0, 0.0, 0.0)
COLOUR_NAMES = {OFF: "off", RED: "red", GREEN: "green", BLUE: "blue",
                (1.0, 1.0, 0.0): "yellow", (0.0, 1.0, 1.0): "cyan", (1.0, 0.0, 1.0): "magenta",
                (1.0, 1.0, 1.0): "white"}


@dataclass(frozen=True)
class Verdict:
    passed: bool
    summary: str
    look_at: tuple[str, ...] = ()

    def render(self) -> str:
        head = f"{'PASS' if self.passed else 'FAIL'}: {self.summary}"
        return "\n".join([head, *(f"  - {line}" for line in self.look_at)])


def lesson_scenario(chosen: Lesson, script: Path) -> Scenario:
    """The lesson's scenario with every robot group running `script`."""
    return chosen.scenario().with_script(script)


def run_check(chosen: Lesson, script: Path) -> Verdict:
    """Run lesson `chosen`'s check on `script` (see the module doc)."""
    scenario = lesson_scenario(chosen, script)
    try:
        programs = scenario.programs()
    except UserError as error:
        return Verdict(False, "the script does not compile", (error.render(),))
    sim = scenario.simulation(programs)
    verdict = CHECKS[chosen.slug](sim, scenario)
    stopped = robot_errors(sim)
    if stopped is None or set(stopped.look_at) <= set(verdict.look_at):
        return verdict
    if verdict.passed:
        return stopped
    return replace(verdict, look_at=verdict.look_at + stopped.look_at)


# ---- helpers ---------------------------------------------------------------------------------
def robot_errors(sim: Any) -> Verdict | None:
    failures = sim.failures
    if not failures:
        return None
    lines = tuple(describe_failure(state, world=sim.world.name)
                  for state in failures[:SHOWN_ROBOTS])
    return Verdict(False, f"{len(failures)} robot(s) stopped with an error", lines)


def globals_of(sim: Any, name: str) -> list[Any]:
    return [state.global_value(name) for state in sim.robots]


def colour(led: tuple[float, float, float]) -> str:
    return COLOUR_NAMES.get(tuple(round(v) for v in led), str(led))


def mismatches(sim: Any, name: str, expected: list[Any]) -> list[str]:
    """`robot 3: gradient is 255, expected 2` for each robot whose global differs."""
    found = globals_of(sim, name)
    wrong = [f"robot {s.robot_id}: {name} is {v}, expected {e}"
             for s, v, e in zip(sim.robots, found, expected, strict=True) if v != e]
    if len(wrong) > SHOWN_ROBOTS:
        wrong = wrong[:SHOWN_ROBOTS] + [f"... and {len(wrong) - SHOWN_ROBOTS} more"]
    return wrong


def run_until(sim: Any, steps: int, done: Callable[[], bool]) -> bool:
    """Step up to `steps` times; True as soon as `done()` holds (checked after each step)."""
    for _ in range(steps):
        sim.step()
        if done():
            return True
    return False


# ---- the checks ------------------------------------------------------------------------------
def check_first_light(sim: Any, scenario: Scenario) -> Verdict:
    lit = np.zeros(sim.count, dtype=int)
    changes = np.zeros(sim.count, dtype=int)
    before = [colour(s.led) for s in sim.robots]
    for _ in range(scenario.steps):
        sim.step()
        now = [colour(s.led) for s in sim.robots]
        lit += [c == "red" for c in now]
        changes += [a != b for a, b in zip(before, now, strict=True)]
        before = now
    others = {c for s in sim.robots for c in [colour(s.led)] if c not in ("red", "off")}
    wrong = [f"robot {s.robot_id}: red on {lit[i]} of {scenario.steps} steps, changed "
             f"{changes[i]} times" for i, s in enumerate(sim.robots)
             if not (4 <= lit[i] <= scenario.steps - 4 and changes[i] >= 8)]
    if others:
        wrong.append(f"colours other than red were seen: {', '.join(sorted(others))}")
    if wrong:
        return Verdict(False, "the LEDs do not blink red, one step on, one step off",
                       tuple(wrong[:SHOWN_ROBOTS]))
    return Verdict(True, f"all {sim.count} robots blink red")


def check_who_am_i(sim: Any, scenario: Scenario) -> Verdict:
    sim.run(scenario.steps)
    wrong = [f"robot {s.robot_id} ({'even' if s.robot_id % 2 == 0 else 'odd'} id) is "
             f"{colour(s.led)}, expected {'green' if s.robot_id % 2 == 0 else 'blue'}"
             for s in sim.robots if s.led != (GREEN if s.robot_id % 2 == 0 else BLUE)]
    if wrong:
        return Verdict(False, "even ids must be green and odd ids blue", tuple(wrong))
    return Verdict(True, "even ids are green, odd ids blue")


def check_neighbours(sim: Any, scenario: Scenario) -> Verdict:
    sim.run(scenario.steps)
    links = pairs_within_range(sim.positions, sim.world.comm_range)
    expected = np.bincount(links.senders, minlength=sim.count).tolist()
    wrong = mismatches(sim, "n", expected)
    if wrong:
        return Verdict(False, "n is not the number of robots in IR range", tuple(wrong))
    return Verdict(True, f"every robot counts its neighbours (n = {expected})")


def check_hop_count(sim: Any, scenario: Scenario) -> Verdict:
    expected = hop_counts(sim.positions, sim.world.comm_range)
    if run_until(sim, scenario.steps, lambda: globals_of(sim, "hops") == expected):
        return Verdict(True, f"all robots know their hop count by step {sim.step_count}")
    return Verdict(False, f"hops is not the hop count from robot 0 after {scenario.steps} "
                          "steps", tuple(mismatches(sim, "hops", expected)))


def check_leader(sim: Any, scenario: Scenario) -> Verdict:
    largest = max(s.robot_id for s in sim.robots)
    expected = [largest] * sim.count
    if run_until(sim, scenario.steps, lambda: globals_of(sim, "leader") == expected):
        return Verdict(True, f"the swarm agrees on leader {largest} at step {sim.step_count}")
    return Verdict(False, f"the swarm does not agree on the largest id ({largest}) within "
                          f"{scenario.steps} steps", tuple(mismatches(sim, "leader", expected)))


def check_memory(sim: Any, scenario: Scenario) -> Verdict:
    delivered = np.zeros(sim.count, dtype=np.int64)
    for _ in range(scenario.steps):
        delivered += sim.step().received
        if sim.failures:
            break
    stopped = robot_errors(sim)
    if stopped is not None:
        peak = max(int(s.robot.vm.heap.peak_used) for s in sim.robots
                   if s.robot is not None and getattr(s.robot, "vm", None) is not None)
        return replace(stopped, summary=f"{stopped.summary} at step {sim.step_count} "
                                        f"(heap peak {peak} of {sim.robots[0].profile.heap_size}"
                                        " bytes): open the inspector's heap map",
                       look_at=stopped.look_at)
    wrong = mismatches(sim, "heard", delivered.tolist())
    if wrong:
        return Verdict(False, "heard is not the number of messages received", tuple(wrong))
    return Verdict(True, f"{scenario.steps} steps without running out of heap, every message "
                         "counted")


def check_first_flight(sim: Any, scenario: Scenario) -> Verdict:
    sim.run(scenario.steps)
    wrong = []
    for state in sim.robots:
        x, y, z = state.pose
        goal = (state.robot_id - 1.5, 0.0, 1.0)
        flying = bool(state.labels.get("flying"))
        if not flying:
            wrong.append(f"robot {state.robot_id} is not flying (z = {z:.2f} m)")
        elif np.hypot(x - goal[0], y - goal[1]) > 0.15 or abs(z - goal[2]) > 0.10:
            wrong.append(f"robot {state.robot_id} is at ({x:.2f}, {y:.2f}, {z:.2f}) m, "
                         f"expected ({goal[0]:.2f}, 0.00, 1.00)")
    if wrong:
        return Verdict(False, f"after {scenario.steps} steps the drones are not lined up",
                       tuple(wrong))
    return Verdict(True, "every drone flies at its place on the line")


def check_pitfalls(sim: Any, scenario: Scenario) -> Verdict:
    sim.run(scenario.steps)
    seconds_expected = round(scenario.steps * sim.world.step_seconds)
    wrong = []
    for state in sim.robots:
        if not state.labels.get("flying"):
            wrong.append(f"robot {state.robot_id} never took off: what does `not 0` give on "
                         "BittyBuzz?")
        seconds = state.global_value("seconds")
        if not isinstance(seconds, int) or abs(seconds - seconds_expected) > 1:
            wrong.append(f"robot {state.robot_id}: seconds is {seconds}, expected "
                         f"{seconds_expected}: does every intermediate value fit in int16?")
        front = float(sim.world.ranges[state.index, 0])
        expected_near = int(front < 1.0)
        near = state.global_value("near")
        if near != expected_near:
            wrong.append(f"robot {state.robot_id}: near is {near} with a wall {front:.2f} m "
                         f"ahead, expected {expected_near}: what is compared with what?")
    if wrong:
        return Verdict(False, "the three pitfalls are not all fixed", tuple(wrong))
    return Verdict(True, "flying, on time and seeing the wall: all three pitfalls avoided")


def check_shared_choice(sim: Any, scenario: Scenario) -> Verdict:
    sim.run(scenario.steps)
    bids = globals_of(sim, "bid")
    if not all(isinstance(b, int) for b in bids):
        return Verdict(False, "every drone needs a whole-number bid", tuple(
            f"robot {s.robot_id}: bid is {b}" for s, b in zip(sim.robots, bids, strict=True)))
    lowest = min(bids)
    wrong = mismatches(sim, "best", [lowest] * sim.count)
    for state, bid in zip(sim.robots, bids, strict=True):
        flying = bool(state.labels.get("flying"))
        if flying != (bid == lowest):
            wrong.append(f"robot {state.robot_id} (bid {bid}) is "
                         f"{'flying' if flying else 'on the floor'}; only the drone with bid "
                         f"{lowest} should fly")
    if wrong:
        return Verdict(False, f"the swarm has not settled on the lowest bid ({lowest}) after "
                              f"{scenario.steps} steps", tuple(wrong))
    return Verdict(True, f"all drones agree on bid {lowest}, and only its drone flies")


#: Lesson slug -> its check.
CHECKS: dict[str, Callable[[Any, Scenario], Verdict]] = {
    "first-light": check_first_light,
    "who-am-i": check_who_am_i,
    "neighbours": check_neighbours,
    "hop-count": check_hop_count,
    "leader": check_leader,
    "memory": check_memory,
    "first-flight": check_first_flight,
    "pitfalls": check_pitfalls,
    "shared-choice": check_shared_choice,
}
