"""The three ways editors save a file (measured with watchdog/inotify, ui-stack-notes §5).

Shared by the file-watcher test and benchmarks/editor_bench.py, so both exercise the same saves.
"""

from __future__ import annotations

import os
from pathlib import Path


def save_in_place(path: Path, text: str) -> None:
    """Truncate and write the same inode (nano, most IDEs by default)."""
    with open(path, "w") as handle:
        handle.write(text)


def save_atomically(path: Path, text: str) -> None:
    """Write a temp file beside it, then rename it over the file (VS Code, JetBrains, ours)."""
    temp = path.with_name(f".{path.name}.swp")
    temp.write_text(text)
    os.replace(temp, path)


def save_like_vim(path: Path, text: str) -> None:
    """Move the file away as a backup, write a new one, delete the backup (vim's default)."""
    backup = path.with_name(path.name + "~")
    os.replace(path, backup)
    path.write_text(text)
    backup.unlink()


SAVE_STYLES = (save_in_place, save_atomically, save_like_vim)
