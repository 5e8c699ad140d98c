"""The example scripts run on real VMs in their worlds and do what their comments claim.

Small swarms and few steps (the VM model is slow); each test says what it checks.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from bbzide.vm.robot import Robot
from bbzide.worlds.commands import load_script
from bbzide.worlds.engine import Simulation
from bbzide.worlds.radio import hop_counts
from bbzide.worlds.registry import WORLDS

REPO = Path(__file__).resolve().parents[2]


def program(world: str, name: str, constants: dict[str, int] | None = None, tmp=None):
    path = REPO / "examples" / world / f"{name}.bzz"
    if constants:
        text = path.read_text()
        for key, value in constants.items():
            lines = [f"var {key} = {value}" if line.startswith(f"var {key} = ") else line
                     for line in text.splitlines()]
            text = "\n".join(lines) + "\n"
        path = tmp / f"{name}.bzz"
        path.write_text(text)
    return load_script(path, WORLDS[world].host_names, [])


def values(sim: Simulation, name: str) -> list:
    return [state.global_value(name) for state in sim.robots]


def no_failures(sim: Simulation) -> None:
    assert [(s.robot_id, s.failure) for s in sim.failures] == []


# ---- Kilobot ---------------------------------------------------------------------------------
def test_gradient_converges_to_hop_counts():
    sim = Simulation("kilobot", program("kilobot", "gradient"), robots=12, seed=3,
                     world_options={"spacing": 0.07})
    expected = hop_counts(sim.positions, sim.world.comm_range)
    assert max(expected) >= 3 and min(expected) >= 0          # a multi-hop, connected swarm
    for _ in range(30):
        sim.step()
        if values(sim, "gradient") == expected:
            break
    no_failures(sim)
    assert values(sim, "gradient") == expected
    # the LED shows gradient % 7 + 1 (bits: red, green, blue)
    colour = [int(r) + 2 * int(g) + 4 * int(b) for r, g, b in (s.led for s in sim.robots)]
    assert colour == [h % 7 + 1 for h in expected]


def test_leader_election_agrees_on_the_largest_id():
    sim = Simulation("kilobot", program("kilobot", "leader"), robots=6, seed=2)
    for _ in range(40):
        sim.step()
        if values(sim, "leader") == [5] * 6:
            break
    no_failures(sim)
    assert values(sim, "leader") == [5] * 6
    assert [s.led for s in sim.robots] == [(0.0, 0.0, 1.0)] * 5 + [(0.0, 1.0, 0.0)]


def test_firefly_flashes_fall_into_step():
    sim = Simulation("kilobot", program("kilobot", "firefly"), robots=9, seed=1,
                     world_options={"spacing": 0.04})

    def flashes_per_step(steps: int) -> list[int]:
        counts = []
        for _ in range(steps):
            sim.step()
            counts.append(sum(1 for s in sim.robots if s.led == (1.0, 1.0, 1.0)))
        return counts

    first = flashes_per_step(20)
    assert sum(1 for n in first if n) >= 4             # random phases: flashes spread out
    flashes_per_step(20)
    last = flashes_per_step(20)                        # one whole period, later on
    no_failures(sim)
    busy = [i for i, n in enumerate(last) if n]
    assert sum(last) == 9                              # everyone flashed once ...
    assert busy[-1] - busy[0] <= 2                     # ... within 2 steps of each other


def test_aggregation_lone_robots_walk_and_crowded_robots_stop():
    sim = Simulation("kilobot", program("kilobot", "aggregation"), robots=10, seed=4,
                     world_options={"width": 0.4, "height": 0.4, "layout": "random"})
    start = sim.positions.copy()
    sim.run(60)
    no_failures(sim)
    moved = np.linalg.norm(sim.positions[:, :2] - start[:, :2], axis=1)
    crowded = np.array([s.robot.vm is not None and s.led == (0.0, 1.0, 0.0) for s in sim.robots])
    lonely = np.array([s.led == (1.0, 0.0, 0.0) for s in sim.robots])
    assert (crowded | lonely).all() and crowded.any() and lonely.any()
    motors = sim.world.motors
    assert (motors[crowded] == 0).all()                  # green robots have stopped
    assert (motors[lonely].sum(axis=1) > 0).all()        # red robots are walking
    assert moved.max() > 0.01


# ---- Crazyflie -------------------------------------------------------------------------------
@pytest.mark.parametrize("formation", ["circle", "chain"])
def test_consensus_in_at_most_two_steps(formation):
    sim = Simulation("crazyflie", program("crazyflie", "consensus"), robots=10, seed=7,
                     world_options={"formation": formation})
    sim.run(9)
    no_failures(sim)
    agreed = values(sim, "agreed")
    assert agreed[0] == 5                                 # the writer reads its own value
    assert all(6 <= a <= 7 for a in agreed[1:]), agreed  # 1 or 2 control steps after the put


def test_bidding_has_one_winner_everyone_agrees_on(tmp_path):
    sim = Simulation("crazyflie", program("crazyflie", "bidding", {"N": 3}, tmp_path),
                     robots=3, seed=5)
    sim.run(14)
    no_failures(sim)
    done = values(sim, "done")
    assert all(d is not None and d >= 5 for d in done)
    bids = values(sim, "bid")
    winners = set(values(sim, "winner"))
    lowest = min(range(3), key=lambda i: (bids[i], i))
    assert winners == {lowest}
    assert [s.led for s in sim.robots].count((0.0, 1.0, 0.0)) == 1


def test_exploration_flies_around_without_bumping():
    # A 2 m x 2 m room: at 0.6 m/s a drone reaches a wall within seconds unless it turns away.
    sim = Simulation("crazyflie", program("crazyflie", "exploration"), robots=1, seed=3,
                     world_options={"width": 2.0, "depth": 2.0, "obstacles": ()})
    cells = set()
    closest = 9.0
    for _ in range(160):   # 8 s
        sim.step()
        x, y, _ = sim.positions[0]
        cells.add((int(x // 0.5), int(y // 0.5)))
        closest = min(closest, float(sim.world.ranges[0, :4].min()))
    no_failures(sim)
    assert sim.robots[0].labels["flying"]
    assert sim.robots[0].labels["bumps"] == 0
    assert closest < 0.6                  # it did meet walls ...
    assert len(cells) >= 4                # ... and kept exploring


@pytest.mark.parametrize("period, count, low, high", [(10, 12, 0.0, 0.0),
                                                      (1, 60, 0.005, 0.04)])
def test_packet_loss_follows_the_broadcast_rate(period, count, low, high, tmp_path):
    sim = Simulation("crazyflie",
                     program("crazyflie", "packet_loss", {"PERIOD": period, "COUNT": count},
                             tmp_path), robots=4, seed=11)
    sim.run(count * period + 1)
    no_failures(sim)
    sent, heard = values(sim, "sent"), values(sim, "heard")
    assert sent == [count] * 4
    loss = 1 - sum(heard) / (3 * sum(sent))     # 2 Hz: none lost; 20 Hz: about 1.9 %
    assert low <= loss <= high


def test_same_seed_same_trajectories_and_heaps():
    def run(seed):
        sim = Simulation("kilobot", program("kilobot", "aggregation"), robots=6, seed=seed,
                         world_options={"width": 0.3, "height": 0.3, "layout": "random"})
        sim.run(25)
        return sim.positions.copy(), [Robot.comparable(s.robot.snapshot()) for s in sim.robots]

    positions, heaps = run(8)
    again_positions, again_heaps = run(8)
    other_positions, _ = run(9)
    assert np.array_equal(positions, again_positions) and heaps == again_heaps
    assert not np.array_equal(positions, other_positions)
