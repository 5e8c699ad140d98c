"""The search-and-rescue mission (examples/sar/sar.bzz on the M300 field, real VMs) and the
`bbzide experiment sar` runner (pairs, CSV, resume, plots, bad parameters)."""

import csv
import json
from collections import Counter

import numpy as np
import pytest

from bbzide.cli import main
from bbzide.diagnostics import UserError
from bbzide.vm import heap
from bbzide.worlds import sar_experiment as sx
from bbzide.worlds.engine import Simulation


def mission(search: str, drones: int = 10, seed: int = 11, max_steps: int = 2500):
    """Run the mission like the experiment runner does; returns (simulation, bytes sent)."""
    spec = sx.RunSpec(drones=drones, arena=20.0, search=search, trial=0, seed=seed)
    sim = Simulation("m300", sx._program(), robots=drones, seed=seed,
                     world_options=spec.world_options())
    sent = 0
    while sim.step_count < max_steps:
        sent += sim.step().total_bytes
        if (sim.step_count % 10 == 0 and (sim.world.found_step >= 0).all()
                and sim.world.relay_complete(sim)):
            break
    return sim, sent


@pytest.fixture(scope="module")
def belief_run():
    return mission("belief")


def test_belief_mission_finds_every_target_and_forms_the_relay_tree(belief_run):
    sim, _ = belief_run
    world = sim.world
    assert not sim.failures
    assert (world.found_step >= 0).all()
    assert world.relay_complete(sim)
    roles = Counter(world.roles)
    assert roles["root"] + roles["auctioneer"] == 1           # exactly one root was elected
    root = next(i for i, r in enumerate(world.roles) if r in ("root", "auctioneer"))
    assert np.hypot(*(sim.positions[root, :2] - world.rendezvous)) < 1.0
    # The root knows the three targets (as positions within the camera footprint of each).
    known = np.array(world.known_targets[root])
    assert len(known) == 3
    for target in world.targets:
        assert np.hypot(*(known - target).T).min() <= world.camera_radius
    # Every relay link is a networker whose chain reaches the root, links within range.
    links = world.relay_links()
    assert links and all(world.roles[c] == "networker" for c, _ in links)
    assert world.role_steps[root, 3] > 0                      # it spent time as auctioneer


def test_random_walk_variant_also_completes_without_stigmergy_traffic(belief_run):
    sim, sent = mission("random")
    assert not sim.failures and sim.world.relay_complete(sim)
    _, belief_sent = belief_run
    # Same starts, map and targets; the random walk sends no belief-map gossip.
    assert np.array_equal(sim.world.targets, belief_run[0].world.targets)
    assert sent < belief_sent / 3


def test_a_searcher_lowers_each_cell_it_crossed_by_what_its_camera_swept_there():
    """Thesis §5.3.2: a searcher decreases the belief where it saw no target. One drone, no
    targets: every cell it has left holds prior x missed(length flown in it) in the virtual
    stigmergy (the length measured here from its track, within a step of 0.2 m at each end)."""
    spec = sx.RunSpec(drones=1, arena=20.0, search="belief", trial=0, seed=3, targets=0)
    sim = Simulation("m300", sx._program(), robots=1, seed=3, world_options=spec.world_options())
    world = sim.world
    flown: Counter = Counter()
    cells_left = set()
    while sim.step_count < 400:
        before = sim.positions[0, :2].copy()
        cell = world.cell_of(*before)
        sim.step()
        if sim.positions[0, 2] > 4.99:
            flown[cell] += 10 * np.hypot(*(sim.positions[0, :2] - before))   # dm
        if world.cell_of(*sim.positions[0, :2]) != cell:
            cells_left.add(cell)
    vm = sim.robots[0].robot.vm
    strings = sx._program().strings
    lowered = {int(strings[e.key][1:]): vm.heap.int_value(e.value)
               for e in vm.vstig.entries if vm.heap.obj_type(e.value) == heap.INT}
    assert len(cells_left) >= 5
    assert set(lowered) <= cells_left
    prior = np.round(100 * world.belief.ravel()).astype(int)
    for cell, value in lowered.items():
        longest, shortest = flown[cell] + 4, max(flown[cell] - 4, 0)
        assert (prior[cell] * world.miss_percent(longest) // 100 - 1 <= value
                <= prior[cell] * world.miss_percent(shortest) // 100 + 1), cell
        assert value < prior[cell]
    # Cells it crossed for more than a few decimetres were lowered (a pass too short to change
    # the rounded percent is not put).
    assert all(c in lowered for c in cells_left
               if prior[c] * world.miss_percent(flown[c] + 4) // 100 < prior[c] - 1)


def settings(tmp_path, **changes):
    values = {"drones": [3], "arenas": [20.0], "searches": ["random", "belief"], "trials": 2,
              "seed": 5, "jobs": 1, "out": tmp_path / "out", "max_steps": 30}
    values.update(changes)
    return sx.SweepSettings(**values)


def test_pairs_share_their_seed_and_trials_differ(tmp_path):
    runs = sx.plan_runs(settings(tmp_path, drones=[3, 4]))
    assert len(runs) == 2 * 2 * 2
    by_trial = {}
    for r in runs:
        by_trial.setdefault((r.drones, r.trial), set()).add(r.seed)
    assert all(len(seeds) == 1 for seeds in by_trial.values())
    assert len({next(iter(s)) for s in by_trial.values()}) == 4


def test_sweep_writes_csv_and_plots_and_resumes(tmp_path, capsys):
    s = settings(tmp_path)
    results = sx.run_sweep(s)
    out = s.out
    assert len(results) == 4
    rows = list(csv.DictReader((out / "runs.csv").open()))
    assert [(r["search"], r["trial"]) for r in rows] == [
        ("belief", "0"), ("random", "0"), ("belief", "1"), ("random", "1")]
    assert all(r["complete_step"] == "-1" and r["steps"] == "30" for r in rows)  # timeouts
    assert (out / "comparison.csv").exists()
    table = (out / "summary.md").read_text().splitlines()
    assert table[0].startswith("| arena") and table[2].startswith("| 20 | 3 | 2 |")
    assert rows[0]["command"].startswith("bbzide run ") and "--seed" in rows[0]["command"]
    for name in ("find_time_arena20.png", "relay_time_arena20.png", "bandwidth.png"):
        assert (out / name).read_bytes()[:4] == b"\x89PNG"
    # Resume: a finished run is not run again; a torn one is.
    kept = out / "runs" / "d3_a20_belief_t000.json"
    torn = out / "runs" / "d3_a20_random_t001.json"
    before = kept.stat().st_mtime_ns
    torn.write_text("{not json")
    capsys.readouterr()
    again = sx.run_sweep(s)
    assert "resuming: 3 of 4" in capsys.readouterr().out
    assert kept.stat().st_mtime_ns == before
    assert json.loads(torn.read_text())["run_id"] == "d3_a20_random_t001"
    # Reproducible: the rerun of the torn run gives the same measurements.
    old = {r["run_id"]: r for r in results}["d3_a20_random_t001"]
    new = {r["run_id"]: r for r in again}["d3_a20_random_t001"]
    assert {k: v for k, v in old.items() if k != "wall_seconds"} == {
        k: v for k, v in new.items() if k != "wall_seconds"}
    # Another sweep into the same folder (other placement, other seed) is refused, and the
    # finished runs stay as they were.
    for change in ({"extra": {"targets_where": "anywhere"}}, {"seed": 6}):
        with pytest.raises(UserError, match="another sweep") as refused:
            sx.run_sweep(settings(tmp_path, **change))
        assert "--out" in str(refused.value)
    assert kept.stat().st_mtime_ns == before


def test_sign_test():
    assert sx.sign_test(0, 0) == 1.0
    assert sx.sign_test(10, 0) == pytest.approx(2 / 2 ** 10)
    assert sx.sign_test(5, 5) == 1.0


@pytest.mark.parametrize("extra, words", [
    (["--drones", "0,15"], "at least 1 drone"),
    (["--arena", "8"], "smaller than the 10 m communication range"),
    (["--search", "belief,spiral"], "unknown search 'spiral'"),
    (["--drones", "a"], "integers"),
    (["--trials", "0"], "--trials"),
    (["--seed", "-1"], "--seed must be >= 0"),
])
def test_bad_parameters_are_clear_errors(extra, words, tmp_path, capsys):
    assert main(["experiment", "sar", "--out", str(tmp_path), *extra]) == 1
    err = capsys.readouterr().err
    assert words in err and "Traceback" not in err


def test_an_output_folder_that_is_a_file_is_refused_and_kept(tmp_path, capsys):
    notes = tmp_path / "notes.txt"
    notes.write_text("my notes\n")
    assert main(["experiment", "sar", "--drones", "3", "--arena", "20", "--search", "random",
                 "--trials", "1", "--out", str(notes)]) == 1
    err = capsys.readouterr().err
    assert "is not a folder" in err and "Traceback" not in err
    assert notes.read_text() == "my notes\n"


def _settings(*argv):
    import argparse

    parser = argparse.ArgumentParser()
    sx.register(parser.add_subparsers())
    return sx.settings_from_args(parser.parse_args(["experiment", "sar", *argv]))


def test_the_field_preset_runs_3_trials_unless_trials_is_given_in_either_spelling():
    assert _settings("--preset", "field").trials == 3
    assert _settings("--preset", "field", "--trials", "5").trials == 5
    assert _settings("--preset", "field", "--trials=1").trials == 1
    assert _settings().trials == 30


def test_the_field_preset_refuses_drone_counts_and_arenas_it_would_ignore():
    with pytest.raises(UserError, match="--preset field"):
        _settings("--preset", "field", "--drones", "5")


@pytest.mark.parametrize("extra, words", [
    (["--robots", "0"], "at least 1 robot"),
    (["--set", "size=5"], "smaller than the 10 m communication range"),
    (["--set", "size=20", "--comm-range", "30"], "smaller than the 30 m communication range"),
    (["--set", "search=spiral"], "unknown search 'spiral'"),
    (["--set", "targets=26;24"], "x:y positions"),
])
def test_bad_mission_parameters_of_a_run_are_clear_errors(extra, words, capsys):
    assert main(["run", str(sx.SCRIPT), "--world", "m300", "--steps", "1", *extra]) == 1
    err = capsys.readouterr().err
    assert words in err and "Traceback" not in err


SAR_SCENARIO = sx.SCRIPT.parent / "sar.toml"


def test_a_scenario_gives_the_sweep_its_script_drones_options_seed_and_steps(tmp_path):
    (tmp_path / "mine.bzz").write_text(sx.SCRIPT.read_text())
    (tmp_path / "belief_keys.bzz").write_text((sx.SCRIPT.parent / "belief_keys.bzz").read_text())
    scenario = tmp_path / "mine.toml"
    scenario.write_text('version = 1\nworld = "m300"\nseed = 7\nsteps = 40\n'
                        '[world_options]\nsize = 24.0\nsearch = "random"\ncomm_range = 12.0\n'
                        'targets = [[5.0, 6.0]]\n'
                        '[[robots]]\ncount = 4\nscript = "mine.bzz"\n')
    settings = _settings("--scenario", str(scenario), "--trials", "1", "--out", str(tmp_path))
    assert (settings.drones, settings.arenas, settings.searches) == ([4], [24.0], ["random"])
    assert (settings.seed, settings.max_steps) == (7, 40)
    [spec] = sx.plan_runs(settings)
    assert spec.script == str((tmp_path / "mine.bzz").resolve())
    assert (spec.comm_range, spec.targets) == (12.0, ((5.0, 6.0),))
    result = sx.run_one(spec)
    assert result["steps"] == 40 and result["script"] == spec.script and result["targets"] == 1
    assert sx.reproduce_command(spec, 40)[1] == spec.script
    # the command line still sweeps over what the scenario pins
    widened = _settings("--scenario", str(scenario), "--drones", "3,5", "--seed", "2")
    assert (widened.drones, widened.seed, widened.arenas) == ([3, 5], 2, [24.0])


def test_the_shipped_sar_scenario_is_accepted():
    settings = _settings("--scenario", str(SAR_SCENARIO))
    assert (settings.drones, settings.arenas, settings.searches) == ([6], [36.0], ["belief"])
    assert (settings.seed, settings.max_steps) == (1, 3000)


@pytest.mark.parametrize("text, words", [
    ('world = "kilobot"\n[[robots]]\ncount = 3\nscript = "x.bzz"\n', "runs the m300 world"),
    ('world = "m300"\n[world_options]\nspeed = 2.0\n[[robots]]\ncount = 3\nscript = "x.bzz"\n',
     "does not vary speed"),
    ('world = "m300"\n[[robots]]\ncount = 1\nscript = "x.bzz"\npositions = [[1.0, 1.0]]\n',
     "leave out positions"),
    ('world = "m300"\n[[robots]]\ncount = 3\nscript = "x.bzz"\ncount = 2\n', "TOML syntax"),
    ('world = "m300"\n[[robots]]\ncount = 3\nscript = "broken.bzz"\n', "broken.bzz:1"),
])
def test_a_scenario_the_sweep_cannot_follow_is_refused_with_a_clear_error(tmp_path, text, words,
                                                                    capsys):
    (tmp_path / "x.bzz").write_text("function init() {\n}\nfunction step() {\n}\n")
    (tmp_path / "broken.bzz").write_text("function init( {\n")
    scenario = tmp_path / "s.toml"
    scenario.write_text("version = 1\n" + text)
    assert main(["experiment", "sar", "--scenario", str(scenario), "--out",
                 str(tmp_path / "out")]) == 1
    err = capsys.readouterr().err
    assert words in err.splitlines()[0] and "Traceback" not in err
