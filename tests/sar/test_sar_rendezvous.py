"""The search pattern of thesis §5.3 as it runs: search runs of a fixed duration with returns to
the rendezvous point between them, exactly one root (re-elected when two were proclaimed), and
positions that survive the int16 packing of messages on large fields. Real VMs on the M300
field (examples/sar/sar.bzz), measured through the world's counters and the sweep's CSV."""

import csv
import dataclasses
import math
import statistics

import numpy as np
import pytest

from bbzide.diagnostics import UserError
from bbzide.worlds import sar_experiment as sx
from bbzide.worlds.engine import Simulation
from bbzide.worlds.radio import WorldConfigError


def roots_of(world) -> list[int]:
    return [i for i, r in enumerate(world.roles) if r in ("root", "auctioneer")]


def test_a_lone_searcher_flies_runs_of_20_search_steps_and_returns_between_them():
    """One drone, no target: after takeoff (50 steps of climb) each run lasts 20 search steps of
    1 s, then the drone turns back to the meeting point, reaches it, waits, and starts again."""
    spec = sx.RunSpec(drones=1, arena=40.0, search="random", trial=0, seed=4, targets=0)
    sim = Simulation("m300", sx._program(), robots=1, seed=4, world_options=spec.world_options())
    world = sim.world
    turned: list[int] = []
    while sim.step_count < 1500:
        before = world.roles[0]
        sim.step()
        if before == "searcher" and world.roles[0] == "rendezvous":
            turned.append(sim.step_count)
    assert world.rendezvous_returns[0] == len(turned) >= 2
    assert world.rendezvous_arrivals[0] >= 2
    # The first run starts at mission altitude (5 m at 1 m/s: step 50) and lasts 200 steps;
    # the drone notices the end at its next wake (at most one search step later).
    assert 250 <= turned[0] <= 261
    # The next run starts after the flight back and the wait at the meeting point: runs and
    # returns alternate, the gap being more than the run itself.
    assert turned[1] - turned[0] > 200


def test_a_small_sweep_returns_to_the_rendezvous_and_elects_one_root_in_every_run(tmp_path):
    """15 drones, a 30 m arena, both searches (a pair): every run has at least one return (a
    run ends 20 s after the 5 s climb, before a mission of this arena is done), one root at the
    end and an auction per relay node; the CSV has the counts per run."""
    settings = sx.SweepSettings(drones=[15], arenas=[30.0], searches=["random", "belief"],
                                trials=1, seed=2026, jobs=1, out=tmp_path / "out")
    results = sx.run_sweep(settings)
    rows = list(csv.DictReader((tmp_path / "out" / "runs.csv").open()))
    assert len(rows) == len(results) == 2
    for row in rows:
        assert int(row["complete_step"]) > 0, row["run_id"]
        assert int(row["rendezvous_returns"]) >= 1, row["run_id"]
        assert int(row["roots"]) == 1, row["run_id"]
        assert int(row["root_elections"]) >= 1, row["run_id"]
        assert int(row["auctions"]) >= int(row["networkers"]) >= 1, row["run_id"]
    assert sum(int(r["rendezvous_arrivals"]) for r in rows) >= 1


@pytest.mark.parametrize("sweep_seed, drones, trial", [(2026, 20, 21), (7, 25, 5)],
                         ids=["d20_a20_random_t021", "d25_a20_random_t005"])
def test_the_runs_that_ended_with_two_roots_now_elect_one(sweep_seed, drones, trial):
    spec = sx.RunSpec(drones=drones, arena=20.0, search="random", trial=trial,
                      seed=sx.run_seed(sweep_seed, drones, 20.0, trial))
    result = sx.run_one(spec)
    assert result["complete_step"] > 0
    assert result["roots"] == 1
    assert result["errors"] == 0


def test_two_roots_proclaimed_out_of_radio_contact_re_elect_one_that_keeps_every_target():
    """The radio loses everything until two drones have proclaimed themselves root at the
    meeting point (as when a candidate misses the root's beacons); once they hear each other,
    one steps down and hands over its targets: one root, which knows all of them."""
    spec = sx.RunSpec(drones=3, arena=20.0, search="belief", trial=0, seed=1,
                      targets=((8.0, 6.0), (8.0, 14.0)))
    sim = Simulation("m300", sx._program(), robots=3, seed=1, world_options=spec.world_options())
    world = sim.world
    sim.radio.settings = dataclasses.replace(sim.radio.settings, loss_probability=1.0)
    while sim.step_count < 3000 and len(roots_of(world)) < 2:
        sim.step()
    both = roots_of(world)
    assert len(both) == 2
    knew = {i: list(world.known_targets[i]) for i in both}
    sim.radio.settings = dataclasses.replace(sim.radio.settings, loss_probability=0.0)
    sim.run(100)
    (root,) = roots_of(world)
    assert root in both
    known = np.array(world.known_targets[root])
    for i in both:
        for x, y in knew[i]:
            assert np.hypot(known[:, 0] - x, known[:, 1] - y).min() < 1.0
    assert not sim.failures


def test_positions_beyond_64_m_reach_the_root_and_the_relay_forms():
    """An 80 m field (int16 packing at 0.5 m broke from 64 m: y / 5 dm overflowed into x): a
    target at y = 66 m is known at its place by the root and the relay reaches it."""
    target = (20.0, 66.0)
    spec = sx.RunSpec(drones=6, arena=80.0, search="random", trial=0, seed=2,
                      targets=(target,), comm_range=30.0)
    sim = Simulation("m300", sx._program(), robots=6, seed=2, world_options=spec.world_options())
    world = sim.world
    while sim.step_count < 4000 and not (
            sim.step_count % 10 == 0 and (world.found_step >= 0).all()
            and world.relay_complete(sim)):
        sim.step()
    assert world.relay_complete(sim) and not sim.failures
    (root,) = roots_of(world)
    (known,) = world.known_targets[root]
    assert np.hypot(known[0] - target[0], known[1] - target[1]) <= world.camera_radius


def test_fields_too_large_for_the_packing_are_refused_with_a_message(tmp_path):
    with pytest.raises(WorldConfigError, match="int16 decimetres"):
        Simulation("m300", sx._program(), robots=1, seed=0, world_options={"size": 3300})
    settings = sx.SweepSettings(drones=[3], arenas=[400.0], searches=["random"], trials=1,
                                seed=0, jobs=1, out=tmp_path / "out")
    with pytest.raises(UserError, match="largest arena 179.1 m"):
        sx.validate(settings)
    settings.arenas = [179.1]
    sx.validate(settings)
    assert sx.packing_unit_dm(179.1) == 14 and sx.packing_unit_dm(179.2) == 15
    # with a 4 m range the spacing bound is the tighter one (Q <= 10 dm: up to 127.9 m)
    assert sx.largest_arena(4.0) == 127.9


def test_the_m300_queues_hold_a_full_step_of_the_largest_swarm_and_index_right():
    """25 drones in range send up to 24 x 10 messages in a step; full Buzz keeps and processes
    them all. The rings hold that many and their u8 index wrap is exact (slots divide 256)."""
    from bbzide.vm.messages import RingBuffer
    from bbzide.vm.profiles import M300

    sim = Simulation("m300", sx._program(), robots=1, seed=0)
    arrivals = 24 * sim.world.radio.messages_per_step
    assert M300.in_queue_cap >= arrivals and M300.msg_in_proc_max == M300.in_queue_cap
    assert M300.out_queue_cap >= arrivals
    for cap in (M300.in_queue_cap, M300.out_queue_cap):
        ring = RingBuffer(list(range(cap + 2)), cap + 1)
        for start in range(cap + 1):
            ring.start = start
            assert [ring.index_at(i) for i in range(cap + 1)] == [
                (start + i) % (cap + 1) for i in range(cap + 1)]


def test_uniform_targets_ignore_the_prior_and_share_the_map_of_the_other_placements():
    """`targets_where=uniform` (§5.4.1: "randomly spawned"): over many seeds the share of
    targets in cells under the search threshold is the share of the field's area under it
    (about a binomial spread), while `likely` never puts one there; the belief map is the same
    for every placement of a seed (the pairs and placements compare on one map)."""
    under_area, under_targets, likely_under, n = 0.0, 0, 0, 0
    for seed in range(60):
        worlds = {}
        for where in ("uniform", "likely"):
            sim = Simulation("m300", sx._program(), robots=1, seed=seed,
                             world_options={"size": 20, "targets_where": where})
            worlds[where] = sim.world
        uniform, likely = worlds["uniform"], worlds["likely"]
        assert np.array_equal(uniform.belief, likely.belief)
        prior_at = [uniform.belief.ravel()[uniform.cell_of(x, y)] for x, y in uniform.targets]
        under_targets += sum(p < 0.2 for p in prior_at)
        likely_under += sum(likely.belief.ravel()[likely.cell_of(x, y)] < 0.2
                            for x, y in likely.targets)
        # the area east of the launch strip keep-out (x >= 5 m: columns 3..9 of 2 m cells, the
        # column from 4 to 6 m half in)
        east = uniform.belief[:, 3:].copy()
        weights = np.ones_like(east)
        weights[:, 0] = 0.5
        under_area += float((weights * (east < 0.2)).sum() / weights.sum())
        n += len(prior_at)
    expected = under_area / 60 * n
    assert likely_under == 0
    assert abs(under_targets - expected) < 4 * np.sqrt(expected) + 1
    assert under_targets > 0.3 * n        # generated maps are mostly under the threshold


def _bayes_factor_by_direct_integration(d: list[float], scale: float) -> float:
    """The same Bayes factor from its definition: d_i ~ N(delta sigma, sigma^2) against
    N(0, sigma^2), p(sigma) ~ 1/sigma, delta ~ Cauchy(0, scale); marginal likelihoods by
    brute-force integration over ln sigma and delta (an independent route to the g-form)."""
    d = np.asarray(d, dtype=float)
    log_sigma = np.linspace(-6, 6, 601)
    delta = np.linspace(-40, 40, 8001)
    cauchy = 1 / (np.pi * scale * (1 + (delta / scale) ** 2))

    def log_likelihood(mu: np.ndarray, sigma: float) -> np.ndarray:
        return (-len(d) / 2 * np.log(2 * np.pi * sigma ** 2)
                - ((d[None, :] - mu[:, None]) ** 2).sum(axis=1) / (2 * sigma ** 2))

    null = np.array([log_likelihood(np.zeros(1), s)[0] for s in np.exp(log_sigma)])
    alt = []
    for s in np.exp(log_sigma):
        ll = log_likelihood(delta * s, s)
        alt.append(ll.max() + np.log(np.trapezoid(np.exp(ll - ll.max()) * cauchy, delta)))
    alt = np.array(alt)

    def log_area(values: np.ndarray) -> float:
        return float(values.max() + np.log(np.trapezoid(np.exp(values - values.max()),
                                                        log_sigma)))

    return float(np.exp(log_area(alt) - log_area(null)))


@pytest.mark.parametrize("differences", [
    [1, 2, 3, -1, 2, 0.5, 1.5, 2, 1, 0.2],          # a clear effect: BF10 ~ 7
    [0.1, -0.1, 0.2, -0.2, 0.05, -0.05],           # none: BF10 < 1 (favours no difference)
    [3, 4, 2.5, 5, 3.5, 4.2]])                      # a strong one: BF10 ~ 166
def test_the_jzs_bayes_factor_matches_its_definition(differences):
    bf = sx.jzs_bayes_factor(differences)
    assert bf == pytest.approx(_bayes_factor_by_direct_integration(differences, sx.CAUCHY_SCALE),
                               rel=2e-3)
    assert sx.jzs_bayes_factor([1.0]) is None and sx.jzs_bayes_factor([2.0, 2.0]) is None


def _bayes_factor_by_trapezoids_on_log_g(d: list[float], scale: float) -> float:
    """The g-form integrated by fixed trapezoids on ln g in [-30, 30] (step 0.01): how the
    Bayes factor was computed before scipy's adaptive quadrature took over."""
    n = len(d)
    t = statistics.fmean(d) / (statistics.stdev(d) / math.sqrt(n))
    v = n - 1
    u = np.linspace(-30.0, 30.0, 6001)
    g = np.exp(u)
    spread = 1.0 + n * g * scale ** 2
    log_integrand = (-0.5 * np.log(spread) - (v + 1) / 2 * np.log1p(t * t / (spread * v))
                     - 0.5 * math.log(2 * math.pi) - 0.5 * u - 1 / (2 * g))
    peak = float(log_integrand.max())
    area = float(np.trapezoid(np.exp(log_integrand - peak), u))
    return math.exp(peak + math.log(area) + (v + 1) / 2 * math.log1p(t * t / v))


#: Tolerance between scipy's quadrature and the former fixed trapezoids: both resolve the
#: integrand far better than 1e-6 for every sample size of a sweep (3 to 270 pairs).
FORMER_METHOD_TOLERANCE = 1e-6


@pytest.mark.parametrize("n", [3, 10, 30, 270])
@pytest.mark.parametrize("effect", [0.0, 0.2, 0.6, 1.5])
def test_the_quadrature_gives_the_former_integration_s_bayes_factor(n, effect):
    rng = np.random.default_rng(n * 100 + int(effect * 10))
    differences = list(rng.normal(effect, 1.0, n))
    assert sx.jzs_bayes_factor(differences) == pytest.approx(
        _bayes_factor_by_trapezoids_on_log_g(differences, sx.CAUCHY_SCALE),
        rel=FORMER_METHOD_TOLERANCE)


def test_the_bayes_factor_of_student_s_sleep_data_is_the_published_one():
    # Extra hours of sleep, drug 2 minus drug 1, in the 10 patients of Student (1908): the
    # JZS paired t-test with the medium prior scale sqrt(2)/2 gives BF10 = 17.25888 (Rouder
    # et al.'s BayesFactor package, ttestBF(paired = TRUE), JASP's default prior).
    sleep = [1.2, 2.4, 1.3, 1.3, 0.0, 1.0, 1.8, 0.8, 4.6, 1.4]
    assert sx.jzs_bayes_factor(sleep) == pytest.approx(17.25888, rel=1e-6)


def test_the_comparison_reports_the_bayes_factor_of_the_paired_find_times():
    results = []
    for trial, (random_step, belief_step) in enumerate([(300, 200), (280, 150), (350, 260),
                                                        (240, 250), (400, 210)]):
        for search, step in (("random", random_step), ("belief", belief_step)):
            results.append({"arena": 20.0, "drones": 3, "trial": trial, "search": search,
                            "found_all_step": step, "relay_formation_steps": 10,
                            "complete_step": step + 10, "messages_per_drone": 1.0,
                            "bytes_per_drone": 1.0, "wall_seconds": 1.0})
    (row,) = sx.paired_comparison(results)
    assert row["bayes_factor"] == pytest.approx(
        sx.jzs_bayes_factor([100, 130, 90, -10, 190]), rel=1e-3)
    assert sx.format_markdown([row]).splitlines()[2].endswith(f"| {row['bayes_factor']:.4g} |")


def test_the_relay_tree_carries_the_victims_positions_hop_by_hop_to_the_root():
    """Once the tree is formed, a networker that sees a target reports it ("vic") and every
    networker passes its children's reports on: each link's parent sends a report after its
    child's first one, and reports reach the root (its `reports` counter)."""
    from bbzide.vm.message_layout import BC_TOPIC, BROADCAST, TYPE

    program = sx._program()
    topic = program.string_id("vic")
    spec = sx.RunSpec(drones=10, arena=20.0, search="belief", trial=0, seed=11)
    sim = Simulation("m300", program, robots=10, seed=11, world_options=spec.world_options())
    world = sim.world
    while sim.step_count < 2500 and not (sim.step_count % 10 == 0
                                         and (world.found_step >= 0).all()
                                         and world.relay_complete(sim)):
        sim.step()
    assert world.relay_complete(sim)
    (root,) = roots_of(world)
    before = sim.robots[root].global_value("reports")
    sends: dict[int, list[int]] = {}
    for _ in range(60):                 # 6 s: every networker wakes at least 5 times
        sim.step()
        outbox = sim.step_outbox
        for sender, payload in zip(outbox.robots, outbox.payloads, strict=True):
            if (payload[TYPE] == BROADCAST
                    and int.from_bytes(bytes(payload[BC_TOPIC:BC_TOPIC + 2]), "little") == topic):
                sends.setdefault(int(sender), []).append(sim.step_count)
    links = world.relay_links()
    assert links
    for child, parent in links:
        assert child in sends, f"networker {child} sent no report"
        if parent != root:
            assert max(sends[parent]) > min(sends[child]), (child, parent)
    assert sim.robots[root].global_value("reports") > before
