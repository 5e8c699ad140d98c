"""M300 field: flight model, camera, belief map and targets, doze, relay check, bad options,
and the flocking example on real VMs."""

import re
from pathlib import Path

import numpy as np
import pytest

from bbzide.worlds.commands import load_script
from bbzide.worlds.engine import Simulation
from bbzide.worlds.m300 import (
    BELIEF_FLOOR,
    MAX_CELLS,
    M300Field,
    draw_targets,
    generate_belief_map,
    load_belief_map,
    parse_targets,
)
from bbzide.worlds.radio import WorldConfigError
from bbzide.worlds.registry import WORLDS
from tests.worlds.doubles import factory

ROOT = Path(__file__).resolve().parents[2]


def one_drone(plan, position=(1.0, 10.0), **world):
    log = []

    def fly(robot, step):
        for command in plan.get(step, []):
            log.append((step, robot.call(*command)))
        return []

    field = M300Field(**{"size": 20.0, **world})
    sim = Simulation(field, program="p", robots=1, seed=0,
                     positions=np.array([[*position, 0.0]]), robot_factory=factory(fly))
    return sim, log


def test_takeoff_goto_at_speed_and_land():
    sim, log = one_drone({0: [("takeoff",)], 60: [("goto", 101, 100)], 59: [("arrived",)],
                          200: [("arrived",), ("position",)], 210: [("land",)]},
                         targets=0, speed=2.0, altitude=5.0)
    sim.run(60)
    assert sim.robots[0].pose[2] == pytest.approx(5.0)        # 1 m/s climb, 5 s
    assert log[1][1].returned == [1]                           # arrived at altitude
    sim.run(10)
    assert sim.robots[0].pose[0] == pytest.approx(1.0 + 10 * 0.2)  # 2 m/s = 0.2 m per step
    sim.run(140)
    arrived, position = log[-2][1], log[-1][1]
    assert arrived.returned == [1]
    assert position.returned == [{"x": 101, "y": 100, "z": 50, "cell": 5 * 10 + 5}]
    sim.run(60)
    assert sim.robots[0].pose[2] == 0.0 and sim.world.mode[0] == 0


def test_camera_sees_targets_in_its_footprint_only():
    # Footprint radius at 5 m with a 45 degree field of view: 5 tan(22.5°) = 2.07 m.
    sim, log = one_drone({0: [("camera",), ("takeoff",)], 60: [("camera",)],
                          61: [("goto", 100, 100)],
                          200: [("camera",)]}, targets=[(12.0, 10.0)])
    sim.run(201)
    assert sim.world.camera_radius == pytest.approx(2.071, abs=1e-3)
    assert log[0][1].returned == [None]                        # on the ground
    assert log[2][1].returned == [None]                        # 11 m away
    assert log[4][1].returned == [{"x": 120, "y": 100}]        # 2 m away: seen, geolocated
    assert sim.world.found_step[0] > 0


def test_missed_is_koopmans_random_search_law_for_the_camera_swath():
    # exp(-W L / A): W = 2 x 2.07 m swath, A = the cell's area.
    small, large = M300Field(size=20.0), M300Field(size=40.0)
    assert small.miss_percent(0) == 100
    assert small.miss_percent(20) == round(100 * np.exp(-4.142 * 2.0 / 4.0))   # 2 m: 13 %
    assert large.miss_percent(40) == round(100 * np.exp(-4.142 * 4.0 / 16.0))  # 4 m: 36 %
    assert [small.miss_percent(d) for d in (5, 10, 40)] == sorted(
        [small.miss_percent(d) for d in (5, 10, 40)], reverse=True)
    sim, log = one_drone({0: [("missed", 20), ("missed", -3)]})
    sim.run(1)
    assert [call.returned for _, call in log] == [[13], [100]]


def test_belief_map_generation_is_seeded_and_targets_follow_it():
    a = generate_belief_map(10, np.random.default_rng(5))
    b = generate_belief_map(10, np.random.default_rng(5))
    assert np.array_equal(a, b) and a.max() == 1.0 and a.min() >= BELIEF_FLOOR
    rng = np.random.default_rng(1)
    targets = np.vstack([draw_targets(a, 20.0, 3, rng, keep_out=5.0) for _ in range(200)])
    cells = (np.clip(targets[:, 1] // 2, 0, 9) * 10 + np.clip(targets[:, 0] // 2, 0, 9))
    beliefs = a.ravel()[cells.astype(int)]
    assert beliefs.mean() > a[:, 3:].mean() * 1.5            # drawn where the belief is high
    assert (targets[:, 0] >= 5.0).all()


def test_same_seed_same_map_and_targets_whatever_the_search():
    worlds = []
    for search in ("belief", "random"):
        sim = Simulation(M300Field(size=30.0, search=search), program="p", robots=3, seed=9,
                         robot_factory=factory(lambda r, s: []))
        worlds.append(sim.world)
    assert np.array_equal(worlds[0].belief, worlds[1].belief)
    assert np.array_equal(worlds[0].targets, worlds[1].targets)


def test_load_belief_map(tmp_path):
    path = tmp_path / "map.csv"
    path.write_text("0.1,0.5\n1.0,0.2\n")
    assert load_belief_map(path).shape == (2, 2)
    for bad in ([[0.1, 2.0], [0, 0]], [[0.1, 0.2]]):
        with pytest.raises(WorldConfigError):
            load_belief_map(bad)
    with pytest.raises(WorldConfigError):
        load_belief_map(tmp_path / "missing.csv")


@pytest.mark.parametrize("options, words", [
    ({"size": 8.0}, "smaller than"),
    ({"comm_range": -1.0}, "range"),
    ({"search": "spiral"}, "unknown search"),
    ({"targets": [(50.0, 1.0)]}, "inside the field"),
    ({"speed": 0.0}, "positive"),
    ({"targets": "26,24"}, "x:y positions"),
    ({"map_seed": -1}, "map_seed must be >= 0"),
    ({"threshold": 1000}, "within 0..100, got 1000"),
    ({"threshold": -5}, "within 0..100, got -5"),
    ({"cells": MAX_CELLS + 1}, f"at most {MAX_CELLS} x {MAX_CELLS} cells"),
    ({"belief_map": [[0.5] * 12] * 12}, "got 12 per side"),
])
def test_bad_options_are_user_errors(options, words):
    with pytest.raises(WorldConfigError, match=words):
        M300Field(**options)


def test_max_cells_is_the_sar_scripts_key_table():
    """Each belief cell needs its own stigmergy key in the SAR script: the world refuses more
    cells than the table names (they would all read and write one missing key)."""
    table = (ROOT / "examples" / "sar" / "belief_keys.bzz").read_text()
    keys = re.findall(r'^BK\[(\d+)\] = "c(\d+)"$', table, flags=re.MULTILINE)
    assert [(int(k), int(v)) for k, v in keys] == [(k, k) for k in range(MAX_CELLS ** 2)]
    M300Field(cells=MAX_CELLS)


def test_a_threshold_no_cell_reaches_names_the_threshold():
    """Targets drawn only where the prior reaches the threshold (`likely`) need such a cell."""
    with pytest.raises(WorldConfigError, match="no belief cell reaches 50 % "):
        one_drone({}, belief_map=[[0.1, 0.1], [0.1, 0.1]], threshold=50, targets_where="likely")


def test_doze_skips_steps_until_the_drone_changes_cell():
    steps = []   # world steps at which the robot ran its control step

    def fly(robot, step):
        steps.append(sims[0].step_count)
        if step == 0:
            robot.call("takeoff")
        if step == 60:
            robot.call("goto", 150, 100)
            robot.call("doze", 100)
        return []

    sims = []
    sims.append(Simulation(M300Field(size=20.0, targets=0), program="p", robots=1, seed=0,
                           positions=np.array([[11.0, 10.0, 0.0]]), robot_factory=factory(fly)))
    sims[0].run(100)
    # From x = 11 m at 0.2 m per step the drone enters the next 2 m cell (x >= 12 m) after
    # 5 steps: the robot is woken there, not 100 steps later.
    assert 61 not in steps and 66 in steps


def test_relay_complete_needs_a_networker_over_each_target_and_short_links():
    sim = Simulation(M300Field(size=30.0, targets=[(20.0, 10.0)]), program="p", robots=3,
                     seed=0, positions=np.array([[2.0, 10.0, 5], [11.0, 10.0, 5],
                                                 [20.0, 10.5, 5]]),
                     robot_factory=factory(lambda r, s: []))
    world = sim.world
    world.mode[:] = 1
    world.roles = ["root", "networker", "networker"]
    assert not world.relay_complete(sim)          # no relay links yet
    world.parents[:] = [-1, 0, 1]
    assert world.relay_complete(sim)
    sim.positions[1, 0] = 14.0                    # 12 m from the root: link too long
    assert not world.relay_complete(sim)


def test_flocking_example_sweeps_the_field_as_a_separated_connected_flock():
    """The example's claim: the drones sweep the field together (their cameras see most of the
    belief cells), never closer than 1 m to each other once airborne (separation), and each
    always has a neighbour in radio range (cohesion)."""
    spec = WORLDS["m300"]
    program = load_script(ROOT / spec.example, spec.host_names, [])
    sim = Simulation("m300", program, robots=5, seed=4, world_options={"size": 16.0,
                                                                       "targets": 0})
    # 600 steps: 5 s to climb, then the anchor's 3 lanes of 16 m at 1 m/s take 48 s.
    covered = np.zeros((10, 10), dtype=bool)
    ys, xs = np.mgrid[0:10, 0:10] + 0.5
    centres = np.column_stack([xs.ravel() * 1.6, ys.ravel() * 1.6])
    closest = []
    connected = []
    for step in range(600):
        sim.step()
        xy = sim.positions[:, :2]
        # A cell is covered once its centre has been inside some drone's camera footprint.
        seen = np.hypot(*(centres[:, None] - xy[None]).transpose(2, 0, 1))
        covered |= (seen <= sim.world.camera_radius).any(axis=1).reshape(10, 10)
        if step >= 60:                             # airborne (5 m at 1 m/s) and spread
            gaps = np.hypot(*(xy[:, None] - xy[None]).transpose(2, 0, 1))
            np.fill_diagonal(gaps, np.inf)
            closest.append(gaps.min())
            connected.append(bool((gaps <= sim.world.comm_range).any(axis=1).all()))
    assert not sim.failures
    assert covered.mean() >= 0.8
    assert min(closest) >= 1.0
    assert all(connected)


def test_targets_as_command_line_text():
    assert parse_targets("3") == 3
    assert parse_targets("26:24,10:5.5") == [(26.0, 24.0), (10.0, 5.5)]
    field = M300Field(size=36.0, targets="26:24")
    sim = Simulation(field, program="p", robots=1, seed=0,
                     robot_factory=factory(lambda robot, step: []))
    assert sim.world.targets.tolist() == [[26.0, 24.0]]


def test_likely_targets_lie_only_where_the_prior_reaches_the_threshold():
    belief = generate_belief_map(10, np.random.default_rng(3))
    rng = np.random.default_rng(4)
    targets = np.vstack([draw_targets(belief, 20.0, 3, rng, keep_out=5.0, floor=0.2)
                         for _ in range(100)])
    cells = belief[(targets[:, 1] // 2).astype(int), (targets[:, 0] // 2).astype(int)]
    assert cells.min() >= 0.2
    anywhere = np.vstack([draw_targets(belief, 20.0, 3, rng, keep_out=5.0) for _ in range(100)])
    assert belief[(anywhere[:, 1] // 2).astype(int), (anywhere[:, 0] // 2).astype(int)].min() < 0.2
    # The likely placement stays above the threshold; `anywhere` reaches the floor cells.
    priors: dict[str, list] = {"likely": [], "anywhere": []}
    for where, found in priors.items():
        options = {"targets_where": where}
        for seed in range(40):
            sim, _ = one_drone({}, **options)
            sim.seed = seed                  # a new map and targets per seed
            sim.world.attach(sim)
            world = sim.world
            found += [world.belief.ravel()[world.cell_of(x, y)] for x, y in world.targets]
    assert min(priors["likely"]) >= 0.2 and min(priors["anywhere"]) < 0.2
    assert M300Field().targets_where == "uniform"        # the default: §5.4.1's placement
    with pytest.raises(WorldConfigError, match="targets_where"):
        M300Field(targets_where="nowhere")
