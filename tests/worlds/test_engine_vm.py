"""The engine with real VMs: a stuck or crashing robot is marked and stops, the others go on;
`load_program` reboots the swarm on new bytecode."""

from pathlib import Path

from bbzide.worlds.commands import load_script
from bbzide.worlds.engine import RobotGroup, Simulation
from bbzide.worlds.registry import WORLDS

REPO = Path(__file__).resolve().parents[2]


def compile_text(tmp_path, name, text, world="kilobot"):
    path = tmp_path / f"{name}.bzz"
    path.write_text(text)
    return load_script(path, WORLDS[world].host_names, [])


def test_stuck_and_crashing_robots_stop_the_others_go_on(tmp_path):
    stuck = compile_text(tmp_path, "stuck", "function step() {\n  while (1) {\n  }\n}\n")
    crash = compile_text(tmp_path, "crash", "var t = 0\nfunction step() {\n  t = t + 1\n"
                                            "  if (t == 3) {\n    led(\"red\")\n  }\n}\n")
    talker = compile_text(tmp_path, "talker", "var n = 0\nfunction step() {\n"
                                              "  neighbors.broadcast(\"n\", n)\n  n = n + 1\n}\n")
    sim = Simulation("kilobot", seed=0, instruction_budget=2000, groups=[
        RobotGroup(1, stuck), RobotGroup(1, crash), RobotGroup(2, talker)])
    sim.run(6)
    stuck_state, crash_state, *talkers = sim.robots
    assert stuck_state.failure.reason == "BUDGET" and stuck_state.failure_step == 0
    assert stuck_state.failure.location.line in (2, 3)
    assert crash_state.failure.reason == "TYPE" and crash_state.failure_step == 2
    assert crash_state.failure.location.file.endswith("crash.bzz")
    assert [t.failure for t in talkers] == [None, None]
    assert [t.global_value("n") for t in talkers] == [6, 6]
    assert sim.stats.sent.tolist() == [0, 0, 1, 1]


def test_load_program_reboots_on_new_bytecode(tmp_path):
    gradient = load_script(REPO / "examples/kilobot/gradient.bzz",
                           WORLDS["kilobot"].host_names, [])
    counter = compile_text(tmp_path, "counter", "var k = 0\nfunction step() {\n  k = k + 1\n}\n")
    sim = Simulation("kilobot", gradient, robots=3, seed=1)
    sim.run(3)
    assert sim.robots[1].global_value("gradient") is not None
    positions = sim.positions.copy()
    sim.load_program(counter, keep_state=True)
    sim.run(2)
    assert [s.global_value("k") for s in sim.robots] == [2, 2, 2]
    assert sim.robots[1].global_value("gradient") is None
    assert sim.step_count == 5 and (sim.positions == positions).all()
    sim.load_program(gradient, keep_state=False)
    assert sim.step_count == 0 and sim.robots[0].global_value("gradient") == 0
