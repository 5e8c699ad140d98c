"""Kilobot table: motion from the two motors, walls, light sensor, host functions, delay."""

import math

import numpy as np
import pytest

from bbzide.worlds.engine import Simulation
from bbzide.worlds.kilobot import FORWARD_SPEED, TURN_RATE, KilobotTable
from tests.worlds.doubles import factory


def one_kilobot(command, heading=0.0, position=(0.0, 0.0), **world):
    def drive(robot, step):
        robot.call(*command)
        return []

    table = KilobotTable(motion_noise=0.0, **world)
    return Simulation(table, program="p", robots=1, seed=0,
                      positions=np.array([[*position, 0.0]]), headings=np.array([heading]),
                      robot_factory=factory(drive))


def test_both_motors_walk_forward_at_one_cm_per_second():
    sim = one_kilobot(("set_motor", 120, 120), heading=math.pi / 2)
    sim.run(50)   # 5 s
    x, y, _ = sim.robots[0].pose
    assert x == pytest.approx(0.0, abs=1e-6)
    assert y == pytest.approx(5 * FORWARD_SPEED, rel=0.02)


@pytest.mark.parametrize("motors, sign", [((200, 0), -1), ((0, 200), 1)])
def test_one_motor_pivots(motors, sign):
    sim = one_kilobot(("set_motor", *motors))
    sim.run(10)   # 1 s
    assert sim.robots[0].heading == pytest.approx(sign * TURN_RATE, rel=0.02)
    assert np.hypot(*sim.robots[0].pose[:2]) < 1e-6


def test_walls_stop_a_robot():
    sim = one_kilobot(("motion", 1), position=(0.25, 0.0), width=0.6, height=0.6)
    sim.run(1000)   # 100 s at 1 cm/s would be 1 m: the wall at x = 0.3 stops it
    x = sim.robots[0].pose[0]
    assert 0.3 - 0.0165 - 0.003 < x <= 0.3 - 0.0165 + 1e-3


def test_robots_do_not_overlap():
    def drive(robot, step):
        robot.call("motion", 1)
        return []

    sim = Simulation("kilobot", program="p", robots=16, seed=4, robot_factory=factory(drive),
                     world_options={"width": 0.3, "height": 0.3})
    sim.run(300)
    xy = sim.positions[:, :2]
    gaps = np.linalg.norm(xy[:, None] - xy[None], axis=2) + np.eye(16)
    assert gaps.min() > 2 * 0.0165 * 0.9


def test_led_light_rand_abs_and_errors():
    seen = {}

    def probe(robot, step):
        seen["led"] = robot.call("led", 5)
        seen["light"] = robot.call("light").returned[0]
        seen["rand"] = [robot.call("rand").returned[0] for _ in range(50)]
        seen["abs"] = robot.call("abs", -7).returned[0], robot.call("abs", -32768).returned[0]
        seen["bad"] = robot.call("led", "red").failed, robot.call("motion", 9).failed
        seen["lnum"] = robot.call("set_motor", 1).failed
        return []

    sim = Simulation("kilobot", program="p", robots=1, seed=0, robot_factory=factory(probe),
                     positions=np.array([[0.25, 0.0, 0.0]]), world_options={"light": "gradient"})
    sim.step()
    assert sim.robots[0].led == (1.0, 0.0, 1.0)          # bits 0 and 2: red + blue
    assert abs(seen["light"] - 1023 * 0.75) <= 5          # gradient, 3/4 of the way across
    assert all(0 <= r <= 255 for r in seen["rand"]) and len(set(seen["rand"])) > 20
    assert seen["abs"] == (7, -32768)
    assert seen["bad"] == ("TYPE", "OUTOFRANGE")
    assert seen["lnum"] == "LNUM"


def test_delay_blocks_the_loop():
    def sleepy(robot, step):
        robot.call("delay", 450)   # 4 whole 100 ms steps skipped
        return []

    sim = Simulation("kilobot", program="p", robots=1, seed=0, robot_factory=factory(sleepy))
    sim.run(10)
    assert sim.robots[0].robot.steps == 2    # ran at steps 0 and 5


def test_thousand_robots_fit_on_a_two_metre_table():
    table = KilobotTable(width=2.0, height=2.0)
    assert table.max_robots() >= 1000
    positions, _ = table.place(1000, np.random.default_rng(0))
    gaps = np.linalg.norm(positions[:, None, :2] - positions[None, :, :2], axis=2)
    assert (gaps + np.eye(1000)).min() > 2 * 0.0165


def test_random_layout_scatters_without_overlap():
    positions, _ = KilobotTable(layout="random").place(40, np.random.default_rng(2))
    gaps = np.linalg.norm(positions[:, None, :2] - positions[None, :, :2], axis=2)
    assert (gaps + np.eye(40)).min() > 2 * 0.0165
    assert np.abs(positions[:, :2]).max() < 0.5 and positions[:, 0].std() > 0.2


def test_batched_bodies_move_exactly_as_body_by_body():
    """`advance` writes velocities and reads poses through pymunk.batch; the same swarm
    advanced body by body (its fallback) ends in the same poses, to the bit."""
    def wander(robot, step):
        robot.call("motion", (robot.robot_id + step // 7) % 4)
        return []

    def run(batched: bool) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        sim = Simulation("kilobot", program="p", robots=60, seed=9,
                         world_options={"width": 0.4, "height": 0.4, "spacing": 0.04},
                         robot_factory=factory(wander))
        assert sim.world._batched                 # pymunk visits our bodies in our order
        sim.world._batched = batched
        start = sim.positions.copy()
        sim.run(40)
        return start, sim.positions.copy(), sim.headings.copy()

    (start, p1, h1), (_, p2, h2) = run(True), run(False)
    assert np.array_equal(p1, p2) and np.array_equal(h1, h2)
    assert (np.hypot(*(p1 - start)[:, :2].T) > 0.005).sum() > 20   # most walked > 5 mm
