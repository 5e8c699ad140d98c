"""`bbzide memory`: the RAM a script needs on a platform (peak heap, smallest heap and stack by
bisection), checked against runs at the sizes it reports and one byte or entry less."""

import dataclasses
from pathlib import Path

from bbzide.cli import main
from bbzide.vm.profiles import CRAZYFLIE
from bbzide.worlds.commands import load_script
from bbzide.worlds.engine import RobotGroup, Simulation
from bbzide.worlds.memory import measure
from bbzide.worlds.registry import WORLDS

#: A script that keeps `N` table entries alive and, every step, recurses `DEPTH` calls deep.
SCRIPT = """
var kept = {}
var N = 0
var DEPTH = 0
function down(d) {
  if (d <= 0) { return 0 }
  return 1 + down(d - 1)
}
function init() {
  var i = 0
  while (i < N) {
    kept[i] = i * 3
    i = i + 1
  }
}
function step() {
  down(DEPTH)
}
"""

STEPS = 12


def program(tmp_path: Path, entries: int, depth: int):
    path = tmp_path / f"mem_{entries}_{depth}.bzz"
    path.write_text(SCRIPT.replace("var N = 0", f"var N = {entries}")
                    .replace("var DEPTH = 0", f"var DEPTH = {depth}"))
    return path, load_script(path, WORLDS["crazyflie"].host_names, [])


def fails(prog, profile) -> bool:
    sim = Simulation("crazyflie", None, seed=0, groups=[RobotGroup(1, prog, profile)])
    sim.run(STEPS)
    return bool(sim.failures)


def test_the_reported_sizes_are_the_least_that_run(tmp_path):
    path, prog = program(tmp_path, 30, 6)
    report = measure(path, prog, "crazyflie", "crazyflie", 1, STEPS, 0)
    assert report.heap_size == CRAZYFLIE.heap_size and report.stack_size == CRAZYFLIE.stack_size
    assert report.min_heap <= report.peak_heap < CRAZYFLIE.heap_size
    heap = dataclasses.replace(CRAZYFLIE, heap_size=report.min_heap)
    assert not fails(prog, heap)
    assert fails(prog, dataclasses.replace(CRAZYFLIE, heap_size=report.min_heap - 1))
    assert not fails(prog, dataclasses.replace(CRAZYFLIE, stack_size=report.min_stack))
    assert fails(prog, dataclasses.replace(CRAZYFLIE, stack_size=report.min_stack - 1))
    assert report.ram_bytes == report.min_heap + 2 * report.min_stack
    assert report.bytecode == len(prog.bbo)


def test_more_live_data_needs_more_heap_and_deeper_calls_more_stack(tmp_path):
    small = measure(*program(tmp_path, 5, 2), "crazyflie", "crazyflie", 1, STEPS, 0)
    more_data = measure(*program(tmp_path, 40, 2), "crazyflie", "crazyflie", 1, STEPS, 0)
    deeper = measure(*program(tmp_path, 5, 12), "crazyflie", "crazyflie", 1, STEPS, 0)
    assert more_data.min_heap > small.min_heap
    assert deeper.min_stack > small.min_stack


def test_the_command_prints_the_ram_and_refuses_bad_input(tmp_path, capsys):
    path, _ = program(tmp_path, 3, 1)
    assert main(["memory", str(path), "--platform", "crazyflie", "--robots", "1",
                 "--steps", str(STEPS)]) == 0
    out = capsys.readouterr().out
    assert "on crazyflie (heap 3500 B, stack 128 entries)" in out
    assert "RAM the script needs:" in out and "bytecode (flash):" in out
    for argv, words in (
            (["--platform", "zooids"], "give --world"),
            (["--steps", "0"], "--steps must be at least 1"),
            (["--world", "moon"], "unknown world"),
            (["--robots", "0"], "--robots must be at least 1")):
        assert main(["memory", str(path), *argv]) == 1
        assert words in capsys.readouterr().err
    assert main(["memory", str(tmp_path / "none.bzz")]) == 1
    assert "no such script" in capsys.readouterr().err


def test_a_script_that_fails_at_the_platform_sizes_is_reported(tmp_path, capsys):
    path, _ = program(tmp_path, 3, 200)          # 200 nested calls: beyond 128 stack entries
    assert main(["memory", str(path), "--robots", "1", "--steps", "3"]) == 1
    assert "fails on crazyflie with its own heap and stack" in capsys.readouterr().err


def test_another_platform_runs_in_its_own_world(tmp_path, capsys):
    path = tmp_path / "k.bzz"
    path.write_text("var t = {}\nfunction init() { t.a = 1 }\nfunction step() { t.b = 2 }\n")
    assert main(["memory", str(path), "--platform", "kilobot", "--robots", "2",
                 "--steps", "5"]) == 0
    out = capsys.readouterr().out
    assert "on kilobot (heap 1088 B, stack 96 entries): kilobot world, 2 robot(s)" in out
