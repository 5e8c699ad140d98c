"""`bbzide run --world` and `bbzide worlds`: bad input is a one-line error, never a traceback."""

import re
from pathlib import Path

import pytest

from bbzide.cli import main
from bbzide.vm import swarm_batch

REPO = Path(__file__).resolve().parents[2]
GRADIENT = REPO / "examples" / "kilobot" / "gradient.bzz"


@pytest.mark.parametrize("extra, words", [
    (["--world", "mars"], "unknown world 'mars'"),
    (["--world", "kilobot", "--robots", "0"], "at least 1 robot"),
    (["--world", "kilobot", "--robots", "5000"], "do not fit"),
    (["--world", "kilobot", "--comm-range", "-0.1"], "range must be >= 0"),
    (["--world", "kilobot", "--loss", "1.5"], "loss probability"),
    (["--world", "kilobot", "--set", "light=disco"], "unknown light field"),
    (["--world", "kilobot", "--set", "colour=red"], "bad option"),
    (["--world", "kilobot", "--set", "width"], "KEY=VALUE"),
    (["--world", "crazyflie", "--set", "formation=chain", "--robots", "40"], "do not fit"),
    # an unknown option names the ones the world has
    (["--world", "kilobot", "--set", "colour=red"], "width, height, light"),
    # a word where a number is expected, a fraction where a count is, a non-finite number
    (["--world", "kilobot", "--set", "width=abc"], "width=abc: a number is needed"),
    (["--world", "kilobot", "--set", "loss=abc"], "loss=abc: a number is needed"),
    (["--world", "m300", "--set", "cells=2.5"], "cells=2.5: a whole number is needed"),
    (["--world", "kilobot", "--set", "width=nan"], "width=nan: a finite number is needed"),
    (["--world", "kilobot", "--set", "spacing=inf"], "a finite number is needed"),
    # a list-valued option cannot be given as KEY=VALUE
    (["--world", "crazyflie", "--set", "obstacles=3"], "obstacles cannot be set"),
    (["--world", "kilobot", "--seed", "-1"], "--seed must be >= 0"),
    (["--world", "kilobot", "--threads", "0"], "--threads must be >= 1"),
    (["--world", "m300", "--set", "map_seed=-1"], "map_seed must be >= 0, got -1"),
    (["--world", "m300", "--set", "cells=20"], "at most 10 x 10 cells, got 20"),
    (["--world", "m300", "--set", "threshold=1000"], "within 0..100, got 1000"),
    (["--world", "crazyflie", "--set", "spacing=-1"], "spacing -1 m is less than a Crazyflie"),
])
def test_bad_parameters(extra, words, capsys):
    assert main(["run", str(GRADIENT), *extra]) == 1
    err = capsys.readouterr().err
    assert words in err and "Traceback" not in err


def test_script_that_does_not_compile(tmp_path, capsys):
    script = tmp_path / "broken.bzz"
    script.write_text("function step() {\n  led(1\n}\n")
    assert main(["run", str(script), "--world", "kilobot"]) == 1
    err = capsys.readouterr().err
    assert "broken.bzz:3" in err and "Traceback" not in err


def test_missing_script(capsys):
    assert main(["run", "nowhere.bzz", "--world", "kilobot"]) == 1
    assert "no such script" in capsys.readouterr().err


def test_worlds_lists_every_world(capsys):
    assert main(["worlds"]) == 0
    out = capsys.readouterr().out
    assert "kilobot" in out and "crazyflie" in out and "set_motor" in out


def test_a_run_prints_speed_traffic_and_errors_with_source_lines(tmp_path, capsys):
    script = tmp_path / "crash.bzz"
    script.write_text("var n = 0\nfunction step() {\n  neighbors.broadcast(\"n\", n)\n"
                      "  n = n + 1\n  if (n == 3) {\n    n = n / 0\n  }\n}\n")
    assert main(["run", str(script), "--world", "kilobot", "--robots", "3", "--steps", "5"]) == 0
    out = capsys.readouterr().out
    assert "world kilobot: 3 robots, 5 steps" in out and "steps/s" in out
    assert "messages: 6 sent" in out                  # 2 steps x 3 robots before the crash
    assert "errors: 3 robot(s)" in out
    assert "robot 0 and 2 other(s) (step 2): MATH" in out and "crash.bzz:" in out


def test_a_host_function_of_another_world_is_named_in_the_error(tmp_path, capsys):
    script = tmp_path / "wrong_world.bzz"
    script.write_text("function init() {}\nfunction step() {\n  takeoff()\n}\n")
    assert main(["run", str(script), "--world", "kilobot", "--robots", "2", "--steps", "2"]) == 0
    out = capsys.readouterr().out
    assert "TYPE at" in out and "wrong_world.bzz:" in out
    assert "hint: takeoff() is a host function of the crazyflie, m300 worlds, not of kilobot" in out


def test_an_error_in_a_script_with_non_utf8_bytes_still_shows_its_line(tmp_path, capsys):
    script = tmp_path / "latin1.bzz"
    script.write_bytes(b"s = \"caf\xe9\"\nfunction init() {}\nfunction step() {\n  y = 1 / 0\n}\n")
    assert main(["run", str(script), "--world", "kilobot", "--robots", "1", "--steps", "2"]) == 0
    out = capsys.readouterr().out
    assert "MATH at" in out and "latin1.bzz:5:0" in out   # bzzparse's position: the `}`


LOOP_1000 = ("function init() {}\nfunction step() {\n  var i = 0\n"
             "  while (i < 1000) { i = i + 1 }\n}\n")


def test_budget_and_loop_apply_to_every_robot_of_a_world(tmp_path, capsys):
    script = tmp_path / "busy.bzz"
    script.write_text(LOOP_1000)
    base = ["run", str(script), "--world", "kilobot", "--robots", "2", "--steps", "3"]
    assert main(base) == 0
    assert "errors: none" in capsys.readouterr().out
    assert main([*base, "--budget", "500"]) == 0        # ~6 instructions per iteration
    assert "BUDGET at" in capsys.readouterr().out
    returns = tmp_path / "returns.bzz"
    returns.write_text("function init() {}\nfunction step() {\n  return 1\n}\n")
    long = ["run", str(returns), "--world", "kilobot", "--robots", "1", "--steps", "300"]
    assert main(long) == 0
    assert "errors: none" in capsys.readouterr().out
    assert main([*long, "--loop", "robot"]) == 0     # the firmware keeps step's return value
    assert "STACK" in capsys.readouterr().out


@pytest.mark.parametrize("extra, words", [
    (["--dump"], "--dump is for one robot"),
    (["--inject", "x.txt"], "--inject is for one robot"),
    (["--reg", "log=print"], "--reg is for one robot"),
    (["--robot", "3"], "--robot is for one robot"),
    (["--budget", "-1"], "--budget must be >= 1"),
    (["--budget", "0"], "--budget must be >= 1"),
])
def test_single_robot_options_are_refused_with_a_world(extra, words, capsys):
    assert main(["run", str(GRADIENT), "--world", "kilobot", "--steps", "1", *extra]) == 1
    err = capsys.readouterr().err
    assert words in err and "Traceback" not in err


def test_a_bbo_compiled_for_another_string_table_is_refused(tmp_path, capsys):
    # Strings are ids in a .bbo: one compiled without the world's table calls the wrong host
    # functions (the gradient sent no message at all). The .bo beside it tells which table.
    script = tmp_path / "g.bzz"
    script.write_text(GRADIENT.read_text())
    run = ["run", str(tmp_path / "g.bbo"), "--world", "kilobot", "--robots", "3", "--steps", "5"]
    assert main(["compile", str(script), "--bbo", str(tmp_path / "g.bbo")]) == 0
    capsys.readouterr()
    assert main(run) == 1
    err = capsys.readouterr().err
    assert "string table" in err and "--platform kilobot" in err
    assert main(["compile", str(script), "--platform", "kilobot", "--bbo",
                 str(tmp_path / "g.bbo")]) == 0
    capsys.readouterr()
    assert main(run) == 0
    assert "messages: 0 sent" not in capsys.readouterr().out


def test_an_undefined_call_is_reported_at_its_line_in_plain_words(tmp_path, capsys):
    """The call's own line and column (bzzparse's debug info would say the `}` after it)."""
    script = tmp_path / "student.bzz"
    script.write_text("function init() {}\nfunction step() {\n  led(1)\n  nosuchfunction(id)\n}\n")
    assert main(["run", str(script), "--world", "kilobot", "--robots", "2", "--steps", "2"]) == 0
    out = capsys.readouterr().out
    assert (f"robot 0 and 1 other(s) (step 0): TYPE at {script}:4:2, pc ") in out
    assert "`nosuchfunction` is nil here: it is not defined, and no host function of the " \
           "Kilobot has that name\n      nosuchfunction(id)" in out


def test_globals_read_but_never_defined_are_warned_before_the_run(tmp_path, capsys):
    script = tmp_path / "typo.bzz"
    script.write_text("var gradient = 1\nfunction init() {}\nfunction step() {\n"
                      "  lde(gradiant)\n  led(gradient)\n}\n")
    assert main(["run", str(script), "--world", "kilobot", "--robots", "1", "--steps", "1"]) == 0
    warnings = [line for line in capsys.readouterr().err.splitlines() if "warning" in line]
    assert len(warnings) == 2
    assert warnings[0].startswith(f"{script}:4:2: warning: `lde` is never defined: it is not a "
                                  "global of the script, nor a host function of the Kilobot")
    assert "Known names: `led`, " in warnings[0]          # the close match first
    assert warnings[1].startswith(f"{script}:4:6: warning: `gradiant` is never defined")
    assert "Known names: `gradient`, " in warnings[1]


def test_a_run_prints_each_robots_heap_peak_and_warns_near_the_limit(tmp_path, capsys):
    script = tmp_path / "grow.bzz"
    script.write_text("t = {}\nfunction init() {}\nfunction step() {\n"
                      "  if (id == 1) {\n    t[size(t)] = size(t)\n  }\n}\n")
    assert main(["run", str(script), "--world", "kilobot", "--robots", "3", "--steps", "60"]) == 0
    out = capsys.readouterr().out
    [heap] = [line for line in out.splitlines() if line.startswith("heap peak: ")]
    peaks = {int(robot): int(peak) for robot, peak in re.findall(r"robot (\d+) (\d+) B", heap)}
    assert sorted(peaks) == [0, 1, 2] and heap.endswith(
        "of the 1088 B heap (kilobot profile, 2048 B of RAM)")
    assert peaks[1] > peaks[0] == peaks[2]      # only robot 1 grows its table
    assert "warning: robot(s) 1 used up to " in out and "may stop them with MEM" in out


def test_threads_split_a_large_swarms_steps_and_change_nothing_of_the_run(tmp_path, capsys):
    scenario = tmp_path / "gradient.toml"
    scenario.write_text(
        'version = 1\nworld = "kilobot"\nsteps = 25\nwatch = ["gradient", "heard"]\n'
        '[world_options]\nwidth = 2.0\nheight = 2.0\n'
        f'[[robots]]\ncount = 300\nscript = "{GRADIENT}"\n')
    printed = []
    try:
        for threads in ("1", "3"):
            assert main(["run", str(scenario), "--threads", threads]) == 0
            out = capsys.readouterr().out
            printed.append([line for line in out.splitlines()
                            if not line.startswith(("speed:", "time:"))])
    finally:
        swarm_batch.set_threads(1)  # the process's later runs
    watched = [line for line in printed[0] if line.startswith("watch gradient:")]
    assert len(watched) == 1 and len(set(watched[0].split()[2:])) > 3  # hops spread out
    assert printed[1] == printed[0]
