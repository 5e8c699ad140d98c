"""The names the IDE reads from the engine (bbzide/ui/world_adapter.py) exist and mean it."""

import numpy as np
import pytest

from bbzide.ui.world_adapter import WorldsBackend, WorldsSimulation
from bbzide.worlds.engine import Simulation
from tests.worlds.doubles import factory


def test_backend_lists_worlds_examples_and_platforms():
    backend = WorldsBackend()
    assert backend.default_world() == "kilobot"
    for world in ("kilobot", "crazyflie"):
        assert backend.example_path(world).exists()
        assert backend.platform(world).name == world
    assert backend.host_names("kilobot")[:4] == ["led", "set_motor", "delay", "abs"]


@pytest.mark.parametrize("world", ["kilobot", "crazyflie"])
def test_frame_and_geometry_follow_the_simulation(world):
    def blink(robot, step):
        robot.call("led", 2)
        return [b"hello"]

    sim = Simulation(world, program="p", robots=4, seed=0, robot_factory=factory(blink))
    view = WorldsSimulation(sim, None, WorldsBackend().platform(world))
    view.step()
    view.step()
    frame = view.frame()
    assert frame.step == 2 and frame.robot_ids == [0, 1, 2, 3]
    assert np.allclose(frame.positions, sim.positions[:, :2])
    assert np.allclose(frame.led_colors, [[0, 1, 0]] * 4)
    assert len(frame.links) == len(sim.links) > 0
    geometry = view.geometry()
    assert geometry.bounds == sim.world.bounds
    assert geometry.robot_radius == sim.world.robot_radius
    assert len(geometry.overlay_segments) == len(sim.world.walls)
