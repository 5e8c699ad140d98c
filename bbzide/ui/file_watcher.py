"""Notices when another program saves the `.bzz` file, and says so once per save.

Editors save in three ways (measured with watchdog 7.1 / inotify, ui-stack-notes §5): in place
(`modified`, `closed`), atomically (`created`/`closed` on a temp file then `moved` onto ours:
no `modified` event for our path at all) and vim-style (our file moved away, a new one
`created`). So we watch the *directory* and react to any event whose source or destination is
our path, then wait `DEBOUNCE_SECONDS` for the burst to end before calling back once. The
callback re-reads the file and compares it with what it knows (our own atomic saves come back
here too and are ignored there).
"""

from __future__ import annotations

import os
import threading
from collections.abc import Callable
from pathlib import Path

from watchdog.events import FileSystemEvent, FileSystemEventHandler
from watchdog.observers import Observer

#: One save is a burst of 2-5 events within ~2 ms; 100 ms ends the burst with margin and keeps
#: save -> reload near 0.1 s (the requirement is ~0.5 s).
DEBOUNCE_SECONDS = 0.1


class FileWatcher(FileSystemEventHandler):
    """Calls `on_change()` (from a timer thread) after each burst of events touching `path`."""

    def __init__(self, path: Path, on_change: Callable[[], None]) -> None:
        super().__init__()
        self.path = os.fsdecode(path.resolve())
        self._on_change = on_change
        self._timer: threading.Timer | None = None
        self._timer_lock = threading.Lock()
        self._observer = Observer()
        self._observer.schedule(self, os.path.dirname(self.path), recursive=False)

    def start(self) -> FileWatcher:
        self._observer.start()
        return self

    def stop(self) -> None:
        self._observer.stop()
        self._observer.join(timeout=5)
        with self._timer_lock:
            if self._timer is not None:
                self._timer.cancel()

    def wait_quiet(self, timeout: float | None = None) -> bool:
        """Wait until the callback of the burst in progress (if any) has run; False when
        `timeout` passed first. Events that arrive meanwhile restart the burst and are waited
        for too."""
        while True:
            with self._timer_lock:
                timer = self._timer
            if timer is None:
                return True
            timer.join(timeout)
            if timer.is_alive():
                return False
            with self._timer_lock:
                if self._timer is timer:
                    return True

    def on_any_event(self, event: FileSystemEvent) -> None:
        if event.event_type == "opened":
            return
        touched = {os.fsdecode(event.src_path), os.fsdecode(getattr(event, "dest_path", "") or "")}
        if self.path in touched:
            self._restart_timer()

    def _restart_timer(self) -> None:
        with self._timer_lock:
            if self._timer is not None:
                self._timer.cancel()
            self._timer = threading.Timer(DEBOUNCE_SECONDS, self._on_change)
            self._timer.daemon = True
            self._timer.start()
