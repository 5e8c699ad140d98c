"""The virtual stigmergy at its capacity behaves as BittyBuzz's Kilobot build measured in simavr.

benchmarks/steptime/vstig.bzz puts under an integer key (`vs.put(id, t)`). BittyBuzz's put
looks its key up by comparing a string object with the key object, and an integer never
equals a string, so every put of an integer key takes a new entry; entries learnt from the
neighbours' messages count towards BBZVSTIG_CAP (4 on the Kilobot) as well. Four robots each
put one key, robot 0 learns the other three at its second step, and its next put (t = 3, its
fourth control step) finds the stigmergy full: BBZVM_ERROR_VSTIG. The reference VM's per-step
counts are benchmarks/steptime/kilobot_cycles.csv (its rows stop where the VM stopped); the
model must run the same instructions and collections on the same messages and stop at the
same step, on the same instruction.
"""

from __future__ import annotations

import csv
from pathlib import Path

from bbzide.vm.profiles import get_profile
from bbzide.vm.robot import Robot
from bbzide.vm.states import Error, State
from bbzide.worlds.commands import load_script
from bbzide.worlds.registry import WORLDS

STEPTIME = Path(__file__).resolve().parents[2] / "benchmarks" / "steptime"
SCRIPT = STEPTIME / "vstig.bzz"
#: The calibration set-up (benchmarks/steptime/README.md): robot 0 and three peers running
#: the same script, every payload of a step delivered to the others before their next step.
ROBOTS = 4
#: Kilobot IR distances are in mm; any in-range distance gives the same stigmergy traffic.
DISTANCE_MM = 40.0


def reference_rows() -> list[dict[str, str]]:
    with (STEPTIME / "kilobot_cycles.csv").open(encoding="utf-8") as f:
        rows = csv.DictReader(line for line in f if not line.startswith("#"))
        return [r for r in rows if r["script"] == "benchmarks/steptime/vstig.bzz"]


def run_robot_zero(steps: int) -> tuple[list[tuple[int, int, int]], Robot]:
    """Robot 0's (instructions, collections, messages waiting) per control step."""
    program = load_script(SCRIPT, WORLDS["kilobot"].host_names, [])
    robots = [Robot(program, get_profile("kilobot"), i, host_functions={"led": lambda c: None})
              for i in range(ROBOTS)]
    for robot in robots:
        robot.boot()
    sent: list[list[bytes]] = [[] for _ in robots]
    counts = []
    for _ in range(steps):
        for robot in robots:
            for sender, payloads in enumerate(sent):
                if sender != robot.vm.robot:
                    for payload in payloads:
                        robot.receive(payload, DISTANCE_MM)
        vm = robots[0].vm
        waiting = len(list(vm.queues.inbox.indices()))
        before = (vm.instructions_executed, vm.heap.gc_runs)
        sent = [robot.control_step() for robot in robots]
        counts.append((vm.instructions_executed - before[0], vm.heap.gc_runs - before[1],
                       waiting))
    return counts, robots[0]


def test_a_put_into_a_full_stigmergy_stops_the_kilobot_at_the_reference_s_step() -> None:
    reference = reference_rows()
    assert [int(r["step"]) for r in reference] == [0, 1, 2]   # the reference stopped at step 3
    counts, robot = run_robot_zero(len(reference) + 1)
    # Same work on the same messages while the reference ran ...
    for row, (instructions, collections, waiting) in zip(reference, counts, strict=False):
        assert (instructions, collections, waiting) == (
            int(row["instructions"]), int(row["gc_runs"]), int(row["messages"])), row["step"]
    # ... and then the same stop: the put of step 3 into the 4 entries it learnt.
    assert robot.vm.state == State.ERROR and robot.vm.error == Error.VSTIG
    assert len(robot.vm.vstig.entries) == get_profile("kilobot").vstig_cap
    assert sorted(e.key for e in robot.vm.vstig.entries) == [0, 1, 2, 3]
    assert robot.vm.error_events == [("VSTIG", robot.vm.error_events[0][1])]
    assert "vstig.bzz:11:" in str(robot.failure)          # `vs.put(id, t)`, not the get


def test_entries_learnt_from_messages_fill_the_stigmergy_without_an_error() -> None:
    # After two steps robot 0 holds its own key and the three it learnt: the cap, reached
    # without an error (bbzvstig_put checks the size; bbzmsg_process_vstig does not).
    counts, robot = run_robot_zero(2)
    assert robot.failure is None and len(robot.vm.vstig.entries) == 4
