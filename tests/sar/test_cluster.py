"""`--cluster`: experiment runs on a Dask cluster give the same results as `--jobs`, and a
worker that cannot run them is refused with one clear line.

The clusters here are on 127.0.0.1 only, without dashboards. "A worker without the project" is
a real `dask worker` process whose Python cannot import bbzide (a finder at the front of its
`sys.meta_path` refuses it, as on a machine where the project was never installed).
"""

from __future__ import annotations

import csv
import os
import subprocess
import sys
from pathlib import Path

import pytest

from bbzide.cli import main
from bbzide.diagnostics import UserError
from bbzide.worlds import worker_check
from bbzide.worlds.executors import DaskExecutor, ProcessExecutor, run_in_order

REPO = Path(__file__).resolve().parents[2]
#: A small sweep with varied results: 2 drone counts x 2 trials x 2 searches; 300 steps is
#: long enough for targets to be found at different steps and traffic to differ per run.
SWEEP = ["experiment", "sar", "--drones", "3,4", "--arena", "20", "--trials", "2",
         "--max-steps", "300", "--seed", "5"]
WALL_COLUMNS = {"wall_seconds", "median_wall_seconds"}


def csv_without_wall_times(path: Path) -> tuple[list[str], list[dict[str, str]]]:
    with path.open(newline="") as f:
        reader = csv.DictReader(f)
        rows = [{k: v for k, v in row.items() if k not in WALL_COLUMNS} for row in reader]
        return list(reader.fieldnames or []), rows


def assert_same_but_wall_times(a: Path, b: Path) -> None:
    for name in ("runs.csv", "comparison.csv"):
        header_a, rows_a = csv_without_wall_times(a / name)
        header_b, rows_b = csv_without_wall_times(b / name)
        assert header_a == header_b
        assert rows_a == rows_b, name
    assert (a / "summary.md").read_bytes() == (b / "summary.md").read_bytes()


@pytest.mark.slow
def test_a_sweep_on_a_local_dask_cluster_writes_the_jobs_csv_but_for_wall_times(tmp_path,
                                                                               capsys):
    by_jobs, by_cluster = tmp_path / "jobs", tmp_path / "cluster"
    assert main([*SWEEP, "--jobs", "2", "--out", str(by_jobs)]) == 0
    assert main([*SWEEP, "--jobs", "2", "--cluster", "local", "--out", str(by_cluster)]) == 0
    out = capsys.readouterr().out
    assert "8 runs in" in out and "on a Dask LocalCluster of 2 workers" in out
    assert_same_but_wall_times(by_jobs, by_cluster)
    _, rows = csv_without_wall_times(by_cluster / "runs.csv")
    assert len(rows) == 8
    assert len({(r["found_all_step"], r["messages_per_drone"]) for r in rows}) > 1
    with (by_cluster / "runs.csv").open() as f:
        assert all(float(r["wall_seconds"]) > 0 for r in csv.DictReader(f))
    # Resume on the cluster: the two runs taken out are run again there, the rest kept.
    kept = by_cluster / "runs" / "d3_a20_belief_t000.json"
    before = kept.stat().st_mtime_ns
    for run_id in ("d4_a20_random_t001", "d3_a20_belief_t001"):
        (by_cluster / "runs" / f"{run_id}.json").unlink()
    assert main([*SWEEP, "--jobs", "2", "--cluster", "local", "--out", str(by_cluster)]) == 0
    out = capsys.readouterr().out
    assert "resuming: 6 of 8" in out and "2 runs in" in out
    assert kept.stat().st_mtime_ns == before
    assert_same_but_wall_times(by_jobs, by_cluster)


HIDE_PROJECT = """\
import sys


class NoProject:
    def find_spec(self, name, path=None, target=None):
        if name == "bbzide" or name.startswith("bbzide."):
            raise ModuleNotFoundError(f"No module named {name!r}", name=name)
        return None


sys.meta_path.insert(0, NoProject())
from distributed.cli.dask_worker import main

main()
"""


@pytest.fixture
def scheduler():
    """A scheduler on 127.0.0.1 without workers; its address."""
    from distributed import LocalCluster

    cluster = LocalCluster(n_workers=0, host="127.0.0.1", dashboard_address=None,
                           processes=True)
    yield cluster.scheduler_address
    cluster.close()


@pytest.fixture
def worker_without_project(scheduler, tmp_path):
    """A `dask worker` (no nanny: the hiding finder lives in its own process) joined to
    `scheduler` whose Python cannot import bbzide; the scheduler's address."""
    script = tmp_path / "worker_without_bbzide.py"
    script.write_text(HIDE_PROJECT)
    worker = subprocess.Popen(
        [sys.executable, str(script), scheduler, "--no-nanny", "--nthreads", "1",
         "--no-dashboard", "--host", "127.0.0.1"], cwd=tmp_path,
        stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    yield scheduler
    worker.terminate()
    worker.wait(timeout=60)


@pytest.mark.slow
def test_a_worker_without_the_project_is_a_clear_error_before_any_run(worker_without_project,
                                                                       tmp_path, capsys):
    out = tmp_path / "out"
    assert main([*SWEEP, "--cluster", worker_without_project, "--out", str(out)]) == 1
    err = capsys.readouterr().err
    assert "cannot import bbzide (No module named 'bbzide')" in err
    assert "install it from the lock file" in err
    assert "Traceback" not in err and "pickl" not in err.lower()
    assert len(err.strip().splitlines()) == 1
    assert list((out / "runs").iterdir()) == []


@pytest.mark.slow
def test_a_worker_that_joins_after_the_check_without_the_project_is_a_clear_error_too(
        worker_without_project, tmp_path, capsys, monkeypatch):
    # As if the worker had joined after the check: the check passes, the first task fails.
    monkeypatch.setattr(worker_check, "mismatch", lambda worker, here: None)
    out = tmp_path / "out"
    assert main([*SWEEP, "--cluster", worker_without_project, "--out", str(out)]) == 1
    err = capsys.readouterr().err.split("\r")[-1]   # after the progress bar's last redraw
    assert "a Dask worker could not load the task sar-d" in err
    assert "No module named 'bbzide'" in err and "install it from the lock file" in err
    assert "Traceback" not in err and "pickl" not in err.lower()


def test_a_worker_with_other_sources_or_pins_is_refused_with_what_differs():
    here = worker_check.probe()
    assert here["examples"] and "error" not in here and here["versions"]["numpy"]
    assert worker_check.mismatch(dict(here), here) is None
    other_pin = {**here, "versions": {**here["versions"], "numpy": "1.0.0"}}
    assert worker_check.mismatch(other_pin, here) == (
        f"it has numpy 1.0.0, this machine {here['versions']['numpy']}")
    assert "sources at" in worker_check.mismatch({**here, "sources": "0" * 64}, here)
    assert "Python 2.7" in worker_check.mismatch({**here, "python": "2.7"}, here)
    assert "no examples/ folder" in worker_check.mismatch({**here, "examples": False}, here)


def test_the_pins_come_from_the_checkout_not_from_a_stale_egg_info_in_the_working_folder(
        tmp_path, monkeypatch):
    """Started from a folder holding an older install's `bbzide.egg-info` (which Python finds
    before the venv's record), a client must compare the same pins as a worker started
    elsewhere: those of the checkout's pyproject.toml."""
    stale = tmp_path / "bbzide.egg-info"
    stale.mkdir()
    (stale / "PKG-INFO").write_text("Metadata-Version: 2.1\nName: bbzide\nVersion: 0.0.1\n")
    (stale / "requires.txt").write_text("numba==0.1\nnumpy==0.1\n")
    elsewhere = worker_check.probe()["versions"]
    monkeypatch.chdir(tmp_path)
    monkeypatch.syspath_prepend(str(tmp_path))
    import importlib.metadata
    assert "numba==0.1" in (importlib.metadata.requires("bbzide") or [])  # the stale record wins
    assert worker_check.probe()["versions"] == elsewhere
    assert "numba" not in elsewhere and "numpy" in elsewhere


def test_cluster_without_dask_installed_says_which_extra_to_install(tmp_path, capsys,
                                                                     monkeypatch):
    monkeypatch.setitem(sys.modules, "distributed", None)   # `import distributed` fails
    assert main([*SWEEP, "--cluster", "local", "--out", str(tmp_path / "out")]) == 1
    err = capsys.readouterr().err
    assert "--cluster needs Dask" in err and "'.[cluster]'" in err and "Traceback" not in err


@pytest.mark.slow
def test_workers_of_several_threads_get_a_note_and_still_run_every_task(capsys):
    from distributed import LocalCluster

    with LocalCluster(n_workers=1, threads_per_worker=2, processes=True, host="127.0.0.1",
                      dashboard_address=None) as cluster:
        with DaskExecutor(cluster.scheduler_address) as executor:
            items = list(range(6))
            squares = run_in_order(executor, _square, items, [f"square-{n}" for n in items])
        assert squares == [n * n for n in items]
        assert "(1 workers, 2 threads)" in executor.description
    err = capsys.readouterr().err
    assert "note: some Dask workers run 2 threads" in err and "--nthreads 1" in err


@pytest.mark.parametrize("address", ["", "foo:bar"])
def test_a_malformed_scheduler_address_is_a_clear_error(address, tmp_path, capsys):
    assert main([*SWEEP, "--cluster", address, "--out", str(tmp_path / "out")]) == 1
    err = capsys.readouterr().err
    assert "scheduler address (tcp://HOST:8786) or 'local'" in err and "Traceback" not in err


def _square(n: int) -> int:
    return n * n


@pytest.mark.parametrize("jobs", [1, 2])
def test_run_in_order_gives_every_result_in_the_items_order(jobs):
    items = list(range(12))
    with ProcessExecutor(jobs) as executor:
        assert run_in_order(executor, _square, items, [f"square-{n}" for n in items]) == [
            n * n for n in items]


@pytest.mark.slow
def test_a_crazyflie_experiment_prints_the_same_table_on_a_local_dask_cluster():
    def consensus(*options: str) -> str:
        done = subprocess.run(
            [sys.executable, "experiments/crazyflie_consensus.py", "4", *options], cwd=REPO,
            capture_output=True, text=True, timeout=600,
            env={**os.environ, "PYTHONPATH": str(REPO)})
        assert done.returncode == 0, done.stderr
        return done.stdout

    serial = consensus()
    assert "| chain | 2 |" in serial and "| circle | 2 |" in serial
    assert consensus("--cluster", "local", "--jobs", "2") == serial


def _slow_square(n: int) -> int:
    import time

    time.sleep(0.2 * n)   # later tasks still run when the cluster goes away
    return n * n


@pytest.mark.slow
def test_a_cluster_that_dies_mid_sweep_is_one_line_and_keeps_the_finished_tasks():
    from distributed import LocalCluster

    cluster = LocalCluster(n_workers=1, threads_per_worker=1, processes=True, host="127.0.0.1",
                           dashboard_address=None)
    finished = []
    with pytest.raises(UserError) as caught:
        with DaskExecutor(cluster.scheduler_address) as executor:
            items = list(range(8))
            for index, result in executor.map_unordered(_slow_square, items,
                                                        [f"slow-{n}" for n in items]):
                finished.append((index, result))
                if len(finished) == 1:
                    cluster.close()       # the scheduler and its worker stop here
    message = str(caught.value)
    assert message.startswith(f"lost the Dask scheduler at {cluster.scheduler_address} after 1 "
                              "of 8 tasks")
    assert "rerun the same command to resume" in message and "\n" not in message
    assert finished == [(0, 0)]


def test_an_unreachable_scheduler_is_one_line_for_the_sweep(tmp_path, capsys):
    address = f"tcp://127.0.0.1:{_closed_port()}"
    assert main([*SWEEP, "--cluster", address, "--out", str(tmp_path / "out")]) == 1
    err = capsys.readouterr().err
    assert err.startswith(f"error: cannot reach the Dask scheduler at {address}")
    assert "Connection refused" in err  # said at once, not after Dask's connect timeout
    assert len(err.strip().splitlines()) == 1 and "Traceback" not in err


@pytest.mark.slow
def test_an_unreachable_scheduler_is_one_line_for_the_experiment_scripts():
    address = f"tcp://127.0.0.1:{_closed_port()}"
    done = subprocess.run(
        [sys.executable, "experiments/crazyflie_packet_loss.py", "2", "--cluster", address],
        cwd=REPO, capture_output=True, text=True, timeout=600,
        env={**os.environ, "PYTHONPATH": str(REPO)})
    assert done.returncode == 1
    assert done.stderr.startswith(f"error: cannot reach the Dask scheduler at {address}")
    assert len(done.stderr.strip().splitlines()) == 1 and "Traceback" not in done.stderr


def _closed_port() -> int:
    """A port of 127.0.0.1 nothing listens on (bound, then released)."""
    import socket

    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        return probe.getsockname()[1]
