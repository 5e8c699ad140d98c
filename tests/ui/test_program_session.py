"""ProgramSession: atomic saves, failed compiles keep the old program, disk reloads."""

from __future__ import annotations

import threading
from pathlib import Path

import pytest
from browser import wait_until
from doubles import FakeBackend

from bbzide.ui.program_session import EditConflict, ProgramSession, write_atomically

GOOD = "function step() {\n  x = 1\n}\n"
BAD = "function step() {\n  x = @@ 1\n}\n"


def make_session(tmp_path: Path) -> tuple[ProgramSession, list[object], Path]:
    path = tmp_path / "main.bzz"
    path.write_text(GOOD)
    backend = FakeBackend()
    loaded: list[object] = []
    session = ProgramSession(
        path, lambda text, p: backend.compile(text, p, "fake-table"), loaded.append
    )
    return session, loaded, path


def test_browser_edit_is_saved_atomically_and_compiled(tmp_path: Path) -> None:
    session, loaded, path = make_session(tmp_path)
    session.compile_now()
    outcome = session.edit_from_browser(GOOD + "# more\n")
    assert outcome.ok
    assert path.read_text() == GOOD + "# more\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["main.bzz"]  # no temp file left
    assert [p.text for p in loaded] == [GOOD, GOOD + "# more\n"]
    assert session.revision == 1


def test_failed_compile_keeps_last_good_program_and_reports_line_and_column(tmp_path: Path) -> None:
    session, loaded, path = make_session(tmp_path)
    session.compile_now()
    outcome = session.edit_from_browser(BAD)
    assert not outcome.ok
    assert [(d.line, d.col) for d in outcome.diagnostics] == [(2, 6)]
    assert session.last_good is not None and session.last_good.program.text == GOOD
    assert len(loaded) == 1  # the robots were not reloaded
    assert path.read_text() == BAD  # the user's text is never lost
    state = session.state()
    assert state["status"] == "error" and state["diagnostics_revision"] == state["revision"]


def test_own_saves_are_not_reloaded_but_external_ones_are(tmp_path: Path) -> None:
    session, loaded, path = make_session(tmp_path)
    session.compile_now()
    session.edit_from_browser(GOOD + "# a\n")
    assert session.reload_from_disk() is None  # the watcher sees our own save: ignored
    write_atomically(path, GOOD + "# b\n")
    outcome = session.reload_from_disk()
    assert outcome is not None and outcome.ok
    assert session.text == GOOD + "# b\n" and session.revision == 2
    assert session.reload_from_disk() is None  # same bytes again: nothing to do


def test_atomic_write_failure_leaves_the_old_file(tmp_path: Path) -> None:
    path = tmp_path / "main.bzz"
    path.write_text(GOOD)
    try:
        write_atomically(path, "\udcff")  # not encodable as UTF-8
    except UnicodeEncodeError:
        pass
    assert path.read_text() == GOOD
    assert sorted(p.name for p in tmp_path.iterdir()) == ["main.bzz"]


def test_an_edit_based_on_an_old_revision_never_overwrites_newer_text(tmp_path: Path) -> None:
    """A stale tab (based on revision 0) saves after another tab's save (revision 1)."""
    session, _, path = make_session(tmp_path)
    session.compile_now()
    session.edit_from_browser(GOOD + "# other tab\n", base_revision=0)
    with pytest.raises(EditConflict) as refused:
        session.edit_from_browser(GOOD + "# stale tab\n", base_revision=0)
    assert path.read_text() == GOOD + "# other tab\n"  # the newer text stays on disk
    assert (refused.value.revision, refused.value.text) == (1, GOOD + "# other tab\n")
    session.edit_from_browser(GOOD + "# stale tab\n", base_revision=1)  # "overwrite" chosen
    assert path.read_text() == GOOD + "# stale tab\n" and session.revision == 2


def test_an_external_save_the_watcher_has_not_delivered_yet_is_not_overwritten(
    tmp_path: Path,
) -> None:
    session, loaded, path = make_session(tmp_path)
    session.compile_now()
    write_atomically(path, GOOD + "# vim\n")  # no reload_from_disk: the watcher is late
    with pytest.raises(EditConflict) as refused:
        session.edit_from_browser(GOOD + "# browser\n", base_revision=0)
    assert path.read_text() == GOOD + "# vim\n"
    assert refused.value.text == GOOD + "# vim\n" and session.text == GOOD + "# vim\n"
    assert [p.text for p in loaded] == [GOOD, GOOD + "# vim\n"]  # the external text compiled
    assert session.reload_from_disk() is None  # the late watcher event finds nothing new


def test_an_edit_equal_to_the_newer_text_is_no_conflict(tmp_path: Path) -> None:
    session, loaded, path = make_session(tmp_path)
    session.compile_now()
    first = session.edit_from_browser(GOOD + "# same\n", base_revision=0)
    again = session.edit_from_browser(GOOD + "# same\n", base_revision=0)
    assert again is first and again.ok  # not compiled again: no robot reloaded for nothing
    assert session.revision == 1 and path.read_text() == GOOD + "# same\n"
    assert [p.text for p in loaded] == [GOOD, GOOD + "# same\n"]


class _ContendedLock:
    """A re-entrant lock that tells when a second thread has to wait for it."""

    def __init__(self) -> None:
        self._lock = threading.RLock()
        self.waited_for = threading.Event()

    def acquire(self, blocking: bool = True, timeout: float = -1) -> bool:
        if self._lock.acquire(blocking=False):
            return True
        self.waited_for.set()
        return self._lock.acquire(blocking, timeout)

    def release(self) -> None:
        self._lock.release()

    __enter__ = acquire

    def __exit__(self, *exc: object) -> None:
        self.release()


def test_a_browser_save_during_the_watchers_read_keeps_the_newer_text(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    # The watcher's event for the editor's save of A is read while the editor saves B: the
    # save waits for that read to be compared, so A never comes back as an "external" edit
    # (which would run A on the robots and refuse the editor's next save as a conflict).
    session, loaded, path = make_session(tmp_path)
    session.compile_now()
    first = GOOD + "# A\n"
    newer = GOOD + "# B\n"
    session.edit_from_browser(first, base_revision=0)
    lock = _ContendedLock()
    session._lock = lock  # type: ignore[assignment]
    read_disk = session._read_disk
    saved = threading.Event()
    saves: list[int] = []

    def save_newer() -> None:
        saves.append(session.save_from_browser(newer, base_revision=1))
        saved.set()

    def read_during_a_save() -> str | None:
        text = read_disk()
        monkeypatch.setattr(session, "_read_disk", read_disk)  # the save reads the disk too
        saver = threading.Thread(target=save_newer)
        saver.start()
        wait_until(lambda: lock.waited_for.is_set() or saved.is_set(), 30.0,
                   message="the save to wait for the lock or to be done")
        return text

    monkeypatch.setattr(session, "_read_disk", read_during_a_save)
    assert session.reload_from_disk() is None  # the editor's own save of A
    wait_until(saved.is_set, 30.0, message="the save of B")
    assert saves == [2]
    assert session.text == newer == path.read_text() and session.revision == 2
    assert session.save_from_browser(newer + "# C\n", base_revision=2) == 3  # no conflict
