import numpy as np
import pytest

from bbzide.worlds import radio
from bbzide.worlds.radio import WorldConfigError, drop_lost, pairs_within_range


def brute_force(points, comm_range):
    n = len(points)
    return {(i, j) for i in range(n) for j in range(n)
            if i != j and np.linalg.norm(points[i] - points[j]) <= comm_range}


@pytest.mark.parametrize("seed", range(5))
def test_grid_search_matches_all_pairs(seed):
    rng = np.random.default_rng(seed)
    points = np.column_stack([rng.uniform(-1, 1, 300), rng.uniform(-1, 1, 300), np.zeros(300)])
    links = pairs_within_range(points, 0.1)
    found = set(zip(links.senders.tolist(), links.receivers.tolist(), strict=True))
    assert found == brute_force(points, 0.1)
    assert len(found) > 0


@pytest.mark.parametrize("seed", range(3))
def test_small_swarm_all_pairs_path_matches_grid(seed, monkeypatch):
    rng = np.random.default_rng(seed)
    points = np.column_stack([rng.uniform(0, 0.4, 60), rng.uniform(0, 0.4, 60),
                              rng.uniform(0, 0.2 * seed, 60)])   # seed 0: one z layer
    assert len(points) <= radio.ALL_PAIRS_MAX
    small = pairs_within_range(points, 0.1)
    monkeypatch.setattr(radio, "ALL_PAIRS_MAX", 0)
    grid = pairs_within_range(points, 0.1)

    def rows(links):
        return sorted(zip(links.senders.tolist(), links.receivers.tolist(),
                          links.distances.tolist(), strict=True))

    assert rows(small) == rows(grid)
    assert {(a, b) for a, b, _ in rows(small)} == brute_force(points, 0.1)
    assert len(rows(small)) > 0


def test_two_robots_at_known_distance():
    links = pairs_within_range(np.array([[0.0, 0, 0], [0.07, 0, 0], [0.5, 0, 0]]), 0.1)
    pairs = zip(links.senders.tolist(), links.receivers.tolist(), strict=True)
    assert sorted(pairs) == [(0, 1), (1, 0)]
    assert np.allclose(links.distances, 0.07)


def test_negative_range_is_a_user_error():
    with pytest.raises(WorldConfigError):
        pairs_within_range(np.zeros((2, 3)), -1.0)


def test_loss_rate_is_statistically_right_and_seeded():
    rng = np.random.default_rng(0)
    points = np.column_stack([rng.uniform(0, 0.3, 400), rng.uniform(0, 0.3, 400), np.zeros(400)])
    links = pairs_within_range(points, 0.1)
    a = drop_lost(links, 0.2, np.random.default_rng(7))
    b = drop_lost(links, 0.2, np.random.default_rng(7))
    assert np.array_equal(a.senders, b.senders)
    kept = len(a.senders) / len(links.senders)
    assert abs(kept - 0.8) < 0.02


def test_neighbour_cache_gives_the_search_s_pairs_while_robots_move():
    rng = np.random.default_rng(3)
    points = np.column_stack([rng.uniform(0, 1, 400), rng.uniform(0, 1, 400),
                              rng.uniform(0, 0.05, 400)])
    cache = radio.NeighbourCache(0.1)

    def rows(links):
        return sorted(zip(links.senders.tolist(), links.receivers.tolist(),
                          links.distances.tolist(), strict=True))

    for step in range(60):
        points += rng.normal(0, 0.001, points.shape)          # a Kilobot-like crawl
        if step == 40:
            points[7] = [0.5, 0.5, 0.0]                          # one robot moved by hand
        got = cache.pairs(points)
        assert rows(got) == rows(pairs_within_range(points, 0.1))
        pairs = np.column_stack([got.receivers, got.senders])
        assert (np.diff(pairs[:, 0] * 400 + pairs[:, 1]) > 0).all()   # receiver, sender
    assert 2 < cache.searches < 20                               # reused, yet rebuilt


def test_radio_follows_a_range_changed_in_its_settings():
    import dataclasses

    from bbzide.vm.swarm_batch import PackedMessages
    from bbzide.worlds.radio import Radio, TrafficCounters
    from bbzide.worlds.world import RadioSettings

    points = np.array([[0.0, 0, 0], [0.15, 0, 0]])
    r = Radio(RadioSettings(comm_range=0.1), 2, 0.1, np.random.default_rng(0),
              np.random.default_rng(1))

    def links(step: int) -> list:
        counters = TrafficCounters.zeros(2)
        r.queue_outbox(PackedMessages.from_rows([(0, 0, b"a", 0, 0, 0), (1, 1, b"b", 0, 0, 0)]),
                       counters)
        return r.transmit(step, points, np.zeros(2), np.ones(2, dtype=bool), counters).tolist()

    assert links(0) == []
    r.settings = dataclasses.replace(r.settings, comm_range=0.2)
    assert links(1) == [[0, 1], [1, 0]]
