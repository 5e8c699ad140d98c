"""The cost of Dask, phase by phase: the same SAR runs with `--jobs N` (local processes) and with
`--cluster local --jobs N` (a LocalCluster of N single-threaded worker processes), alternating.

Design: in this process, each mode goes through the executor exactly as `bbzide experiment sar`
does (`open_executor`, the sweep's submission order `in_submission_order`, `map_unordered` of
`run_one`), with each task wrapped to stamp, on the worker, its process id, wall-clock start
and end (time.time: one clock for every process of this machine) and the CPU time it used.
From the stamps the sweep's wall time splits into phases:

  start-up   entering the executor: the pool's fork, or the LocalCluster's scheduler and
             worker processes and the workers' check (worker_check.probe)
  first run  per worker, from the submission to the start of its first task: the dispatch,
             and the worker's imports of bbzide, numpy, numba on its first task
  runs       the tasks' own time (their CPU time beside it)
  gaps       per worker, the time between one task's end and its next task's start
  tail       per worker, from its last task's end to the last result: workers idle at the
             end while another finishes its last run (a straggler)
  shut-down  leaving the executor (terminating the pool, closing the cluster)

The per-worker phases are summed over the workers and divided by N, so that the phases add up
to the wall time. Each round's results must be identical in both modes but for the wall-time
field (the sweep's promise). The load average is printed before and after each mode; speed
under load is noise: compare the CPU times.

The runs are the full study's grid (15,20,25 drones x 20,30,40 m x both searches, sweep seed
2026) with fewer trials: `--trials 3` is 54 of the 540 runs.

    nice -n 10 .venv/bin/python benchmarks/cluster_bench.py [trials, default 1]
        [rounds, default 1] [jobs, default 2]
"""

from __future__ import annotations

import os
import sys
import time
from collections import defaultdict
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from bbzide.worlds import sar_experiment as sx
from bbzide.worlds.executors import open_executor

GRID = {"drones": [15, 20, 25], "arenas": [20.0, 30.0, 40.0], "searches": ["random", "belief"]}
SEED = 2026


@dataclass(frozen=True)
class Stamp:
    worker: int          # the process id that ran the task
    start: float         # time.time() at the task's start, on the worker
    end: float
    cpu: float           # the task's process CPU seconds


def stamped_run(spec: sx.RunSpec) -> tuple[Stamp, dict[str, Any]]:
    """`run_one(spec)` and when and where it ran."""
    start, cpu = time.time(), time.process_time()
    result = sx.run_one(spec)
    return Stamp(os.getpid(), start, time.time(), time.process_time() - cpu), result


def load() -> str:
    return "/".join(f"{value:.1f}" for value in os.getloadavg())


def sweep(specs: list[sx.RunSpec], jobs: int, cluster: bool) -> tuple[dict[str, float],
                                                                       list[dict[str, Any]]]:
    """One mode's phases (seconds) and its results in submission order."""
    began = time.time()
    executor = open_executor(jobs, "local" if cluster else None,
                             local_modules=[sys.modules[__name__]])
    executor.__enter__()
    try:
        submitted = time.time()
        stamps: list[Stamp] = [None] * len(specs)   # type: ignore[list-item]
        results: list[dict[str, Any]] = [{}] * len(specs)
        keys = [sx.task_key(spec) for spec in specs]
        for index, (stamp, result) in executor.map_unordered(stamped_run, specs, keys):
            stamps[index], results[index] = stamp, result
        last_result = time.time()
    finally:
        closing = time.time()
        executor.__exit__(None, None, None)
    ended = time.time()
    by_worker: dict[int, list[Stamp]] = defaultdict(list)
    for stamp in stamps:
        by_worker[stamp.worker].append(stamp)
    first = gaps = tail = 0.0
    for mine in by_worker.values():
        mine.sort(key=lambda stamp: stamp.start)
        first += mine[0].start - submitted
        gaps += sum(b.start - a.end for a, b in zip(mine, mine[1:], strict=False))
        tail += last_result - mine[-1].end
    # A worker that ran nothing idles the whole time: count it in the tail.
    tail += (jobs - len(by_worker)) * (last_result - submitted)
    phases = {"wall": ended - began, "start-up": submitted - began,
              "first run": first / jobs, "runs": sum(s.end - s.start for s in stamps) / jobs,
              "runs CPU": sum(s.cpu for s in stamps) / jobs, "gaps": gaps / jobs,
              "tail": tail / jobs, "shut-down": ended - closing, "workers": len(by_worker)}
    return phases, results


def without_wall_times(results: list[dict[str, Any]]) -> list[dict[str, Any]]:
    return [{k: v for k, v in r.items() if k != "wall_seconds"} for r in results]


def main() -> None:
    trials = int(sys.argv[1]) if len(sys.argv) > 1 else 1
    rounds = int(sys.argv[2]) if len(sys.argv) > 2 else 1
    jobs = int(sys.argv[3]) if len(sys.argv) > 3 else 2
    settings = sx.SweepSettings(trials=trials, seed=SEED, jobs=jobs, out=Path("unused"),
                                **GRID)
    specs = sx.in_submission_order(sx.plan_runs(settings))
    totals = {"jobs": 0.0, "cluster": 0.0}
    print(f"{len(specs)} runs per sweep, {jobs} processes, {rounds} round(s); seconds, per-worker "
          "phases averaged over the workers; load average 1/5/15 min")
    print(f"{'':18}{'wall':>7}{'start-up':>10}{'first run':>11}{'runs':>8}{'(CPU)':>8}"
          f"{'gaps':>7}{'tail':>7}{'shut-down':>11}")
    for round_ in range(rounds):
        outputs = {}
        # jobs first in odd rounds, the cluster first in even ones
        for mode in ("jobs", "cluster")[:: 1 if round_ % 2 == 0 else -1]:
            before = load()
            phases, outputs[mode] = sweep(specs, jobs, mode == "cluster")
            totals[mode] += phases["wall"]
            print(f"round {round_ + 1} {mode:8}{phases['wall']:7.1f}{phases['start-up']:10.1f}"
                  f"{phases['first run']:11.1f}{phases['runs']:8.1f}{phases['runs CPU']:8.1f}"
                  f"{phases['gaps']:7.2f}{phases['tail']:7.1f}{phases['shut-down']:11.1f}"
                  f"   load {before} -> {load()}", flush=True)
        same = without_wall_times(outputs["jobs"]) == without_wall_times(outputs["cluster"])
        print(f"round {round_ + 1} results identical but for wall times: {same}")
        if not same:
            sys.exit("the cluster's results differ from the local processes'")
    overhead = 100 * (totals["cluster"] / totals["jobs"] - 1)
    print(f"total: --jobs {jobs} {totals['jobs']:.1f} s, --cluster local {totals['cluster']:.1f} s"
          f" ({overhead:+.1f} %)")


if __name__ == "__main__":
    main()
