"""Scenario files: every example ships one, save -> load gives the same run, and a malformed
file is refused with its file, line and key (bbzide/worlds/scenario.py)."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from bbzide.cli import main
from bbzide.worlds.scenario import (
    KeyLines,
    RobotGroupSpec,
    Scenario,
    ScenarioError,
    load_scenario,
    parse_scenario,
    pin_positions,
    save_scenario,
    scenario_text,
)
from tests.worlds.fingerprint import fingerprint

REPO = Path(__file__).resolve().parents[2]
EXAMPLES = REPO / "examples"


def included_scripts() -> set[Path]:
    """Scripts another example pulls in with `include` (not runnable on their own)."""
    found = set()
    for script in EXAMPLES.glob("*/*.bzz"):
        for name in re.findall(r'^include\s+"([^"]+)"', script.read_text(), re.MULTILINE):
            found.add((script.parent / name).resolve())
    return found


RUNNABLE = sorted(p for p in EXAMPLES.glob("*/*.bzz") if p.resolve() not in included_scripts())


def test_the_examples_are_all_found():
    assert len(RUNNABLE) >= 10
    assert EXAMPLES / "sar" / "belief_keys.bzz" not in RUNNABLE   # an include file


@pytest.mark.parametrize("script", RUNNABLE, ids=lambda p: f"{p.parent.name}/{p.stem}")
def test_every_example_ships_a_scenario_that_runs_it(script):
    scenario = load_scenario(script.with_suffix(".toml"))
    assert scenario.scripts() == [script.resolve()]
    assert scenario.world == script.parent.name or script.parent.name == "sar"
    assert scenario.steps > 0 and scenario.title
    sim = scenario.simulation()
    sim.run(min(scenario.steps, 10))                # it compiles, boots and runs cleanly
    assert sim.failures == [] and sim.count == scenario.robots


def write(tmp_path: Path, text: str, name: str = "s.toml") -> Path:
    (tmp_path / "a.bzz").write_text("function init() {\n}\nfunction step() {\n}\n")
    path = tmp_path / name
    path.write_text(text)
    return path


def small_gradient() -> Scenario:
    scenario = load_scenario(EXAMPLES / "kilobot" / "gradient.toml")
    return Scenario(world=scenario.world, groups=(RobotGroupSpec(
        count=6, script=scenario.groups[0].script, labels={"role": "cell"}),),
        seed=5, steps=8, watch=("gradient",), world_options={"spacing": 0.06},
        radio={"loss": 0.1}, title="small")


def test_save_then_load_gives_the_same_scenario_and_the_same_run(tmp_path):
    original = small_gradient()
    saved = save_scenario(original, tmp_path / "copy.toml")
    loaded = load_scenario(saved)
    assert loaded == original
    assert fingerprint(loaded.simulation(), 8) == fingerprint(original.simulation(), 8)
    # a different seed is a different run (the fingerprint can tell runs apart)
    assert fingerprint(loaded.with_seed(6).simulation(), 8) != fingerprint(
        original.simulation(), 8)


def test_pinned_positions_reproduce_the_placed_run(tmp_path):
    original = small_gradient()
    placed = original.simulation()          # step 0: where the world put the robots
    pinned = pin_positions(original, placed)
    assert pinned.groups[0].positions is not None and len(pinned.groups[0].positions) == 6
    loaded = load_scenario(save_scenario(pinned, tmp_path / "pinned.toml"))
    assert loaded == pinned
    assert fingerprint(loaded.simulation(), 8) == fingerprint(placed, 8)


def test_two_groups_and_passive_bodies_round_trip(tmp_path):
    path = write(tmp_path, """version = 1
world = "crazyflie"
steps = 3
[[robots]]
count = 2
script = "a.bzz"
positions = [[0.0, 0.0], [1.0, 0.5, 0.0]]
headings = [0.0, 1.5]
[[robots]]
count = 1
positions = [[-1.0, -1.0]]
labels = { role = "target", weight = 2 }
""")
    scenario = load_scenario(path)
    assert [g.count for g in scenario.groups] == [2, 1]
    assert scenario.groups[1].script is None and scenario.groups[1].labels["role"] == "target"
    sim = scenario.simulation()
    assert sim.count == 3 and sim.robots[2].robot is None           # a passive body
    assert tuple(sim.positions[1]) == (1.0, 0.5, 0.0)
    again = parse_scenario(scenario_text(scenario, tmp_path), tmp_path / "again.toml")
    assert again == scenario


BAD = [
    # (text after the header, expected line, expected key text, words of the message)
    ('version = 2\nworld = "kilobot"\n', 1, "version", "version 1"),
    ('world = "kilobot"\n', 1, None, "missing key 'version'"),
    ('version = 1\nworld = "kilobots"\n', 2, "world", "unknown world"),
    ('version = 1\nworld = "kilobot"\nseeds = 3\n', 3, "seeds", "unknown key"),
    ('version = 1\nworld = "kilobot"\nseed = -1\n[[robots]]\ncount = 1\n', 3, "seed", ">= 0"),
    ('version = 1\nworld = "kilobot"\n\n[world_options]\nwidth = 1.0\nspacingg = 0.1\n'
     '[[robots]]\ncount = 1\n', 6, "world_options.spacingg", "bad option"),
    ('version = 1\nworld = "kilobot"\n[world_options]\nwidth = "wide"\n[[robots]]\ncount = 1\n',
     4, "world_options.width", "number"),
    ('version = 1\nworld = "kilobot"\n[[robots]]\ncount = 2\nscript = "a.bzz"\n'
     '[[robots]]\n# the second group\ncount = -2\n', 8, "robots[1].count", ">= 1"),
    ('version = 1\nworld = "kilobot"\n[[robots]]\ncount = 1\nscript = "nope.bzz"\n', 5,
     "robots[0].script", "no such script"),
    ('version = 1\nworld = "kilobot"\n[[robots]]\ncount = 2\npositions = [\n  [0.0, 0.0],\n'
     '  [9.0, 0.0],\n]\n', 5, "robots[0].positions", "outside the world"),
    ('version = 1\nworld = "kilobot"\n[[robots]]\ncount = 1\nlabels = { role = { a = 1 } }\n',
     5, "robots[0].labels.role", "string or a number"),
    ('version = 1\nworld = "kilobot"\nwatch = ["ok", "2bad"]\n[[robots]]\ncount = 1\n', 3,
     "watch", "not a Buzz global"),
    ('version = 1\nworld = "kilobot"\n[radio]\nloss = 1.5\n[[robots]]\ncount = 1\n', 4,
     "radio.loss", "probability"),
    ('version = 1\nworld = "kilobot"\n[[robots]]\ncount = 5000\n', 3, "robots",
     "do not fit"),
]


@pytest.mark.parametrize("text, line, key, words", BAD)
def test_a_malformed_scenario_names_file_line_and_key(tmp_path, text, line, key, words):
    path = write(tmp_path, text)
    with pytest.raises(ScenarioError) as caught:
        load_scenario(path)
    message = str(caught.value)
    expected = f"{path.resolve()}:{line}: " + (f"{key}: " if key else "")
    assert message.startswith(expected), message
    assert words in message


def test_a_toml_syntax_error_gives_line_and_column(tmp_path):
    path = write(tmp_path, 'version = 1\nworld = "kilobot\n')
    with pytest.raises(ScenarioError, match=r"s\.toml:2:\d+: TOML syntax error"):
        load_scenario(path)


def test_key_lines_skip_multi_line_arrays_and_strings():
    lines = KeyLines('a = 1\nb = [\n  [1, 2],\n  "x = ]",\n]\n[t]\nc = """\n[not]\nd = 1\n"""\n'
                     '[[r]]\ne = 1\n[[r]]\n# comment\ne = 2\n')
    assert lines.line_of(("a",)) == 1 and lines.line_of(("b",)) == 2
    assert lines.line_of(("t", "c")) == 7
    assert ("not",) not in lines.lines and ("t", "d") not in lines.lines
    assert lines.line_of(("r", 0, "e")) == 12 and lines.line_of(("r", 1, "e")) == 15
    assert lines.line_of(("r", 1, "missing")) == 13       # falls back to its table
    dotted = KeyLines('version = 1\nworld_options.spacing = 0.07\n"a b".c = 2\n')
    assert dotted.line_of(("world_options", "spacing")) == 2
    assert dotted.line_of(("a b", "c")) == 3


def test_bbzide_run_takes_a_scenario_and_prints_the_watched_globals(capsys):
    assert main(["run", str(EXAMPLES / "kilobot" / "gradient.toml")]) == 0
    out = capsys.readouterr().out
    assert "world kilobot: 12 robots, 30 steps" in out and "seed 3" in out
    watched = re.search(r"watch gradient: ([\d ]+)", out).group(1).split()
    assert len(watched) == 12 and watched.count("0") == 1 and "255" not in watched


def test_bbzide_run_scenario_steps_and_seed_override_the_file(capsys):
    assert main(["run", str(EXAMPLES / "kilobot" / "leader.toml"), "--steps", "2",
                 "--seed", "9"]) == 0
    out = capsys.readouterr().out
    assert "6 robots, 2 steps" in out and "seed 9" in out


def test_bbzide_run_scenario_refuses_options_it_pins(capsys):
    assert main(["run", str(EXAMPLES / "kilobot" / "leader.toml"), "--robots", "3"]) == 1
    assert "--robots cannot be combined with a scenario file" in capsys.readouterr().err


def test_bbzide_run_reports_a_bad_scenario_in_one_line(tmp_path, capsys):
    path = write(tmp_path, 'version = 1\nworld = "kilobot"\n[[robots]]\ncount = 0\n')
    assert main(["run", str(path)]) == 1
    err = capsys.readouterr().err
    assert "s.toml:4: robots[0].count: must be >= 1" in err and "Traceback" not in err
