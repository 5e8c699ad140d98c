"""The SAR tables of README.md and BENCHMARKS.md, regenerated from the sweeps' CSV files.

Design: the full 540-run sweeps of `bbzide experiment sar` (thesis §5.4) and its field test
(§5.5) are kept as their `runs.csv` in experiments/sar/results/ (`runs_<placement>.csv`,
`runs_field.csv`; results/README.md gives the commands that made them). This script reads
them, recomputes per configuration what `bbzide experiment sar` prints (medians, the paired
sign test, the JZS Bayes factor: `sar_experiment.paired_comparison`) plus the Bayes factor of
the relay formation times, sets the paper's figures beside ours (its Bayes factors from the
captions of Figs. 5.6-5.11 and Table 5.1: the paper gives no medians in numbers), checks the
pattern the thesis describes (rendezvous returns, one root per run), and writes each table
between its marker comments in README.md / BENCHMARKS.md. Nothing in those tables is typed by
hand: `--check` exits 1 when a document differs from what the CSV files give (a test runs it).

    .venv/bin/python experiments/sar/tables.py --uniform DIR/runs.csv --likely DIR2/runs.csv
        [--field DIR3/runs.csv]      # keep the CSVs in results/, rewrite the tables
    .venv/bin/python experiments/sar/tables.py            # rewrite them from results/
    .venv/bin/python experiments/sar/tables.py --check    # 0 if README/BENCHMARKS match
"""

from __future__ import annotations

import argparse
import csv
import statistics
import sys
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

from bbzide.worlds import sar_experiment as sx

REPO = Path(__file__).resolve().parents[2]
RESULTS = REPO / "experiments" / "sar" / "results"
DOCUMENTS = (REPO / "README.md", REPO / "BENCHMARKS.md")
#: The placements of the targets swept in full, in the order the documents show them.
PLACEMENTS = ("uniform", "likely")

#: The paper's Bayes factors of the paired find times (belief vs random), per (arena m,
#: drones): captions of Figs. 5.6-5.8.
PAPER_FIND_BF = {(20, 15): 92.404, (20, 20): 2.886, (20, 25): 70.606,
                 (30, 15): 66550.284, (30, 20): 914.282, (30, 25): 25.268,
                 (40, 15): 210.765, (40, 20): 203.165, (40, 25): 3577.307}
#: ... and of the relay formation times (the root's steps as auctioneer): Figs. 5.9-5.11.
PAPER_RELAY_BF = {(20, 15): 0.115, (20, 20): 8.070e-4, (20, 25): 2.539e-6,
                  (30, 15): 0.264, (30, 20): 3.327e-6, (30, 25): 0.022,
                  (40, 15): 3.862, (40, 20): 0.017, (40, 25): 0.469}
#: Table 5.1: the field test's three belief-map runs (timesteps of 0.1 s).
PAPER_FIELD_DISCOVERY = (1159, 863, 1295)
PAPER_FIELD_RELAY = (301, 324, 249)
#: The means the text gives (§5.5); the relay column's three values average 291.3.
PAPER_FIELD_STATED_MEANS = (1105, 295)

#: Steps before a drone can first turn back to the meeting point: the 5 m climb at 1 m/s
#: (50 steps) and one search run of 20 search steps of 1 s (200 steps). A run that ends
#: sooner ended before the paper's pattern has any return in it.
FIRST_RETURN_STEP = 50 + sx.SEARCH_STEPS * 10

INTEGER_COLUMNS = ("drones", "trial", "seed", "targets", "targets_found", "found_all_step",
                   "relay_formation_steps", "complete_step", "steps", "max_steps",
                   "networkers", "roots", "rendezvous_returns", "rendezvous_arrivals",
                   "root_elections", "auctions", "errors")
FLOAT_COLUMNS = ("arena", "messages_per_drone", "bytes_per_drone", "wall_seconds")


def read_runs(path: Path) -> list[dict[str, Any]]:
    """A sweep's runs.csv with its numbers as numbers."""
    with path.open(newline="", encoding="utf-8") as f:
        rows: list[dict[str, Any]] = list(csv.DictReader(f))
    for row in rows:
        for name in INTEGER_COLUMNS:
            row[name] = int(row[name])
        for name in FLOAT_COLUMNS:
            row[name] = float(row[name])
    return rows


def _bf(value: float | None) -> str:
    if value is None:
        return "-"
    if value >= 1e5 or value < 1e-3:
        return f"{value:.2e}"
    return f"{value:.4g}"


def _median(values: Sequence[float]) -> str:
    return f"{statistics.median(values):g}" if values else "-"


def _pairs(runs: Sequence[dict[str, Any]]) -> dict[tuple[float, int], list[dict[str, Any]]]:
    by_trial: dict[tuple[float, int, int], dict[str, dict[str, Any]]] = {}
    for r in runs:
        by_trial.setdefault((r["arena"], r["drones"], r["trial"]), {})[r["search"]] = r
    pairs: dict[tuple[float, int], list[dict[str, Any]]] = {}
    for (arena, drones, _), pair in sorted(by_trial.items()):
        if "random" in pair and "belief" in pair:
            pairs.setdefault((arena, drones), []).append(pair)
    return pairs


def relay_bayes_factor(pairs: Sequence[dict[str, dict[str, Any]]]) -> float | None:
    """JZS BF10 of the paired relay formation times, on the pairs whose trees both formed."""
    differences = [p["random"]["relay_formation_steps"] - p["belief"]["relay_formation_steps"]
                   for p in pairs
                   if p["random"]["complete_step"] >= 0 and p["belief"]["complete_step"] >= 0]
    return sx.jzs_bayes_factor(differences)


def comparison_table(runs: Sequence[dict[str, Any]]) -> str:
    """Per configuration: medians, wins, sign test and Bayes factors, the paper's beside."""
    rows = {(r["arena"], r["drones"]): r for r in sx.paired_comparison(runs)}
    pairs = _pairs(runs)
    lines = ["| arena | drones | pairs | find: random | find: belief | belief faster / "
             "slower / tie | sign test p | find BF10 | paper's find BF | relay: random | "
             "relay: belief | relay BF10 | paper's relay BF |",
             "|" + "---:|" * 13]
    for (arena, drones), row in sorted(rows.items()):
        ties = row["complete_pairs"] - row["belief_faster"] - row["random_faster"]
        key = (int(arena), drones)

        def median(search: str, column: str, pairs_here: list = pairs[(arena, drones)]) -> str:
            return _median([p[search][column] for p in pairs_here if p[search][column] >= 0])

        lines.append(
            f"| {arena:g} | {drones} | {row['pairs']} | {median('random', 'found_all_step')} | "
            f"{median('belief', 'found_all_step')} | {row['belief_faster']} / "
            f"{row['random_faster']} / {ties} | {row['sign_test_p']:.3g} | "
            f"{_bf(row['bayes_factor'])} | {_bf(PAPER_FIND_BF.get(key))} | "
            f"{median('random', 'relay_formation_steps')} | "
            f"{median('belief', 'relay_formation_steps')} | "
            f"{_bf(relay_bayes_factor(pairs[(arena, drones)]))} | "
            f"{_bf(PAPER_RELAY_BF.get(key))} |")
    return "\n".join(lines)


def totals_line(runs: Sequence[dict[str, Any]]) -> str:
    """All pairs together, and the pattern checks of issue-level facts: returns, one root."""
    diffs = []
    for pairs in _pairs(runs).values():
        diffs += [p["random"]["found_all_step"] - p["belief"]["found_all_step"] for p in pairs
                  if p["random"]["found_all_step"] >= 0 and p["belief"]["found_all_step"] >= 0]
    wins, losses = sum(d > 0 for d in diffs), sum(d < 0 for d in diffs)
    long_runs = [r for r in runs if r["steps"] > FIRST_RETURN_STEP]
    returned = sum(r["rendezvous_returns"] >= 1 for r in long_runs)
    one_root = sum(r["roots"] == 1 for r in runs)
    complete = sum(r["complete_step"] >= 0 for r in runs)
    errors = sum(r["errors"] > 0 for r in runs)
    return (f"{len(runs)} runs: over the {len(diffs)} pairs in which both searches found every "
            f"target the belief search was faster in {wins}, slower in {losses} "
            f"({len(diffs) - wins - losses} ties; sign test p = {sx.sign_test(wins, losses):.2g},"
            f" BF10 = {_bf(sx.jzs_bayes_factor(diffs))}). Relay tree complete in {complete} of "
            f"{len(runs)} runs; exactly one root in {one_root} of {len(runs)}; at least one "
            f"return to the rendezvous point in {returned} of the {len(long_runs)} runs longer "
            f"than one search run ({FIRST_RETURN_STEP} steps: climb and {sx.SEARCH_STEPS} search "
            f"steps); median returns per run {_median([r['rendezvous_returns'] for r in runs])},"
            f" root elections {_median([r['root_elections'] for r in runs])}, auctions "
            f"{_median([r['auctions'] for r in runs])}; runs with a VM error: {errors}.")


def field_table(runs: Sequence[dict[str, Any]]) -> str:
    """Table 5.1 beside ours: per search, the discovery and relay formation times (the root's
    time as auctioneer, the simulations' metric), and the time from discovery to the complete
    line (another reading of the paper's "time to form a relay chain")."""
    def spread(values: Sequence[int]) -> str:
        if not values:
            return "-"
        return (f"median {statistics.median(values):g}, mean {statistics.fmean(values):.0f} "
                f"({min(values)}-{max(values)})")

    lines = ["| field run, 36 m, 3 drones | runs | target discovery (timesteps) | relay "
             "formation (timesteps) | line complete after discovery (timesteps) | relay line "
             "formed |", "|---|---:|---|---|---|---|",
             f"| paper, belief map, Table 5.1 | {len(PAPER_FIELD_DISCOVERY)} | "
             f"{', '.join(map(str, PAPER_FIELD_DISCOVERY))} (mean "
             f"{statistics.fmean(PAPER_FIELD_DISCOVERY):.1f}; text: "
             f"{PAPER_FIELD_STATED_MEANS[0]}) | {', '.join(map(str, PAPER_FIELD_RELAY))} (mean "
             f"{statistics.fmean(PAPER_FIELD_RELAY):.1f}; text: {PAPER_FIELD_STATED_MEANS[1]})"
             " | - | 3 of 3 |"]
    for search, name in (("belief", "belief map"), ("random", "random walk")):
        mine = [r for r in runs if r["search"] == search]
        if not mine:
            continue
        found = [r["found_all_step"] for r in mine if r["found_all_step"] >= 0]
        relay = [r["relay_formation_steps"] for r in mine if r["complete_step"] >= 0]
        after = [r["complete_step"] - r["found_all_step"] for r in mine
                 if r["complete_step"] >= 0 and r["found_all_step"] >= 0]
        formed = sum(r["complete_step"] >= 0 for r in mine)
        lines.append(f"| bbzide, {name} | {len(mine)} | {spread(found)} | {spread(relay)} | "
                     f"{spread(after)} | {formed} of {len(mine)} |")
    return "\n".join(lines)


def sections(results: Path = RESULTS) -> dict[str, str]:
    """Marker name -> generated text, for every CSV present in `results`."""
    out: dict[str, str] = {}
    for placement in PLACEMENTS:
        path = results / f"runs_{placement}.csv"
        if not path.exists():
            continue
        runs = read_runs(path)
        out[f"sar-{placement}"] = comparison_table(runs) + "\n\n" + totals_line(runs)
        out[f"sar-{placement}-full"] = sx.format_markdown(sx.paired_comparison(runs))
    field = results / "runs_field.csv"
    if field.exists():
        out["sar-field"] = field_table(read_runs(field))
    return out


def begin_marker(name: str) -> str:
    return f"<!-- {name}: generated by experiments/sar/tables.py from experiments/sar/results -->"


def end_marker(name: str) -> str:
    return f"<!-- /{name} -->"


def replace_sections(text: str, generated: dict[str, str],
                     missing: Callable[[str], None] | None = None) -> str:
    """`text` with the body between each pair of markers replaced by its generated table; a
    marker pair whose CSV is absent is reported to `missing` and left as it is."""
    for name in sorted({line.split(":")[0][5:] for line in text.splitlines()
                        if line.startswith("<!-- sar-") and ": generated by" in line}):
        begin, end = begin_marker(name), end_marker(name)
        if begin not in text or end not in text:
            raise SystemExit(f"error: marker {name!r} is not closed by {end!r}")
        if name not in generated:
            if missing is not None:
                missing(name)
            continue
        head, rest = text.split(begin, 1)
        _, tail = rest.split(end, 1)
        text = f"{head}{begin}\n{generated[name]}\n{end}{tail}"
    return text


def main(argv: Sequence[str] | None = None, documents: Sequence[Path] = DOCUMENTS,
         results: Path = RESULTS) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--check", action="store_true",
                        help="exit 1 if README.md or BENCHMARKS.md differ from the CSV files")
    for name in (*PLACEMENTS, "field"):
        parser.add_argument(f"--{name}", type=Path, metavar="RUNS_CSV",
                            help=f"a finished sweep's runs.csv to keep as "
                                 f"results/runs_{name}.csv before the tables are made")
    args = parser.parse_args(argv)
    for name in (*PLACEMENTS, "field"):
        given: Path | None = getattr(args, name)
        if given is None:
            continue
        try:
            read_runs(given)   # a CSV this script can read, before it replaces the kept one
            kept = results / f"runs_{name}.csv"
            if given.resolve() != kept.resolve():
                kept.write_bytes(given.read_bytes())
        except (OSError, KeyError, ValueError) as error:
            print(f"error: --{name} {given}: not a runs.csv of bbzide experiment sar "
                  f"({error})", file=sys.stderr)
            return 1
    generated = sections(results)
    for name, text in generated.items():
        print(f"## {name}\n\n{text}\n")
    stale = []
    for document in documents:
        old = document.read_text(encoding="utf-8")
        new = replace_sections(old, generated,
                               lambda name: print(f"note: no CSV for {name}", file=sys.stderr))
        if new == old:
            continue
        if args.check:
            stale.append(document.name)
        else:
            document.write_text(new, encoding="utf-8")
            print(f"rewrote the tables of {document.name}", file=sys.stderr)
    if stale:
        print(f"error: {', '.join(stale)} differ from {results}: run "
              "experiments/sar/tables.py", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
