"""`scripts/warm_kernels.py` leaves one kernel cache (the folders of earlier kernel sources go),
its extra runs reach the kernels the world examples do not (the neighbour walks' and a
replay's receive), and a robot that fails in it (a kernel numba did not compile) stops it."""

from __future__ import annotations

import importlib.util
from collections import Counter
from pathlib import Path

import pytest

from bbzide.vm.compiled import fasthost, fastreceive

REPO = Path(__file__).resolve().parents[1]


def _warm_kernels() -> object:
    spec = importlib.util.spec_from_file_location("warm_kernels", REPO / "scripts/warm_kernels.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_only_the_current_sources_cache_stays(tmp_path: Path) -> None:
    current = tmp_path / "kernels-0123456789abcdef"
    for folder in (current, tmp_path / "kernels-old1", tmp_path / "kernels-old2"):
        (folder / "compiled").mkdir(parents=True)
        (folder / "compiled" / "fastloop.run-1.py311.nbi").write_bytes(b"index")
    (tmp_path / "fastgc.cpython-311.pyc").write_bytes(b"bytecode")

    removed = _warm_kernels().remove_stale_caches(current)  # type: ignore[attr-defined]

    assert sorted(folder.name for folder in removed) == ["kernels-old1", "kernels-old2"]
    assert sorted(path.name for path in tmp_path.iterdir()) == [
        "fastgc.cpython-311.pyc", "kernels-0123456789abcdef"]
    assert (current / "compiled" / "fastloop.run-1.py311.nbi").read_bytes() == b"index"


def _counting(monkeypatch: pytest.MonkeyPatch, module: object, names: list[str]) -> Counter:
    calls: Counter = Counter()
    for name in names:
        kernel = getattr(module, name)

        def counted(*args: object, _kernel: object = kernel, _name: str = name) -> object:
            calls[_name] += 1
            return _kernel(*args)  # type: ignore[operator]

        monkeypatch.setattr(module, name, counted)
    return calls


def test_the_walking_script_runs_the_walk_kernels(monkeypatch: pytest.MonkeyPatch,
                                                  tmp_path: Path) -> None:
    calls = _counting(monkeypatch, fasthost, ["xtreme_walk", "add_functions"])
    _warm_kernels().walk_neighbours(tmp_path)  # type: ignore[attr-defined]
    assert calls["xtreme_walk"] > 0 and calls["add_functions"] > 0, calls


def test_the_rebuilt_recording_receives_through_the_kernel(monkeypatch: pytest.MonkeyPatch,
                                                           tmp_path: Path) -> None:
    calls = _counting(monkeypatch, fastreceive, ["receive_all"])
    _warm_kernels().record_and_rebuild(tmp_path)  # type: ignore[attr-defined]
    assert calls["receive_all"] > 0, calls


def test_a_robot_failing_in_the_warm_up_stops_it_with_the_reason(tmp_path: Path) -> None:
    script = tmp_path / "fails.bzz"
    script.write_text("function init() {}\nfunction step() { x = 1 / 0 }\n")
    with pytest.raises(SystemExit, match=r"robot 0 of fails.bzz failed: [A-Z]+"):
        _warm_kernels().run_briefly("kilobot", script)  # type: ignore[attr-defined]
