"""FileWatcher sees all three ways editors save (ui-stack-notes §5), once per save, quickly."""

from __future__ import annotations

import os
import threading
import time
from pathlib import Path

from bbzide.ui.file_watcher import FileWatcher


def save_in_place(path: Path, text: str) -> None:
    with open(path, "w") as handle:
        handle.write(text)


def save_atomically(path: Path, text: str) -> None:
    temp = path.with_name(".main.bzz.swp")
    temp.write_text(text)
    os.replace(temp, path)


def save_like_vim(path: Path, text: str) -> None:
    backup = path.with_name(path.name + "~")
    os.replace(path, backup)
    path.write_text(text)
    backup.unlink()


def test_every_save_style_is_noticed_once_within_half_a_second(tmp_path: Path) -> None:
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
        for number, save in enumerate([save_in_place, save_atomically, save_like_vim], start=1):
            changed.clear()
            saved_at = time.monotonic()
            save(path, f"x = {number}\n")
            assert changed.wait(2.0), f"{save.__name__} not noticed"
            latency = calls[-1] - saved_at
            print(f"{save.__name__}: noticed after {latency * 1000:.0f} ms")
            assert latency < 0.5
            time.sleep(0.3)  # the burst is over: no second call
            assert len(calls) == number, f"{save.__name__} gave {len(calls) - number + 1} calls"
        (tmp_path / "other.bzz").write_text("y = 1\n")  # another file: ignored
        time.sleep(0.3)
        assert len(calls) == 3
    finally:
        watcher.stop()
