"""Crazyflie lab: flight model, obstacles, multi-ranger, positioning, BLE loss vs rate."""

import numpy as np
import pytest

from bbzide.worlds.crazyflie import BLE_LOSS_BY_RATE, CrazyflieLab
from bbzide.worlds.engine import Simulation
from bbzide.worlds.radio import interpolate_loss
from tests.worlds.doubles import factory


def one_drone(plan, position=(0.0, 0.0), **world):
    log = []

    def fly(robot, step):
        for command in plan.get(step, []):
            log.append((step, robot.call(*command)))
        return []

    lab = CrazyflieLab(**world)
    sim = Simulation(lab, program="p", robots=1, seed=0,
                     positions=np.array([[*position, 0.0]]), robot_factory=factory(fly))
    return sim, log


def test_takeoff_goto_land():
    sim, _ = one_drone({0: [("takeoff", 1.0)], 60: [("goTo", 1.0, -1.0, 1.5)],
                        200: [("land",)]}, obstacles=())
    sim.run(60)
    assert sim.robots[0].pose[2] == pytest.approx(1.0, abs=0.05)
    assert sim.robots[0].labels["flying"]
    sim.run(140)
    assert np.allclose(sim.robots[0].pose, (1.0, -1.0, 1.5), atol=0.05)
    sim.run(100)
    assert sim.robots[0].pose[2] == 0.0 and not sim.robots[0].labels["flying"]


def test_speed_and_acceleration_limits():
    sim, _ = one_drone({0: [("takeoff", 1.0)], 40: [("goTo", 2.5, 0.0, 1.0)]}, obstacles=())
    sim.run(41)
    world = sim.world
    previous = world.velocities.copy()
    for _ in range(40):
        sim.step()
        v = world.velocities[0]
        assert np.hypot(v[0], v[1]) <= 1.0 + 1e-9
        assert np.linalg.norm(v - previous[0]) <= 2.0 * 0.05 + 1e-9
        previous = world.velocities.copy()


def test_obstacle_stops_the_drone_and_ranger_sees_it():
    sim, log = one_drone({0: [("takeoff", 0.5)], 20: [("goTo", 2.0, 0.0, 0.5)],
                          119: [("ranges",)]}, obstacles=[(1.0, -0.5, 1.4, 0.5)])
    sim.run(120)
    x = sim.robots[0].pose[0]
    assert x == pytest.approx(1.0 - 0.046, abs=1e-6)
    assert sim.robots[0].labels["bumps"] > 0
    ranges = log[-1][1].returned[0]
    assert ranges["front"] == pytest.approx(0.0, abs=1e-6)
    assert ranges["back"] == pytest.approx(x + 3.0 - 0.046, abs=1e-6)
    assert ranges["up"] == pytest.approx(2.5, abs=0.02)


def test_position_has_centimetre_noise():
    sim, log = one_drone({s: [("position",)] for s in range(200)}, position=(1.0, 2.0),
                         obstacles=())
    sim.run(200)
    xs = np.array([c.returned[0]["x"] for _, c in log])
    assert abs(xs.mean() - 1.0) < 0.003 and 0.005 < xs.std() < 0.015


def test_goto_is_ignored_on_the_ground():
    sim, _ = one_drone({0: [("goTo", 1.0, 1.0, 1.0)]}, obstacles=())
    sim.run(20)
    assert sim.robots[0].pose == (0.0, 0.0, 0.0)


def test_formations_chain_and_circle():
    chain, _ = CrazyflieLab(formation="chain").place(10, np.random.default_rng(0))
    assert np.allclose(np.diff(chain[:, 0]), 0.5)
    circle, _ = CrazyflieLab(formation="circle", obstacles=()).place(10, np.random.default_rng(0))
    assert np.allclose(np.linalg.norm(circle[1:, :2] - circle[0, :2], axis=1), 0.5)


def test_ble_loss_follows_the_papers_rates():
    assert interpolate_loss(BLE_LOSS_BY_RATE, np.array([2.0, 10.0, 20.0])).tolist() == [
        0.0, 0.0155, 0.019]

    def broadcast_every(period):
        return lambda robot, step: [b"x"] if step % period == 0 else []

    lost = {}
    for period, hz in ((10, 2), (1, 20)):
        sim = Simulation("crazyflie", program="p", robots=6, seed=1,
                         robot_factory=factory(broadcast_every(period)))
        sim.run(600)
        lost[hz] = sim.totals["dropped"] / (sim.totals["dropped"] + sim.totals["received"])
    assert lost[2] == 0.0
    assert 0.012 < lost[20] < 0.026


def test_reboot_in_the_air_lands():
    def first_firmware_flies(robot, step):
        if robot.program == "flies" and step == 0:
            robot.call("takeoff", 1.0)
        return []

    sim = Simulation(CrazyflieLab(obstacles=()), program="flies", robots=1, seed=0,
                     robot_factory=factory(first_firmware_flies))
    sim.run(60)
    assert sim.robots[0].pose[2] > 0.9
    sim.load_program("stays", keep_state=True)     # the new firmware never calls takeoff
    sim.run(80)
    assert sim.robots[0].pose[2] == 0.0 and not sim.robots[0].labels["flying"]
