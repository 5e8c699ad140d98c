"""`bbzide experiment sar`: the search-and-rescue simulation study of thesis §5.4 (and the field
test of §5.5) on the M300 field world running `examples/sar/sar.bzz`.

Design: a sweep is a list of `RunSpec`s, one per (drones, arena, search, trial). The run seed
depends on (sweep seed, drones, arena, trial) but not on the search, so the two searches of a
pair start from the same drone positions, belief map and targets (the world draws them from the
run seed) and differ only in how goals are chosen. Each run is independent and reproducible from
its spec alone, so runs are independent tasks (keyed by run id and seed, `task_key`) for an
`executors.Executor`: local processes (`--jobs`) or a Dask cluster (`--cluster`). Each finished
run comes back to this process and is written at once, atomically, as `runs/<id>.json` in the
output folder: an interrupted sweep keeps every finished run and a rerun of the same command
skips them (resume), wherever the runs ran. When every run is done, the JSON files are
summarised into `runs.csv`, the paired
belief-vs-random comparison `comparison.csv` (and on screen, and as the README's markdown
table in `summary.md`), and the plots (`sar_plots.py`).

A run ends when every target has been seen and the relay tree is complete (`M300Field.
relay_complete`, checked every CHECK_PERIOD steps), or after `max_steps` (a timeout, reported).
Measured per run (thesis §5.4.2): the step at which the last target was first seen ("timesteps
to find all targets"), the steps the root spent as auctioneer ("relay formation time"), the
step at which the tree was complete, messages and bytes sent per drone, the bytes each
drone sent per simulated second (the bandwidth plot, Fig. 5.12), and the events of the search
pattern (§5.3), summed over the drones: returns to the rendezvous point (runs ended) and
arrivals there, root elections and auctions opened.

Recording: `runs.csv` gives, per run, the `bbzide run` command that replays it step for step
(`reproduce_command`: same program, seed and world options, `--steps` = the run's length);
adding `--record X.rrd` records it for `bbzide replay`. The sweep itself does not record: the
recording room sits above the worlds room, and a recording is ~0.5 MB per 1,000 drone-steps
(the field run: 3 drones x 680 steps, 1.1 MB).
"""

from __future__ import annotations

import argparse
import csv
import hashlib
import json
import math
import os
import shlex
import statistics
import time
from collections.abc import Iterable, Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from bbzide.diagnostics import UserError
from bbzide.worlds.executors import add_executor_arguments, open_executor, progress_bar

#: The paper's fixed parameters (thesis §5.4.2): 3 targets, 10 m range, 20 search steps.
TARGETS = 3
COMM_RANGE = 10.0
SEARCH_STEPS = 20
SEARCHES = ("random", "belief")
#: Steps between two relay-completion checks (1 s: the check walks every drone and target).
CHECK_PERIOD = 10
#: Bandwidth samples are bytes per drone per simulated second (10 steps of 0.1 s).
SAMPLE_STEPS = 10
#: A run that has not found every target and formed the tree by then is a timeout: 10,000
#: steps = 1,000 s simulated, several times the slowest 40 m random-walk runs we measured.
DEFAULT_MAX_STEPS = 10_000
SCRIPT = Path(__file__).resolve().parents[2] / "examples" / "sar" / "sar.bzz"
FIELD_BELIEF = Path(__file__).resolve().parents[2] / "examples" / "sar" / "field_belief.csv"
#: The field test (thesis §5.5): a 36 m football field, 3 drones, 1 target, a fixed belief map.
#: The target sits 24.7 m from the meeting point; with a 15 m range the relay is the root and two
#: networkers, which is what three drones can form (at the simulations' 10 m, three drones
#: cannot span 24.7 m: the paper does not give its field range, Wi-Fi reaches further).
FIELD_TARGET = (26.0, 24.0)
FIELD_COMM_RANGE = 15.0


@dataclass(frozen=True)
class RunSpec:
    """One run of the sweep; everything the run depends on."""

    drones: int
    arena: float
    search: str
    trial: int
    seed: int
    max_steps: int = DEFAULT_MAX_STEPS
    comm_range: float = COMM_RANGE
    targets: int | tuple[tuple[float, float], ...] = TARGETS
    belief_map: str | None = None
    search_steps: int = SEARCH_STEPS
    targets_where: str = "uniform"
    script: str = str(SCRIPT)   # a scenario may name another SAR script

    @property
    def run_id(self) -> str:
        return f"d{self.drones}_a{self.arena:g}_{self.search}_t{self.trial:03d}"

    def world_options(self) -> dict[str, Any]:
        options: dict[str, Any] = {"size": self.arena, "comm_range": self.comm_range,
                                   "search": self.search, "search_steps": self.search_steps,
                                   "targets": (self.targets if isinstance(self.targets, int)
                                               else [list(t) for t in self.targets])}
        if self.belief_map is not None:
            options["belief_map"] = self.belief_map
        options["targets_where"] = self.targets_where
        return options


@dataclass
class SweepSettings:
    drones: list[int]
    arenas: list[float]
    searches: list[str]
    trials: int
    seed: int
    jobs: int
    out: Path
    max_steps: int = DEFAULT_MAX_STEPS
    preset: str | None = None
    extra: dict[str, Any] = field(default_factory=dict)
    cluster: str | None = None   # a Dask scheduler's address, or "local" (executors.py)


def _int_list(text: str, what: str) -> list[int]:
    try:
        values = [int(v) for v in text.split(",") if v.strip()]
    except ValueError:
        raise UserError(f"--{what} wants integers separated by commas, got {text!r}") from None
    if not values:
        raise UserError(f"--{what} is empty")
    return values


def _float_list(text: str, what: str) -> list[float]:
    try:
        values = [float(v) for v in text.split(",") if v.strip()]
    except ValueError:
        raise UserError(f"--{what} wants numbers separated by commas, got {text!r}") from None
    if not values:
        raise UserError(f"--{what} is empty")
    return values


def validate(settings: SweepSettings, comm_range: float = COMM_RANGE) -> None:
    """Every parameter problem as one clear `UserError` before anything runs."""
    if any(d < 1 for d in settings.drones):
        raise UserError(f"every run needs at least 1 drone (--drones {settings.drones})")
    small = [a for a in settings.arenas if a < comm_range]
    if small:
        raise UserError(f"arena {small[0]:g} m is smaller than the {comm_range:g} m "
                        "communication range: the swarm would never be sparse")
    coarse = [a for a in settings.arenas if a > largest_arena(comm_range)]
    if coarse:
        raise UserError(
            f"arena {coarse[0]:g} m is too large: the script sends positions in one int16, at "
            f"{packing_unit_dm(coarse[0]) / 10:g} m resolution there, too coarse to keep relay "
            f"nodes in a {comm_range:g} m range or a networker over its target (largest arena "
            f"{largest_arena(comm_range):g} m)")
    unknown = [s for s in settings.searches if s not in SEARCHES]
    if unknown:
        raise UserError(f"unknown search {unknown[0]!r}; choose from {', '.join(SEARCHES)}")
    if settings.trials < 1:
        raise UserError("--trials must be at least 1")
    if settings.jobs < 1:
        raise UserError("--jobs must be at least 1")
    if settings.max_steps < 1:
        raise UserError("--max-steps must be at least 1")
    if settings.seed < 0:  # numpy's seed sequences take non-negative integers only
        raise UserError(f"--seed must be >= 0, got {settings.seed}")
    if settings.out.exists() and not settings.out.is_dir():
        raise UserError(f"--out {settings.out} is not a folder (a file of that name exists)")


def packing_unit_dm(arena: float) -> int:
    """The resolution (dm) at which examples/sar/sar.bzz packs a position into one int16 on
    an `arena` m field: Q = size / 128 + 1 (its `pack`), so x/Q and y/Q stay under 128."""
    return int(round(arena * 10)) // 128 + 1


def largest_arena(comm_range: float) -> float:
    """The largest arena (m) whose packing unit Q keeps the relay sound: Q at most a quarter
    of the range (the script spaces nodes range - 2 Q apart, at least half a range; two
    packed nodes are then within range: their truncation errors differ by under Q per
    axis, so by under 1.42 Q < 2 Q), and a packed target within the camera footprint of
    the networker sent over it (Q sqrt(2) at most the footprint radius: 2.07 m at the
    default 5 m altitude, so Q <= 14 dm and arenas up to 179.1 m)."""
    from bbzide.worlds.m300 import CAMERA_FOV, DEFAULT_ALTITUDE

    footprint_dm = DEFAULT_ALTITUDE * math.tan(CAMERA_FOV / 2) * 10
    unit = min(int(comm_range * 10 // 4), int(footprint_dm / math.sqrt(2)))
    return (unit * 128 - 1) / 10


def run_seed(seed: int, drones: int, arena: float, trial: int) -> int:
    """The seed of a trial, shared by its two searches (a pair)."""
    sequence = np.random.SeedSequence(seed, spawn_key=(drones, int(round(arena * 10)), trial))
    return int(sequence.generate_state(1)[0])


def plan_runs(settings: SweepSettings) -> list[RunSpec]:
    runs = []
    for arena in settings.arenas:
        for drones in settings.drones:
            for trial in range(settings.trials):
                seed = run_seed(settings.seed, drones, arena, trial)
                for search in settings.searches:
                    runs.append(RunSpec(drones, arena, search, trial, seed,
                                        max_steps=settings.max_steps, **settings.extra))
    return runs


def reproduce_command(spec: RunSpec, steps: int) -> list[str]:
    """The `bbzide run` arguments that replay run `spec` for `steps` steps: the same program,
    seed and world options, so it takes the same course step for step; add `--record X.rrd`
    to record it for `bbzide replay` (recording lives above the worlds room)."""
    options = {"size": f"{spec.arena:g}", "search": spec.search,
               "comm_range": f"{spec.comm_range:g}", "search_steps": str(spec.search_steps),
               "targets": (str(spec.targets) if isinstance(spec.targets, int)
                           else ",".join(f"{x:g}:{y:g}" for x, y in spec.targets))}
    if spec.belief_map is not None:
        options["belief_map"] = spec.belief_map
    options["targets_where"] = spec.targets_where
    command = ["run", spec.script, "--world", "m300", "--robots", str(spec.drones),
               "--seed", str(spec.seed), "--steps", str(steps)]
    for key, value in options.items():
        command += ["--set", f"{key}={value}"]
    return command


# ---- one run (in a worker process) -------------------------------------------------------------
_PROGRAMS: dict[str, Any] = {}


def _program(script: str = str(SCRIPT)) -> Any:
    """`script` compiled for the M300 (once per worker process)."""
    if script not in _PROGRAMS:
        from bbzide.compiler import bittybuzz_string_table, compile_file
        from bbzide.worlds.registry import M300_HOST_NAMES

        strings = bittybuzz_string_table(list(M300_HOST_NAMES))
        _PROGRAMS[script] = compile_file(Path(script), string_table=strings).to_bbo()
    return _PROGRAMS[script]


def run_one(spec: RunSpec) -> dict[str, Any]:
    """Run one mission to completion (or timeout) and return its measurements."""
    from bbzide.worlds.engine import Simulation
    from bbzide.worlds.m300 import ROLE_NAMES

    started = time.perf_counter()
    sim = Simulation("m300", _program(spec.script), robots=spec.drones, seed=spec.seed,
                     world_options=spec.world_options())
    world = sim.world
    sent = np.zeros(spec.drones, dtype=np.int64)
    sent_bytes = np.zeros(spec.drones, dtype=np.int64)
    window = np.zeros(spec.drones, dtype=np.int64)
    bandwidth: list[list[int]] = []
    complete_step = -1
    while sim.step_count < spec.max_steps:
        stats = sim.step()
        sent += stats.sent
        sent_bytes += stats.bytes_sent
        window += stats.bytes_sent
        if sim.step_count % SAMPLE_STEPS == 0:
            bandwidth.append(window.tolist())
            window[:] = 0
        if (sim.step_count % CHECK_PERIOD == 0 and (world.found_step >= 0).all()
                and world.relay_complete(sim)):
            complete_step = sim.step_count
            break
    found = world.found_step
    auctioneer = ROLE_NAMES.index("auctioneer")
    return {
        **{k: v for k, v in asdict(spec).items()
           if k not in ("targets", "belief_map", "script")},
        **({} if spec.script == str(SCRIPT) else {"script": spec.script}),
        "run_id": spec.run_id,
        "targets": len(world.targets),
        "found_all_step": int(found.max()) if len(found) and (found >= 0).all() else -1,
        "targets_found": int((found >= 0).sum()),
        "relay_formation_steps": int(world.role_steps[:, auctioneer].sum()),
        "complete_step": complete_step,
        "steps": sim.step_count,
        "networkers": sum(r == "networker" for r in world.roles),
        "roots": sum(r in ("root", "auctioneer") for r in world.roles),
        "rendezvous_returns": int(world.rendezvous_returns.sum()),
        "rendezvous_arrivals": int(world.rendezvous_arrivals.sum()),
        "root_elections": int(world.root_elections.sum()),
        "auctions": int(world.auctions.sum()),
        "messages_per_drone": float(sent.mean()),
        "bytes_per_drone": float(sent_bytes.mean()),
        "errors": len(sim.failures),
        "error_reasons": sorted({str(getattr(s.failure, "reason", s.failure))
                                 for s in sim.failures}),
        "wall_seconds": round(time.perf_counter() - started, 2),
        "bandwidth": bandwidth,
    }


# ---- results on disk ---------------------------------------------------------------------------
def result_path(out: Path, spec: RunSpec) -> Path:
    return out / "runs" / f"{spec.run_id}.json"


def write_result(out: Path, result: dict[str, Any]) -> None:
    """Atomic: a killed sweep leaves either the whole file or none."""
    path = out / "runs" / f"{result['run_id']}.json"
    tmp = path.with_suffix(".json.tmp")
    tmp.write_text(json.dumps(result))
    os.replace(tmp, path)


def load_result(path: Path) -> dict[str, Any] | None:
    try:
        return json.loads(path.read_text())
    except (OSError, ValueError):
        return None   # torn or foreign: run it again


#: The settings a run's result depends on besides its id (drones, arena, search, trial): a
#: finished run in the output folder is reused only when it was made with the same ones.
SWEEP_KEYS = ("seed", "max_steps", "comm_range", "search_steps", "targets_where")


def _check_same_sweep(previous: dict[str, Any], spec: RunSpec, out: Path) -> None:
    """Refuse to resume into a folder whose finished run was made with other settings (e.g.
    another seed or target placement): mixing them would make a wrong table, and running
    the run again would overwrite a result. A result without a key (an older bbzide) does
    not match."""
    differ = [f"{key} {previous.get(key, 'not recorded')!r} there, {getattr(spec, key)!r} now"
              for key in SWEEP_KEYS if previous.get(key) != getattr(spec, key)]
    if previous.get("script", str(SCRIPT)) != spec.script:  # recorded when not the example
        differ.append(f"script {previous.get('script', str(SCRIPT))} there, {spec.script} now")
    if differ:
        raise UserError(f"{out} holds runs of another sweep ({spec.run_id}: "
                        f"{'; '.join(differ)}); give another --out to keep both")


CSV_FIELDS = ("run_id", "drones", "arena", "search", "trial", "seed", "targets",
              "targets_found", "found_all_step", "relay_formation_steps", "complete_step",
              "steps", "max_steps", "networkers", "roots", "rendezvous_returns",
              "rendezvous_arrivals", "root_elections", "auctions", "messages_per_drone",
              "bytes_per_drone", "errors", "wall_seconds", "command")


def write_csv(path: Path, results: Sequence[dict[str, Any]]) -> None:
    with path.open("w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=CSV_FIELDS, extrasaction="ignore")
        writer.writeheader()
        for r in sorted(results, key=lambda r: (r["arena"], r["drones"], r["trial"],
                                                r["search"])):
            writer.writerow(r)


def sign_test(wins: int, losses: int) -> float:
    """Two-sided exact sign test p-value (ties dropped): the binomial test of `wins` in
    `wins + losses` pairs against 1/2."""
    from scipy.stats import binomtest  # scipy.stats takes ~0.5 s to import: only when needed

    if wins + losses == 0:
        return 1.0
    return float(binomtest(wins, wins + losses, 0.5).pvalue)


#: Scale of the Cauchy prior on the effect size of the Bayes factor: sqrt(2)/2, the default
#: of JASP's Bayesian paired samples t-test, the software the thesis used (§5.4.2, [74]).
CAUCHY_SCALE = math.sqrt(2) / 2


def jzs_bayes_factor(differences: Sequence[float], scale: float = CAUCHY_SCALE) -> float | None:
    """BF10 of the JZS Bayesian paired t-test (Rouder et al. 2009, two-sided, Cauchy prior of
    scale `scale` on the effect size): the thesis' comparison (BF > 1 favours a difference).
    From the t statistic of the differences: BF10 = integral over g of
    (1 + n g r^2)^(-1/2) (1 + t^2 / ((1 + n g r^2) v))^(-(v+1)/2) (2 pi)^(-1/2) g^(-3/2)
    e^(-1/(2g)) dg / (1 + t^2/v)^(-(v+1)/2), v = n - 1, integrated by scipy's adaptive
    quadrature (QUADPACK) on ln g, scaled by the integrand's peak so that the BF10 of a
    270-pair sweep (~1e25) neither overflows nor underflows. None with fewer than 2
    differences or all differences equal."""
    from scipy.integrate import quad
    from scipy.optimize import minimize_scalar

    n = len(differences)
    if n < 2:
        return None
    mean = statistics.fmean(differences)
    sd = statistics.stdev(differences)
    if sd == 0:
        return None
    t = mean / (sd / math.sqrt(n))
    v = n - 1

    def log_integrand(u: float) -> float:   # u = ln g; + u: dg = g du
        g = math.exp(u)
        spread = 1.0 + n * g * scale ** 2
        return (-0.5 * math.log(spread) - (v + 1) / 2 * math.log1p(t * t / (spread * v))
                - 0.5 * math.log(2 * math.pi) - 1.5 * u - 1 / (2 * g) + u)

    # The integrand has one peak on ln g (e^-1/(2g) kills it on the left, it falls as e^-u
    # on the right): found in [-30, 30] and given to QUADPACK as the split point. 60 on
    # either side of the peak it is below e^-60 of it, far under quad's relative tolerance.
    peak_u = float(minimize_scalar(lambda u: -log_integrand(u), bounds=(-30.0, 30.0),
                                   method="bounded", options={"xatol": 1e-6}).x)
    peak = log_integrand(peak_u)
    area = 0.0
    for low, high in ((peak_u - 60.0, peak_u), (peak_u, peak_u + 60.0)):
        part, _ = quad(lambda u: math.exp(log_integrand(u) - peak), low, high,
                       epsabs=0.0, epsrel=1e-9, limit=200)
        area += part
    log_null = -(v + 1) / 2 * math.log1p(t * t / v)
    return math.exp(peak + math.log(area) - log_null)


def paired_comparison(results: Sequence[dict[str, Any]]) -> list[dict[str, Any]]:
    """Per (arena, drones): belief vs random on the pairs where both found every target."""
    by_pair: dict[tuple[float, int, int], dict[str, dict[str, Any]]] = {}
    for r in results:
        by_pair.setdefault((r["arena"], r["drones"], r["trial"]), {})[r["search"]] = r
    rows = []
    for arena, drones in sorted({(a, d) for a, d, _ in by_pair}):
        pairs = [p for (a, d, _), p in sorted(by_pair.items())
                 if a == arena and d == drones and "belief" in p and "random" in p]
        ok = [p for p in pairs
              if p["belief"]["found_all_step"] >= 0 and p["random"]["found_all_step"] >= 0]
        diffs = [p["random"]["found_all_step"] - p["belief"]["found_all_step"] for p in ok]
        wins = sum(d > 0 for d in diffs)
        losses = sum(d < 0 for d in diffs)

        def med(search: str, key: str, rows: list = pairs) -> float | None:
            values = [p[search][key] for p in rows if p[search][key] >= 0]
            return statistics.median(values) if values else None

        rows.append({
            "arena": arena, "drones": drones, "pairs": len(pairs), "complete_pairs": len(ok),
            "median_find_random": med("random", "found_all_step"),
            "median_find_belief": med("belief", "found_all_step"),
            "median_paired_saving": statistics.median(diffs) if diffs else None,
            "belief_faster": wins, "random_faster": losses,
            "sign_test_p": round(sign_test(wins, losses), 4),
            "bayes_factor": (None if (bf := jzs_bayes_factor(diffs)) is None
                             else float(f"{bf:.4g}")),
            "median_relay_random": med("random", "relay_formation_steps"),
            "median_relay_belief": med("belief", "relay_formation_steps"),
            "incomplete_trees": sum(p[s]["complete_step"] < 0 for p in pairs for s in p),
            "median_messages_random": med("random", "messages_per_drone"),
            "median_messages_belief": med("belief", "messages_per_drone"),
            "median_bytes_random": med("random", "bytes_per_drone"),
            "median_bytes_belief": med("belief", "bytes_per_drone"),
            "median_wall_seconds": statistics.median(
                [p[s]["wall_seconds"] for p in pairs for s in p]) if pairs else None,
        })
    return rows


def format_markdown(rows: Iterable[dict[str, Any]]) -> str:
    """The README's results table: medians per configuration, random | belief; the last
    column is the JZS Bayes factor of the paired find times (the paper's comparison)."""
    def f(v: Any, digits: int = 0) -> str:
        return "-" if v is None else f"{v:.{digits}f}"

    lines = ["| arena | drones | pairs | find: random | find: belief | belief faster | sign "
             "test p | relay: random | relay: belief | msgs/drone: random | msgs/drone: belief "
             "| bytes/drone: random | bytes/drone: belief | incomplete trees | find BF10 |",
             "|" + "---:|" * 15]
    for r in rows:
        lines.append(
            f"| {r['arena']:g} | {r['drones']} | {r['pairs']} | {f(r['median_find_random'])} | "
            f"{f(r['median_find_belief'])} | {r['belief_faster']}/{r['complete_pairs']} | "
            f"{r['sign_test_p']:.3f} | {f(r['median_relay_random'])} | "
            f"{f(r['median_relay_belief'])} | {f(r['median_messages_random'])} | "
            f"{f(r['median_messages_belief'])} | {f(r['median_bytes_random'])} | "
            f"{f(r['median_bytes_belief'])} | {r['incomplete_trees']} | "
            f"{'-' if r.get('bayes_factor') is None else format(r['bayes_factor'], '.4g')} |")
    return "\n".join(lines)


def write_comparison(path: Path, rows: Sequence[dict[str, Any]]) -> None:
    if not rows:
        return
    with path.open("w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)


def format_comparison(rows: Iterable[dict[str, Any]]) -> str:
    lines = ["arena drones pairs  find(random) find(belief) saving  belief/random faster  p"
             "      relay(random) relay(belief) incomplete"]
    for r in rows:
        def f(v: Any) -> str:
            return "-" if v is None else f"{v:g}"
        lines.append(
            f"{r['arena']:>5g} {r['drones']:>6} {r['pairs']:>5}  {f(r['median_find_random']):>12}"
            f" {f(r['median_find_belief']):>12} {f(r['median_paired_saving']):>6}  "
            f"{r['belief_faster']:>6}/{r['random_faster']:<6}        {r['sign_test_p']:<6} "
            f"{f(r['median_relay_random']):>13} {f(r['median_relay_belief']):>13} "
            f"{r['incomplete_trees']:>10}")
    return "\n".join(lines)


# ---- the sweep ---------------------------------------------------------------------------------
def task_key(spec: RunSpec) -> str:
    """The run's task name for a Dask scheduler: its id and seed, and a digest of the rest of
    its spec, since the scheduler treats two tasks of one name as one result."""
    digest = hashlib.blake2b(repr(spec).encode(), digest_size=6).hexdigest()
    return f"sar-{spec.run_id}-seed{spec.seed}-{digest}"


def in_submission_order(specs: Iterable[RunSpec]) -> list[RunSpec]:
    """The order runs are handed to an executor, the same for local processes and Dask: trial
    by trial, so a sweep stopped early has as many pairs in every configuration (give it
    --trials 30 and stop it when time is up); within a trial, longest runs first (big arenas,
    few drones) so the workers do not end on one straggler."""
    return sorted(specs, key=lambda s: (s.trial, -s.arena, s.drones, s.search))


def run_sweep(settings: SweepSettings) -> list[dict[str, Any]]:
    validate(settings, settings.extra.get("comm_range", COMM_RANGE))
    out = settings.out
    try:
        (out / "runs").mkdir(parents=True, exist_ok=True)
    except OSError as error:
        raise UserError(f"cannot create the output folder {out}: {error.strerror}") from None
    specs = plan_runs(settings)
    results: dict[str, dict[str, Any]] = {}
    todo = []
    for spec in specs:
        previous = load_result(result_path(out, spec))
        if previous is not None:
            _check_same_sweep(previous, spec, out)
            results[spec.run_id] = previous
        else:
            todo.append(spec)
    if results:
        print(f"resuming: {len(results)} of {len(specs)} runs already in {out / 'runs'}")
    started = time.monotonic()
    executor = open_executor(settings.jobs, settings.cluster)
    if todo:
        todo = in_submission_order(todo)
        with executor, progress_bar(len(specs), len(results)) as bar:
            for _, result in executor.map_unordered(run_one, todo, [task_key(s) for s in todo]):
                write_result(out, result)
                results[result["run_id"]] = result
                bar.update()
    wall = time.monotonic() - started
    finished = [results[s.run_id] for s in specs]
    for spec, result in zip(specs, finished, strict=True):
        result["command"] = "bbzide " + shlex.join(reproduce_command(spec, result["steps"]))
    write_csv(out / "runs.csv", finished)
    rows = paired_comparison(finished)
    write_comparison(out / "comparison.csv", rows)
    (out / "summary.md").write_text(format_markdown(rows) + "\n")
    print(format_comparison(rows))
    from bbzide.worlds import sar_plots

    written = sar_plots.write_all(out, finished)
    timeouts = sum(r["complete_step"] < 0 for r in finished)
    print(f"{len(todo)} runs in {wall / 60:.1f} min on {executor.description} "
          f"({len(finished)} in {out}); {timeouts} without a complete relay tree; "
          f"plots: {', '.join(p.name for p in written)}")
    return finished


# ---- command line ------------------------------------------------------------------------------
def register(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser(
        "experiment", help="reproduce a paper experiment (sar: thesis §5.4 / §5.5)")
    parser.add_argument("name", choices=["sar"], help="the experiment")
    parser.add_argument("--drones", default=None,
                        help=f"drone counts (comma-separated; default {DEFAULT_DRONES})")
    parser.add_argument("--arena", default=None,
                        help=f"arena sides in metres (default {DEFAULT_ARENAS})")
    parser.add_argument("--search", default=None,
                        help=f"random and/or belief (default: the scenario's, else "
                             f"{DEFAULT_SEARCHES})")
    parser.add_argument("--trials", type=int, default=None,
                        help=f"trials per configuration (default {DEFAULT_TRIALS}; "
                             f"{FIELD_TRIALS} with --preset field)")
    parser.add_argument("--seed", type=int, default=None,
                        help="sweep seed (default: the scenario's, else 0)")
    parser.add_argument("--scenario", type=Path, default=None, metavar="S.toml",
                        help="an m300 scenario (e.g. examples/sar/sar.toml): its script, "
                             "drones, world options (size, search, comm_range, targets, ...), "
                             "seed and steps (as --max-steps) are the sweep's defaults; "
                             "--drones, --arena, --search, --seed and --max-steps still "
                             "override them")
    add_executor_arguments(parser, default_jobs=None)
    parser.add_argument("--out", default="sar-results", help="output folder (resumable)")
    parser.add_argument("--max-steps", type=int, default=None,
                        help=f"steps before a run counts as a timeout (default: the "
                             f"scenario's steps, else {DEFAULT_MAX_STEPS})")
    parser.add_argument("--targets-where", choices=["uniform", "likely", "anywhere"],
                        default=None,
                        help="generated targets: uniform (default): anywhere in the field "
                             "whatever the prior (thesis §5.4.1: randomly spawned); or in "
                             "proportion to the prior belief: likely: only where it reaches "
                             "the search threshold; anywhere: floor included")
    parser.add_argument("--preset", choices=["field"], default=None,
                        help="field: the paper's field test (36 m, 3 drones, 1 target, "
                             "fixed belief map; 3 trials unless --trials is given)")
    parser.set_defaults(handler=run_command)


#: The §5.4 sweep's grid (thesis Figs. 5.6-5.11) and the runs per configuration we use.
DEFAULT_DRONES, DEFAULT_ARENAS, DEFAULT_TRIALS = "15,20,25", "20,30,40", 30
DEFAULT_SEARCHES = "random,belief"
#: The field test's trials when --trials is not given: the paper's Table 5.1 has 3 runs.
FIELD_TRIALS = 3


#: The M300 world options a scenario may set for the sweep: the RunSpec's own fields (the
#: sweep's axes, size and search, come from --arena and --search when those are given).
SCENARIO_OPTIONS = ("size", "search", "comm_range", "search_steps", "targets", "belief_map",
                    "targets_where")


@dataclass(frozen=True)
class ScenarioDefaults:
    """What an m300 scenario file gives the sweep (`scenario_defaults`)."""

    script: str
    drones: str
    seed: int
    max_steps: int
    arena: str | None = None
    search: str | None = None
    extra: dict[str, Any] = field(default_factory=dict)


def scenario_defaults(path: Path) -> ScenarioDefaults:
    """Read `path` (a scenario, bbzide.worlds.scenario) as the sweep's defaults; a scenario
    the sweep cannot follow exactly (another world, pinned positions, several scripts, a world
    option a run does not carry) is refused, naming what to change."""
    from bbzide.worlds.scenario import load_scenario

    scenario = load_scenario(path)
    if scenario.world != "m300":
        raise UserError(f"{path}: the sar experiment runs the m300 world, not {scenario.world}")
    scripts = scenario.scripts()
    if len(scripts) != 1 or len(scenario.groups) != 1:
        raise UserError(f"{path}: the sar experiment runs one group of drones with one script")
    if scenario.groups[0].positions is not None:
        raise UserError(f"{path}: the sar experiment places the drones from each run's seed: "
                        "leave out positions")
    if scenario.radio or scenario.asynchronous:
        raise UserError(f"{path}: the sar experiment takes comm_range as a world option; "
                        "leave out [radio] and asynchronous")
    options = dict(scenario.world_options)
    other = sorted(set(options) - set(SCENARIO_OPTIONS))
    if other:
        raise UserError(f"{path}: the sar experiment does not vary {', '.join(other)}; its "
                        f"world options are {', '.join(SCENARIO_OPTIONS)}")
    scenario.programs()   # a script that does not compile fails here, once, with its line
    extra: dict[str, Any] = {}
    for key in ("comm_range", "search_steps", "targets_where", "belief_map"):
        if key in options:
            extra[key] = options[key]
    if "belief_map" in extra:   # relative to the scenario, as its script is
        extra["belief_map"] = str((path.resolve().parent / extra["belief_map"]).resolve())
    if "targets" in options:
        targets = options["targets"]
        extra["targets"] = targets if isinstance(targets, int) else tuple(
            (float(x), float(y)) for x, y in targets)
    return ScenarioDefaults(
        script=str(scripts[0]), drones=str(scenario.robots), seed=scenario.seed,
        max_steps=scenario.steps or DEFAULT_MAX_STEPS,
        arena=None if "size" not in options else f"{float(options['size']):g}",
        search=options.get("search"), extra=extra)


def settings_from_args(args: argparse.Namespace) -> SweepSettings:
    pinned = None if getattr(args, "scenario", None) is None else scenario_defaults(args.scenario)
    if pinned is not None and args.preset is not None:
        raise UserError("--preset and --scenario both set the sweep: give one")
    search_text = args.search if args.search is not None else (
        (pinned.search if pinned is not None else None) or DEFAULT_SEARCHES)
    searches = [s.strip() for s in search_text.split(",") if s.strip()]
    if args.preset == "field" and (args.drones is not None or args.arena is not None):
        raise UserError("--preset field has 3 drones on a 36 m field: "
                        "leave out --drones and --arena")
    trials = args.trials
    if trials is None:
        trials = FIELD_TRIALS if args.preset == "field" else DEFAULT_TRIALS
    drones = args.drones or (pinned.drones if pinned else DEFAULT_DRONES)
    arenas = args.arena or (pinned.arena if pinned and pinned.arena else DEFAULT_ARENAS)
    seed = args.seed if args.seed is not None else (pinned.seed if pinned else 0)
    max_steps = args.max_steps if args.max_steps is not None else (
        pinned.max_steps if pinned else DEFAULT_MAX_STEPS)
    settings = SweepSettings(
        drones=_int_list(drones, "drones"), arenas=_float_list(arenas, "arena"),
        searches=searches, trials=trials, seed=seed, jobs=args.jobs,
        out=Path(args.out), max_steps=max_steps, preset=args.preset,
        cluster=args.cluster)
    if pinned is not None:
        settings.extra.update(pinned.extra, script=pinned.script)
    if args.targets_where is not None or "targets_where" not in settings.extra:
        settings.extra["targets_where"] = args.targets_where or "uniform"
    if args.preset == "field":
        settings.drones, settings.arenas = [3], [36.0]
        settings.extra = {"targets": (FIELD_TARGET,), "belief_map": str(FIELD_BELIEF),
                          "comm_range": FIELD_COMM_RANGE}
    return settings


def run_command(args: argparse.Namespace) -> int:
    finished = run_sweep(settings_from_args(args))
    if args.preset == "field":
        formed = sum(r["complete_step"] >= 0 for r in finished)
        print(f"field test: the relay line formed in {formed} of {len(finished)} runs")
        shown = next((r for r in finished if r["search"] == "belief"), finished[0])
        print(f"record one for replay: {shown['command']} --record field.rrd")
    return 0
