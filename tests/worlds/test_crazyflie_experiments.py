"""The Crazyflie experiment scripts of chapter 4: the exploration plot (Fig. 4.9) draws real
flights, and the consensus script reports each reader's delay within one control step."""

from __future__ import annotations

import importlib
import sys
from pathlib import Path

import pytest

EXPERIMENTS = Path(__file__).resolve().parents[2] / "experiments"


@pytest.fixture(scope="module")
def experiments():  # noqa: ANN201 - a loader of experiment modules
    sys.path.insert(0, str(EXPERIMENTS))
    try:
        yield importlib.import_module
    finally:
        sys.path.remove(str(EXPERIMENTS))


def test_exploration_plot_draws_two_flights(experiments, tmp_path) -> None:  # noqa: ANN001
    plot = experiments("crazyflie_exploration_plot")
    path, sim = plot.trajectories(steps=80, seed=3)
    assert path.shape == (81, 2, 3)
    assert (path[-1, :, 2] > 0.5).all()                 # both took off toward 0.8 m
    travelled = abs(path[-1, :, :2] - path[0, :, :2]).sum(axis=1)
    assert (travelled > 0.2).all()                      # and flew somewhere
    out = tmp_path / "fig.png"
    plot.plot(path, sim, str(out))
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_exploration_plot_draws_the_run_a_scenario_pins(experiments, tmp_path,  # noqa: ANN001
                                                       capsys) -> None:  # noqa: ANN001
    plot = experiments("crazyflie_exploration_plot")
    scenario = tmp_path / "room.toml"
    (tmp_path / "exploration.bzz").write_text((EXPERIMENTS.parent / "examples" / "crazyflie"
                                               / "exploration.bzz").read_text())
    scenario.write_text('version = 1\ntitle = "Two in a small room"\nworld = "crazyflie"\n'
                        'seed = 5\nsteps = 30\n[world_options]\nwidth = 3.0\ndepth = 2.0\n'
                        'obstacles = []\n[[robots]]\ncount = 2\nscript = "exploration.bzz"\n'
                        'positions = [[-1.0, -0.5], [1.0, 0.5]]\n')
    path, sim, title = plot.scenario_trajectories(scenario)
    assert path.shape == (31, 2, 3) and title == "Two in a small room"
    assert path[0, :, :2].tolist() == [[-1.0, -0.5], [1.0, 0.5]]   # the pinned start
    assert tuple(sim.world.bounds) == (-1.5, -1.0, 1.5, 1.0) and len(sim.world.obstacles) == 0
    out = tmp_path / "room.png"
    assert plot.main(["--scenario", str(scenario), str(out)]) == 0
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    kilobot = EXPERIMENTS.parent / "examples" / "kilobot" / "gradient.toml"
    assert plot.main(["--scenario", str(kilobot), str(out)]) == 1
    assert "draws a crazyflie room, not the kilobot world" in capsys.readouterr().err


def test_consensus_reader_delays_are_within_one_step(experiments) -> None:  # noqa: ANN001
    consensus = experiments("crazyflie_consensus")
    from common import compile_example

    program = compile_example("crazyflie", "examples/crazyflie/consensus.bzz")
    delays = consensus.reader_delays("circle", seed=1, program=program)
    assert len(delays) == consensus.DRONES - 1
    assert all(0 <= d <= 1 for d in delays)
    assert consensus.consensus_time("circle", 1, program) == max(delays)


def test_synchronized_drones_split_into_two_modes_with_a_gap(experiments) -> None:  # noqa: ANN001
    consensus = experiments("crazyflie_consensus")
    from common import compile_example

    program = compile_example("crazyflie", "examples/crazyflie/consensus.bzz")
    spread = 0.4   # 20 ms of a 50 ms step
    delays = [d for seed in range(3)
              for d in consensus.reader_delays("circle", seed, program, spread=spread)]
    assert all(d >= 0 for d in delays)
    # A reader stepping after the writer reads within the spread, one stepping before it
    # waits almost a full step: nothing in between.
    assert all(d <= spread or d >= 1 - spread for d in delays)
    assert any(d <= spread for d in delays) and any(d >= 1 - spread for d in delays)


def test_bidding_loss_lengthens_auctions_and_keeps_one_winner(experiments) -> None:  # noqa: ANN001
    bidding = experiments("crazyflie_bidding")
    from common import compile_example

    program = compile_example("crazyflie", "examples/crazyflie/bidding.bzz", {"N": 4})
    clean = [bidding.auction_time(4, seed, program) for seed in range(4)]
    lossy = [bidding.auction_time(4, seed, program, loss=0.3) for seed in range(4)]
    assert all(t >= 0 and same for t, same in clean + lossy)
    assert sum(t for t, _ in lossy) > sum(t for t, _ in clean)
