"""Where an experiment's runs execute: one `Executor` interface for every experiment command
(`bbzide experiment sar`, experiments/crazyflie_*.py), on this machine or on a Dask cluster.

Design: an experiment is a list of independent tasks, one picklable function applied to each of
a list of picklable items, each task named by a key that says everything its result depends on
(a SAR run: its id and seed). `Executor.map_unordered` submits them all in order and yields
`(index, result)` as each finishes, so the caller can store every result at once (a sweep
resumes from them) and advance its progress bar (`progress_bar`, tqdm).

- `ProcessExecutor(jobs)`: this machine; in this process for 1 job, else a `multiprocessing`
  pool (fork on Linux: workers start with the parent's imports).
- `DaskExecutor(address, jobs)`: a Dask `distributed` cluster: the scheduler at `address`
  (`tcp://host:8786`), or `local` for a `LocalCluster` of `jobs` single-threaded worker
  processes on 127.0.0.1 without a dashboard. Tasks are submitted one by one, so the scheduler
  runs them first come first served (the caller's order). Before the first task every worker
  runs `worker_check.probe`, shipped by value: a worker without the project, or with other
  sources or pins, is a one-line `UserError`, not a pickling error in the first task. Tasks
  travel as bytes unpickled inside the task (`worker_check.ship`), so a worker that joins
  later without bbzide fails its task with an import error (one line here too) instead of
  dropping off the cluster. While it waits for results it asks the scheduler every
  WATCH_SECONDS whether it is still there and still has workers: a scheduler lost mid-sweep,
  or one left without workers for FIRST_WORKER_SECONDS, is a one-line `UserError` (the
  finished runs are already stored, so the same command resumes), not a traceback or a hang.

Dask is the optional `cluster` extra (pyproject.toml): it is imported only for `--cluster`.
"""

from __future__ import annotations

import argparse
import logging
import multiprocessing
import os
import pickle
import socket
import sys
import time
from collections.abc import Callable, Iterator, Sequence
from types import ModuleType, TracebackType
from typing import Any, Protocol, TypeVar

from bbzide.diagnostics import UserError
from bbzide.worlds import worker_check

Item = TypeVar("Item")
Result = TypeVar("Result")

#: `--cluster` value that starts a Dask LocalCluster on this machine.
LOCAL = "local"
#: Seconds to reach a scheduler: a reachable one answers in well under a second, a wrong
#: address (a typo, a firewall) should not keep the user waiting for Dask's default 30 s.
CONNECT_SECONDS = 10
#: The port `dask scheduler` listens on unless told otherwise (an address without a port).
DEFAULT_SCHEDULER_PORT = 8786
#: Seconds to wait for the first worker of a scheduler that has none yet: time to start
#: `dask worker` on another machine after the scheduler, not an endless hang.
FIRST_WORKER_SECONDS = 60
#: Tasks a LocalCluster's scheduler hands a worker per thread (its "worker-saturation"): 1.0,
#: the next run is sent when one finishes, like `multiprocessing.Pool.imap_unordered`.
LOCAL_WORKER_SATURATION = 1.0
#: Seconds without a finished task after which the sweep asks the scheduler whether it still
#: has workers: a SAR run takes ~1-60 s, and a question every 5 s costs the scheduler nothing.
WATCH_SECONDS = 5


class Executor(Protocol):
    """Runs independent tasks; a context manager (leaving it stops its workers)."""

    #: One line for the user: where the runs went ("2 local processes", "Dask cluster ...").
    description: str

    def map_unordered(self, function: Callable[[Item], Result], items: Sequence[Item],
                      keys: Sequence[str]) -> Iterator[tuple[int, Result]]:
        """`(index, function(items[index]))` for every item, in the order they finish."""
        ...

    def __enter__(self) -> Executor: ...

    def __exit__(self, kind: type[BaseException] | None, error: BaseException | None,
                 trace: TracebackType | None) -> None: ...


class ProcessExecutor:
    """This machine: `jobs` worker processes (none for 1 job: the runs run in this process)."""

    def __init__(self, jobs: int) -> None:
        if jobs < 1:
            raise UserError("--jobs must be at least 1")
        self.jobs = jobs
        self.description = f"{jobs} job{'s' if jobs > 1 else ''}"
        self._pool: Any = None

    def __enter__(self) -> ProcessExecutor:
        if self.jobs > 1:
            context = multiprocessing.get_context("spawn" if sys.platform == "darwin"
                                                  else "fork")
            self._pool = context.Pool(self.jobs)
        return self

    def __exit__(self, kind: type[BaseException] | None, error: BaseException | None,
                 trace: TracebackType | None) -> None:
        if self._pool is not None:
            self._pool.terminate()
            self._pool = None

    def map_unordered(self, function: Callable[[Item], Result], items: Sequence[Item],
                      keys: Sequence[str]) -> Iterator[tuple[int, Result]]:
        if self._pool is None:
            for index, item in enumerate(items):
                yield index, function(item)
            return
        yield from self._pool.imap_unordered(_IndexedCall(function), enumerate(items))


class _IndexedCall:
    """`(index, item) -> (index, function(item))` for the pool (a lambda does not pickle)."""

    def __init__(self, function: Callable[[Any], Any]) -> None:
        self.function = function

    def __call__(self, indexed: tuple[int, Any]) -> tuple[int, Any]:
        index, item = indexed
        return index, self.function(item)


def _refused_at_once(address: str) -> None:
    """Raise `ConnectionRefusedError` at once when nothing listens at a TCP scheduler address
    (a wrong port, a scheduler not started): Dask's client retries a refused connection until
    its timeout, CONNECT_SECONDS of waiting for an answer that is already known."""
    from distributed.comm.addressing import parse_address, parse_host_port

    scheme, location = parse_address(address)
    if scheme != "tcp":
        return
    host, port = parse_host_port(location, default_port=DEFAULT_SCHEDULER_PORT)
    with socket.create_connection((host, port), timeout=CONNECT_SECONDS):
        pass


class DaskExecutor:
    """A Dask cluster: the scheduler at `address`, or a LocalCluster of `jobs` workers."""

    def __init__(self, address: str, jobs: int = 1,
                 local_modules: Sequence[ModuleType] = ()) -> None:
        if not address.strip():
            raise UserError("--cluster wants a scheduler address (tcp://HOST:8786) or 'local'")
        if address == LOCAL and jobs < 1:
            raise UserError("--jobs must be at least 1")
        self.address, self.jobs = address, jobs
        self.local_modules = tuple(local_modules)
        self.description = f"Dask cluster {address}"
        self._cluster: Any = None
        self._client: Any = None

    def __enter__(self) -> DaskExecutor:
        try:
            import cloudpickle
            from distributed import Client, LocalCluster
        except ImportError:
            raise UserError("--cluster needs Dask: install the cluster extra "
                            "(pip install -e '.[cluster]')") from None
        # The probe, and modules the workers do not have installed (experiment scripts outside
        # the package), travel with the tasks instead of being imported there.
        for module in (worker_check, *self.local_modules):
            cloudpickle.register_pickle_by_value(module)
        try:
            if self.address == LOCAL:
                import dask

                # One task per worker at a time, as a pool process takes them: Dask's default
                # (1.1 x threads, rounded up: 2) queues a second run on a busy worker, and at
                # the end of a sweep a long run can wait there while the other worker idles.
                # No statistical profiler in the workers: its thread samples every task's
                # stack every 10 ms, CPU time the runs pay for a dashboard we do not open.
                with dask.config.set({"distributed.scheduler.worker-saturation":
                                      LOCAL_WORKER_SATURATION,
                                      "distributed.worker.profile.enabled": False}):
                    self._cluster = LocalCluster(
                        n_workers=self.jobs, threads_per_worker=1, processes=True,
                        host="127.0.0.1", dashboard_address=None, silence_logs=logging.ERROR)
                self._client = Client(self._cluster)
                self.description = f"a Dask LocalCluster of {self.jobs} workers"
            else:
                _refused_at_once(self.address)
                self._client = Client(self.address, timeout=CONNECT_SECONDS)
        except ValueError:   # Dask could not parse the address
            self.__exit__(None, None, None)
            raise UserError(f"--cluster {self.address!r} is not a scheduler address "
                            "(tcp://HOST:8786) or 'local'") from None
        except (OSError, TimeoutError) as error:
            self.__exit__(None, None, None)
            raise UserError(f"cannot reach the Dask scheduler at {self.address}: "
                            f"{_first_line(error)}") from None
        try:
            self._check_workers()
        except BaseException:
            self.__exit__(None, None, None)
            raise
        return self

    def __exit__(self, kind: type[BaseException] | None, error: BaseException | None,
                 trace: TracebackType | None) -> None:
        if self._client is not None:
            self._client.close()
            self._client = None
        if self._cluster is not None:
            self._cluster.close()
            self._cluster = None

    def _check_workers(self) -> None:
        try:
            self._client.wait_for_workers(1, timeout=FIRST_WORKER_SECONDS)
        except TimeoutError:
            raise UserError(f"no Dask worker joined the scheduler at {self.address} within "
                            f"{FIRST_WORKER_SECONDS} s: start `dask worker {self.address}` on "
                            "each machine") from None
        here = worker_check.probe()
        reports = self._client.run(worker_check.probe)
        for worker, report in sorted(reports.items()):
            why = worker_check.mismatch(report, here)
            if why is not None:
                raise UserError(f"Dask worker {worker} cannot run bbzide's experiments: {why}; "
                                f"{worker_check.INSTALL_HINT}")
        threads = self._client.nthreads()
        if self.address != LOCAL:
            self.description = (f"Dask cluster {self.address} ({len(reports)} workers, "
                                f"{sum(threads.values())} threads)")
        if max(threads.values()) > 1:
            # A run is pure Python: threads of one worker process take turns on one core.
            print(f"note: some Dask workers run {max(threads.values())} threads; a run holds "
                  "Python's lock, so start workers with `--nworkers N --nthreads 1` for N "
                  "runs at a time", file=sys.stderr)

    def map_unordered(self, function: Callable[[Item], Result], items: Sequence[Item],
                      keys: Sequence[str]) -> Iterator[tuple[int, Result]]:
        from distributed import wait

        if len(set(keys)) != len(keys):
            raise ValueError("two tasks share a key: Dask would run only one of them")
        try:
            futures = [self._client.submit(pickle.loads, worker_check.ship(function, item),
                                           key=key)
                       for item, key in zip(items, keys, strict=True)]
        except Exception as error:   # the scheduler went away between the check and now
            raise self._cluster_lost(error, 0, len(items)) from None
        index_of = {future.key: index for index, future in enumerate(futures)}
        pending, finished = set(futures), 0
        workers_seen = time.monotonic()
        while pending:
            try:
                done, pending = wait(pending, timeout=WATCH_SECONDS, return_when="FIRST_COMPLETED")
            except TimeoutError:
                # Nothing finished for a while: fine while workers run long tasks, a clear
                # error once the scheduler is gone or has had no worker for too long.
                workers_seen = self._check_still_there(workers_seen, finished, len(futures))
                continue
            except Exception as error:
                raise self._cluster_lost(error, finished, len(futures)) from None
            for future in sorted(done, key=lambda done_future: index_of[done_future.key]):
                yield index_of[future.key], self._result(future, finished, len(futures))
                finished += 1
                future.release()

    def _result(self, future: Any, finished: int, total: int) -> Any:
        """The task's result, or its failure as one line."""
        try:
            return future.result()
        except ImportError as error:
            raise UserError(f"a Dask worker could not load the task {future.key}: "
                            f"{_first_line(error)}; {worker_check.INSTALL_HINT}") from None
        except Exception as error:
            if type(error).__name__ == "KilledWorker":
                raise UserError(f"the task {future.key} stopped every worker that ran it "
                                "(out of memory, or the worker was killed)") from None
            if _is_lost_connection(error) or self._client.status != "running":
                raise self._cluster_lost(error, finished, total) from None
            raise

    def _check_still_there(self, workers_seen: float, finished: int, total: int) -> float:
        """The time a worker was last seen; raises once the cluster is gone."""
        if self._client.status != "running":
            raise self._cluster_lost(None, finished, total)
        try:
            workers = self._client.scheduler_info().get("workers", {})
        except Exception as error:
            raise self._cluster_lost(error, finished, total) from None
        now = time.monotonic()
        if workers:
            return now
        if now - workers_seen > FIRST_WORKER_SECONDS:
            raise UserError(f"every Dask worker left the scheduler at {self.address} "
                            f"{FIRST_WORKER_SECONDS} s ago, {finished} of {total} tasks done "
                            "(kept): start `dask worker` again and rerun the same command to "
                            "resume")
        return workers_seen

    def _cluster_lost(self, error: BaseException | None, finished: int, total: int) -> UserError:
        why = "" if error is None else f" ({_first_line(error)})"
        return UserError(f"lost the Dask scheduler at {self.address} after {finished} of "
                         f"{total} tasks{why}: the finished ones are kept; rerun the same "
                         "command to resume")


def _is_lost_connection(error: BaseException) -> bool:
    """A task failed because the client lost its scheduler, not because the task failed."""
    from concurrent.futures import CancelledError

    return isinstance(error, (CancelledError, OSError)) or type(error).__name__ in (
        "CommClosedError", "FutureCancelledError")


def _first_line(error: BaseException) -> str:
    text = str(error).strip() or type(error).__name__
    return text.splitlines()[0]


def open_executor(jobs: int, cluster: str | None = None,
                  local_modules: Sequence[ModuleType] = ()) -> Executor:
    """`--jobs` / `--cluster` as an executor (not yet entered)."""
    if cluster is None:
        return ProcessExecutor(jobs)
    return DaskExecutor(cluster, jobs, local_modules)


def add_executor_arguments(parser: argparse.ArgumentParser, default_jobs: int | None) -> None:
    """`--jobs N` and `--cluster ADDRESS`, the same for every experiment command."""
    jobs = default_jobs if default_jobs is not None else os.cpu_count() or 1
    shown = "all cores" if default_jobs is None else str(jobs)
    parser.add_argument("--jobs", type=int, default=jobs,
                        help="parallel worker processes on this machine, or the workers of "
                             f"--cluster local (default: {shown})")
    parser.add_argument("--cluster", default=None, metavar="ADDRESS",
                        help="run on a Dask cluster: its scheduler's address "
                             "(tcp://HOST:8786), or 'local' to start one on this machine "
                             "(needs the cluster extra)")


def progress_bar(total: int, done: int = 0, what: str = "runs") -> Any:
    """A tqdm bar on stderr: `done` of `total` already finished (a resumed sweep)."""
    from tqdm import tqdm

    return tqdm(total=total, initial=done, unit=what.rstrip("s"), desc=what,
                file=sys.stderr, dynamic_ncols=True)


def run_in_order(executor: Executor, function: Callable[[Item], Result],
                 items: Sequence[Item], keys: Sequence[str],
                 what: str = "runs") -> list[Result]:
    """`[function(item) for item in items]` on `executor`, with a progress bar."""
    results: dict[int, Result] = {}
    with progress_bar(len(items), what=what) as bar:
        for index, result in executor.map_unordered(function, items, keys):
            results[index] = result
            bar.update()
    return [results[index] for index in range(len(items))]
