"""The cost of Dask: the same `bbzide experiment sar` sweep with `--jobs N` and with `--cluster
local --jobs N` (a LocalCluster of N single-threaded worker processes), alternating.

Design: each sweep is a fresh `bbzide` process writing into a fresh folder, timed from start to
exit, so the LocalCluster's start-up and shut-down, the workers' imports and their first
compile of the SAR script all count against Dask. The modes alternate, and each goes first in
every other round, so a machine whose load changes during the benchmark burdens both alike;
the load average is printed before and after each sweep. Each pair's `runs.csv` files must
match but for the wall-time column (the sweep's promise); the overhead is the cluster's total
time over the local processes' total. Per sweep it also prints the runs' own wall times summed
per process, and the rest (start-up, dispatch, idle processes, the summary and plots).

The runs are the full study's grid (15,20,25 drones x 20,30,40 m x both searches, sweep seed
2026) with fewer trials: `--trials 3` is 54 of the 540 runs.

    PYTHONPATH=. python benchmarks/cluster_bench.py [trials, default 1] [rounds, default 1]
        [jobs, default 2]
"""

from __future__ import annotations

import csv
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
GRID = ["experiment", "sar", "--drones", "15,20,25", "--arena", "20,30,40",
        "--search", "random,belief", "--seed", "2026"]


def sweep(trials: int, jobs: int, cluster: bool, out: Path) -> float:
    command = [sys.executable, "-m", "bbzide", *GRID, "--trials", str(trials),
               "--jobs", str(jobs), "--out", str(out)]
    if cluster:
        command += ["--cluster", "local"]
    started = time.perf_counter()
    done = subprocess.run(command, cwd=REPO, capture_output=True, text=True)
    seconds = time.perf_counter() - started
    if done.returncode != 0:
        sys.exit(f"sweep failed: {done.stderr.strip().splitlines()[-1]}")
    return seconds


def rows_but_wall_times(folder: Path) -> list[dict[str, str]]:
    with (folder / "runs.csv").open(newline="") as f:
        return [{k: v for k, v in row.items() if k != "wall_seconds"}
                for row in csv.DictReader(f)]


def run_seconds(folder: Path) -> float:
    """The runs' own wall times, summed (what the sweep would take with no start-up, no
    dispatch and no process ever idle)."""
    with (folder / "runs.csv").open(newline="") as f:
        return sum(float(row["wall_seconds"]) for row in csv.DictReader(f))


def load() -> str:
    return "/".join(f"{value:.1f}" for value in os.getloadavg())


def main() -> None:
    trials = int(sys.argv[1]) if len(sys.argv) > 1 else 1
    rounds = int(sys.argv[2]) if len(sys.argv) > 2 else 1
    jobs = int(sys.argv[3]) if len(sys.argv) > 3 else 2
    runs = 3 * 3 * 2 * trials
    totals = {"jobs": 0.0, "cluster": 0.0}
    print(f"{runs} runs per sweep, {jobs} processes, {rounds} round(s); load average 1/5/15 min")
    with tempfile.TemporaryDirectory() as folder:
        for round_ in range(rounds):
            outputs = {}
            # jobs first in odd rounds, the cluster first in even ones
            for mode in ("jobs", "cluster")[:: 1 if round_ % 2 == 0 else -1]:
                out = Path(folder) / f"{mode}{round_}"
                before = load()
                seconds = sweep(trials, jobs, mode == "cluster", out)
                totals[mode] += seconds
                outputs[mode] = out
                busy = run_seconds(out) / jobs
                print(f"round {round_ + 1} {mode:8} {seconds:7.1f} s   load {before} -> {load()}"
                      f"   runs {busy:6.1f} s per process, outside them {seconds - busy:5.1f} s",
                      flush=True)
            same = rows_but_wall_times(outputs["jobs"]) == rows_but_wall_times(
                outputs["cluster"])
            print(f"round {round_ + 1} runs.csv identical but for wall times: {same}")
            if not same:
                sys.exit("the cluster's results differ from the local processes'")
    overhead = 100 * (totals["cluster"] / totals["jobs"] - 1)
    print(f"total: --jobs {jobs} {totals['jobs']:.1f} s, --cluster local {totals['cluster']:.1f} s"
          f" ({overhead:+.1f} %)")


if __name__ == "__main__":
    main()
