"""`bbzide run … --break FILE:LINE[:CONDITION] [--stop]`, through the real command line
(`bbzide.cli.main`), on the stepping test swarm's script."""

from __future__ import annotations

from pathlib import Path

import pytest

from bbzide.cli import main
from tests.debugger.swarms import STEPPING_SCRIPT


@pytest.fixture
def script(tmp_path: Path) -> Path:
    path = tmp_path / "swarm.bzz"
    path.write_text(STEPPING_SCRIPT)
    return path


def run(script: Path, *options: str) -> list[str]:
    return ["run", str(script), "--world", "kilobot", "--robots", "3", "--steps", "2",
            "--set", "width=0.2", "--set", "height=0.2", *options]


def test_each_hit_prints_robot_step_line_and_locals(script: Path, capsys) -> None:
    status = main(run(script, "--break", f"{script}:9:value > 0"))
    out = capsys.readouterr().out
    assert status == 0
    blocks = [block for block in out.split("hit ")[1:]]
    # step 1: robot 0 hears robots 1 and 2 (value > 0), robot 1 hears 2, robot 2 hears 1
    headers = [block.splitlines()[0] for block in blocks]
    assert headers == [
        "1: robot 0, control step 1, line 9 in lambda at line 8 (value > 0)",
        "2: robot 0, control step 1, line 9 in lambda at line 8 (value > 0)",
        "3: robot 1, control step 1, line 9 in lambda at line 8 (value > 0)",
        "4: robot 2, control step 1, line 9 in lambda at line 8 (value > 0)",
    ]
    assert "  value = 1\n" in blocks[0] and "  rid = 1\n" in blocks[0]
    assert "world kilobot: 3 robots, 2 steps" in out


def test_stop_ends_the_run_at_the_first_hit(script: Path, capsys) -> None:
    status = main(run(script, "--break", f"{script.name}:15", "--stop"))
    out = capsys.readouterr().out
    assert status == 0
    assert [line for line in out.splitlines() if line.startswith("hit ")] == [
        "hit 1: robot 0, control step 1, line 15 in lambda at line 14"]
    assert "stopped at the first hit (--stop): robot 0, control step 1" in out


@pytest.mark.parametrize(("spec", "message"), [
    ("{script}:40", "no such line (the file has 19 lines)"),
    ("{script}:12", "no code on this line (the next line with code is 13)"),
    ("{script}:13:total >", "condition 'total >' does not compile"),
    ("{script}", "expected FILE:LINE or FILE:LINE:CONDITION"),
    ("elsewhere.bzz:3", "no robot runs that file"),
])
def test_a_bad_spec_is_one_line(script: Path, capsys, spec: str, message: str) -> None:
    status = main(run(script, "--break", spec.format(script=script)))
    err = capsys.readouterr().err
    assert status == 1
    assert message in err and len(err.strip().splitlines()) == 1


def test_stop_without_break_is_refused(script: Path, capsys) -> None:
    assert main(run(script, "--stop")) == 1
    assert "give --break FILE:LINE" in capsys.readouterr().err


def test_break_in_a_scenario_file(script: Path, capsys) -> None:
    scenario = script.with_name("swarm.toml")
    scenario.write_text('version = 1\nworld = "kilobot"\nseed = 1\nsteps = 2\n'
                        '[world_options]\nwidth = 0.2\nheight = 0.2\n'
                        '[[robots]]\ncount = 2\nscript = "swarm.bzz"\n')
    status = main(["run", str(scenario), "--break", f"{script.name}:17:id == 1"])
    out = capsys.readouterr().out
    assert status == 0
    assert [line for line in out.splitlines() if line.startswith("hit ")] == [
        "hit 1: robot 1, control step 0, line 17 in step (id == 1)",
        "hit 2: robot 1, control step 1, line 17 in step (id == 1)"]
