"""The engine with scripted firmware loops: step order, radio routing, failures, determinism."""

import numpy as np
import pytest

from bbzide.diagnostics import UserError
from bbzide.worlds.engine import WORLDS, RobotGroup, Simulation
from bbzide.worlds.radio import WorldConfigError
from tests.worlds.doubles import FakeFailure, factory


def chatty(robot, step):
    return [bytes([robot.robot_id, step % 256])]


def kilobots(positions, behaviour=chatty, **kwargs):
    positions = np.asarray(positions, dtype=float)
    return Simulation("kilobot", program="p", robots=len(positions), seed=3,
                      positions=positions, headings=np.zeros(len(positions)),
                      robot_factory=factory(behaviour), **kwargs)


def test_messages_arrive_next_step_with_distance_in_mm():
    sim = kilobots([[0, 0, 0], [0.06, 0, 0], [0.5, 0, 0]], radio={"loss_probability": 0.0,
                                                                 "distance_noise": 0.0})
    sim.step()
    a, b, far = (s.robot for s in sim.robots)
    assert a.inbox == [] and b.inbox == []          # latency: delivered at the next step
    assert sorted(sim.links) == [(0, 1), (1, 0)]
    sim.step()
    assert [m for m, *_ in b.inbox] == [bytes([0, 0])]
    assert b.inbox[0][1] == pytest.approx(60.0, abs=0.5)    # mm (robots barely moved)
    assert b.inbox[0][2] == 0.0                             # Kilobot IR has no bearing
    assert far.inbox == []
    assert sim.stats.total_sent == 3 and sim.stats.total_received == 2
    assert sim.totals["bytes"] == 12


def test_bearing_and_elevation_from_geometry():
    sim = Simulation("crazyflie", program="p", robots=2, seed=0,
                     positions=np.array([[0.0, 0, 0], [0.0, 0.5, 0.5]]),
                     headings=np.array([np.pi / 2, 0.0]), robot_factory=factory(chatty))
    sim.run(2)
    receiver = sim.robots[0].robot
    message, distance, azimuth, elevation = receiver.inbox[0]
    assert distance == pytest.approx(np.sqrt(0.5), abs=1e-6)
    assert azimuth == pytest.approx(0.0, abs=1e-6)      # straight ahead of a drone facing +y
    assert elevation == pytest.approx(np.pi / 4, abs=1e-6)


def test_bandwidth_queue_and_overflow():
    def burst(robot, step):
        return [bytes([i]) for i in range(4)] if robot.robot_id == 0 else []

    sim = kilobots([[0, 0, 0], [0.05, 0, 0]], behaviour=burst, radio={"loss_probability": 0.0})
    for _ in range(4):
        sim.step()
    # 1 transmission per step (Kilobot IR) and a queue of 10: the 4th step's burst finds 9
    # waiting (4+4+4 offered - 3 sent), so 1 fits and 3 are dropped at the sender.
    assert sim.totals["sent"] == 4
    assert sim.stats.dropped.tolist() == [3, 0]
    assert sim.radio.queue_length(0) == 9
    assert 16 == sim.totals["sent"] + sim.radio.queue_length(0) + sim.totals["dropped"]


def test_loss_rate_matches_probability():
    sim = kilobots([[0, 0, 0], [0.05, 0, 0]], radio={"loss_probability": 0.3})
    sim.run(400)
    received = sim.totals["received"]
    assert abs(received / (2 * 399) - 0.7) < 0.06


def test_failed_robot_is_marked_and_stops_others_go_on():
    def fails_at_3(robot, step):
        if robot.robot_id == 1 and step == 3:
            robot.failure = FakeFailure("MEM", pc=42)
            return []
        return chatty(robot, step)

    sim = kilobots([[0, 0, 0], [0.05, 0, 0]], behaviour=fails_at_3)
    sim.run(10)
    dead, alive = sim.robots[1], sim.robots[0]
    assert dead.failure.reason == "MEM" and dead.failure_step == 3
    assert dead.robot.steps == 4 and alive.robot.steps == 10
    assert sim.failures == [dead]


def test_same_seed_same_run_and_other_seed_differs():
    def drive(robot, step):
        robot.call("set_motor", 200, 200 if step % 7 else 0)
        return chatty(robot, step)

    def run(seed):
        sim = Simulation("kilobot", program="p", robots=12, seed=seed,
                         robot_factory=factory(drive))
        sim.run(30)
        return sim.positions.copy(), [list(s.robot.inbox) for s in sim.robots]

    p1, in1 = run(5)
    p2, in2 = run(5)
    p3, _ = run(6)
    assert np.array_equal(p1, p2) and in1 == in2
    assert not np.array_equal(p1, p3)


def test_heterogeneous_groups_and_passive_bodies():
    sim = Simulation("kilobot", seed=1, groups=[
        RobotGroup(3, program="p"), RobotGroup(2, program=None, labels={"role": "target"})],
        robot_factory=factory(chatty))
    sim.run(3)
    assert [s.robot is None for s in sim.robots] == [False] * 3 + [True] * 2
    assert sim.robots[4].labels == {"role": "target"}
    assert sim.totals["sent"] == 9


def test_load_program_reboots_and_keeps_or_resets_the_world():
    def drive(robot, step):
        robot.call("motion", 1)
        return []

    sim = Simulation("kilobot", program="a", robots=4, seed=2, robot_factory=factory(drive))
    start = sim.positions.copy()
    sim.run(20)
    moved = sim.positions.copy()
    sim.load_program("b", keep_state=True)
    assert all(s.robot.program == "b" and s.robot.steps == 0 for s in sim.robots)
    assert np.array_equal(sim.positions, moved) and sim.step_count == 20
    sim.load_program("c", keep_state=False)
    assert np.array_equal(sim.positions, start) and sim.step_count == 0


@pytest.mark.parametrize("kwargs, words", [
    ({"robots": 0}, "at least 1 robot"),
    ({"robots": 5000}, "do not fit"),
    ({"robots": 3, "radio": {"comm_range": -1.0}}, "range must be >= 0"),
    ({"robots": 3, "radio": {"loss_probability": 2.0}}, "loss probability"),
    ({"robots": 3, "radio": {"volume": 11}}, "unknown radio setting"),
])
def test_bad_parameters_are_user_errors(kwargs, words):
    with pytest.raises(WorldConfigError, match=words):
        Simulation("kilobot", program="p", seed=0, robot_factory=factory(chatty), **kwargs)


def test_unknown_world_is_a_user_error():
    with pytest.raises(UserError, match="unknown world 'mars'.*crazyflie.*kilobot"):
        Simulation("mars", program="p", robots=2)


def test_registry_names_what_the_ui_reads():
    for name, spec in WORLDS.items():
        assert spec.name == name and spec.default_robots >= 1
        world = spec.create()
        assert world.host_names == spec.host_names and world.profile_name == spec.profile
        assert len(world.bounds) == 4 and world.comm_range > 0 and world.robot_radius > 0


def test_receive_cap_per_step_drops_the_rest():
    ring = [[0.0, 0, 0]] + [[0.05 * np.cos(a), 0.05 * np.sin(a), 0] for a in np.arange(6)]
    sim = kilobots(ring, radio={"loss_probability": 0.0, "receive_cap_per_step": 2})
    sim.run(2)
    centre = sim.robots[0].robot
    assert len(centre.inbox) == 2                      # 6 neighbours sent, 2 taken
    assert sim.stats.dropped[0] == 4                  # counted at the receiver
    assert [m[0] for m, *_ in centre.inbox] == sorted(m[0] for m, *_ in centre.inbox)


def test_asynchronous_robots_hear_later_phases_in_the_same_step():
    sim = kilobots([[0, 0, 0], [0.05, 0, 0]], radio={"loss_probability": 0.0},
                   asynchronous=True)
    early, late = np.argsort(sim.phases)
    sim.step()
    # the late robot already heard the early one's step-0 message; the early one hears the
    # late one's only at its step 1
    assert [m for m, *_ in sim.robots[late].robot.inbox] == [bytes([early, 0])]
    assert sim.robots[early].robot.inbox == []
    sim.step()
    assert [m for m, *_ in sim.robots[early].robot.inbox] == [bytes([late, 0])]
    assert sim.totals["sent"] == 4 and sim.totals["received"] == 3
    # what each robot sent this step, by robot index (phase order does not matter)
    outbox = sim.step_outbox
    assert outbox.robots.tolist() == [0, 1]
    assert [outbox.payload(k) for k in range(2)] == [bytes([0, 1]), bytes([1, 1])]


def test_asynchronous_runs_are_deterministic_and_lose_at_the_set_rate():
    def run():
        sim = kilobots([[0, 0, 0], [0.05, 0, 0], [0.0, 0.05, 0]],
                       radio={"loss_probability": 0.25}, asynchronous=True)
        sim.run(300)
        return sim.totals, [list(s.robot.inbox) for s in sim.robots]

    totals, inboxes = run()
    assert (totals, inboxes) == run()
    delivered = totals["received"] / (totals["received"] + totals["dropped"])
    assert abs(delivered - 0.75) < 0.05
