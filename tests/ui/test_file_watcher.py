"""FileWatcher sees all three ways editors save (ui-stack-notes §5), once per save.

How quickly (issue #5: the IDE recompiles within ~0.5 s) is measured by benchmarks/editor_bench.py;
here a save only has to be noticed, once, within a bound that a loaded CI machine cannot miss.
"""

from __future__ import annotations

import threading
import time
from pathlib import Path

from editor_saves import SAVE_STYLES

from bbzide.ui.file_watcher import FileWatcher

#: Liveness, not speed: ~0.1 s on a quiet machine, and a save must not go unnoticed even when the
#: two cores are saturated (the figure against the 0.5 s goal is the benchmark's).
NOTICE_LIMIT_S = 10.0


def test_every_save_style_is_noticed_once(tmp_path: Path) -> None:
    path = tmp_path / "main.bzz"
    path.write_text("x = 0\n")
    (tmp_path / "other.bzz").write_text("")
    calls: list[float] = []
    changed = threading.Event()

    def on_change() -> None:
        calls.append(time.monotonic())
        changed.set()

    watcher = FileWatcher(path, on_change).start()
    try:
        time.sleep(0.2)
        for number, save in enumerate(SAVE_STYLES, start=1):
            changed.clear()
            saved_at = time.monotonic()
            save(path, f"x = {number}\n")
            assert changed.wait(NOTICE_LIMIT_S), f"{save.__name__} not noticed"
            print(f"{save.__name__}: noticed after {(calls[-1] - saved_at) * 1000:.0f} ms")
            time.sleep(0.3)  # the burst is over: no second call
            assert len(calls) == number, f"{save.__name__} gave {len(calls) - number + 1} calls"
        (tmp_path / "other.bzz").write_text("y = 1\n")  # another file: ignored
        time.sleep(0.3)
        assert len(calls) == 3
    finally:
        watcher.stop()
