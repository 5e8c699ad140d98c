"""`bbzide ide S.toml`: the IDE builds the scenario's swarm (options, positions, labels), drops
the scenario when the world or the robot count changes, and refuses what it cannot edit."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from bbzide.cli import main
from bbzide.ui import commands
from bbzide.ui.run_controller import RunController, RunSettings
from bbzide.ui.world_adapter import WorldsBackend
from bbzide.worlds.scenario import ScenarioError, load_scenario
from tests.ui.browser import free_port, wait_until
from tests.worlds.fingerprint import fingerprint

REPO = Path(__file__).resolve().parents[2]

SCENARIO = """version = 1
world = "kilobot"
seed = 4
watch = ["n"]
[world_options]
light = "uniform"
[[robots]]
count = 3
script = "a.bzz"
positions = [[0.0, 0.0], [0.05, 0.0], [0.0, 0.05]]
labels = { role = "dot" }
"""


@pytest.fixture
def scenario_file(tmp_path: Path) -> Path:
    (tmp_path / "a.bzz").write_text("var n = 7\nfunction init() {\n}\nfunction step() {\n}\n")
    path = tmp_path / "s.toml"
    path.write_text(SCENARIO)
    return path


def test_the_backend_builds_the_scenario_swarm(scenario_file: Path) -> None:
    backend = WorldsBackend()
    scenario = load_scenario(scenario_file)
    _, program = backend.compile((scenario_file.parent / "a.bzz").read_text(),
                                 scenario_file.parent / "a.bzz", "kilobot")
    handle = backend.create("kilobot", program, 3, 9, scenario=scenario)
    sim = handle.sim
    assert sim.seed == 9                                     # the IDE's seed wins
    assert np.allclose(sim.positions[:, :2], [[0.0, 0.0], [0.05, 0.0], [0.0, 0.05]])
    assert sim.world.light_kind == "uniform"
    assert [s.labels for s in sim.robots] == [{"role": "dot", "n": 7}] * 3


def test_changing_the_robot_count_leaves_the_scenario(scenario_file: Path) -> None:
    scenario = load_scenario(scenario_file)
    controller = RunController(WorldsBackend(), RunSettings("kilobot", 3, 4, 0.0,
                                                            scenario=scenario))
    controller.update_settings(seed=5)
    controller._apply_commands()  # noqa: SLF001 - the loop's own step, without its thread
    assert controller.settings.scenario is scenario
    controller.update_settings(robots=5)
    controller._apply_commands()  # noqa: SLF001
    assert controller.settings.scenario is None


def test_ide_opens_a_scenario_on_its_script_and_swarm(scenario_file: Path, monkeypatch,
                                                      capsys) -> None:
    started = {}

    def serve(app, open_browser):  # noqa: ANN001, ANN202 - stands for the Ctrl-C loop
        started["app"] = app
        try:
            wait_until(lambda: app.controller.last_frame is not None)
            with app.controller.locked() as handle:
                started["positions"] = handle.frame().positions.copy()
        finally:
            app.stop()
        return 0

    monkeypatch.setattr(commands, "serve_until_interrupted", serve)
    assert main(["ide", str(scenario_file), "--no-browser", "--paused", "--port",
                 str(free_port())]) == 0
    app = started["app"]
    assert app.controller.settings.robots == 3 and app.controller.settings.seed == 4
    assert np.allclose(started["positions"][:, :2], [[0.0, 0.0], [0.05, 0.0], [0.0, 0.05]])
    assert f"editing {scenario_file.parent / 'a.bzz'}" in capsys.readouterr().out


@pytest.mark.parametrize("extra, words", [(["--robots", "4"], "--robots cannot be combined"),
                                          (["--world", "crazyflie"], "--world cannot be")])
def test_ide_refuses_options_a_scenario_pins(scenario_file: Path, extra, words, capsys) -> None:
    assert main(["ide", str(scenario_file), "--no-browser", *extra]) == 1
    assert words in capsys.readouterr().err


def test_ide_refuses_a_scenario_with_two_scripts(scenario_file: Path, capsys) -> None:
    (scenario_file.parent / "b.bzz").write_text("function step() {\n}\n")
    scenario_file.write_text('version = 1\nworld = "kilobot"\n[[robots]]\ncount = 1\n'
                             'script = "a.bzz"\n[[robots]]\ncount = 1\nscript = "b.bzz"\n')
    assert main(["ide", str(scenario_file), "--no-browser"]) == 1
    assert "the IDE edits one script and this scenario runs 2" in capsys.readouterr().err


def controller_running(scenario_file: Path, scenario=None, robots: int = 3) -> RunController:
    """A controller with the real backend and a.bzz loaded, driven without its thread."""
    backend = WorldsBackend()
    script = scenario_file.parent / "a.bzz"
    _, program = backend.compile(script.read_text(), script, "kilobot")
    controller = RunController(backend, RunSettings("kilobot", robots, 4, 0.0,
                                                    scenario=scenario))
    controller.load_program(program)
    controller._apply_commands()  # noqa: SLF001 - the loop's own step, without its thread
    return controller


def test_saving_the_running_setup_keeps_the_scenario_and_the_run(scenario_file: Path,
                                                                 tmp_path: Path) -> None:
    scenario = load_scenario(scenario_file)
    controller = controller_running(scenario_file, scenario)
    controller.update_settings(seed=8)
    controller._apply_commands()  # noqa: SLF001
    saved = load_scenario(controller.save_setup(tmp_path / "saved.toml",
                                                scenario_file.parent / "a.bzz"))
    assert saved == scenario.with_seed(8)          # options, positions, labels, watch, new seed
    assert fingerprint(saved.simulation(), 5) == fingerprint(scenario.with_seed(8).simulation(),
                                                             5)


def test_saving_a_plain_setup_with_pinned_positions(scenario_file: Path, tmp_path: Path) -> None:
    controller = controller_running(scenario_file, robots=4)
    with controller.locked() as handle:
        handle.step()
        where = handle.sim.positions.copy()
    saved = load_scenario(controller.save_setup(tmp_path / "here.toml",
                                                scenario_file.parent / "a.bzz",
                                                pin_positions=True))
    assert (saved.world, saved.robots, saved.seed) == ("kilobot", 4, 4)
    assert saved.world_options == {} and saved.scripts() == [
        (scenario_file.parent / "a.bzz").resolve()]
    assert np.array_equal(np.array(saved.groups[0].positions), where)


def test_saving_to_a_name_that_is_not_toml_is_refused(scenario_file: Path, tmp_path: Path) -> None:
    controller = controller_running(scenario_file, robots=2)
    with pytest.raises(ScenarioError, match="a scenario file ends in .toml"):
        controller.save_setup(tmp_path / "x.txt", scenario_file.parent / "a.bzz")
