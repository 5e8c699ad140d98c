"""The program being edited: one `.bzz` file, its text, its last compile and its last good program.

`ProgramSession` is the single owner of the source text. Three things change it, and each ends in
the same place (`_accept_text` → compile):

* the browser editor (`edit_from_browser`): the text is saved to disk atomically (temp file in the
  same directory, fsync, `os.replace`) so an editor or a crash never sees half a file. The
  editor says which revision its text was based on; if the text changed since (another tab, or
  an external save, even one the file watcher has not delivered yet: the file is re-read
  first), nothing is written and `EditConflict` carries the newer text, so that newer text is
  never overwritten silently. (Between that re-read and the rename lie microseconds in which an
  external save could still be replaced: no file lock spans two programs on every system.)
* the file on disk (`reload_from_disk`, called by the file watcher): external editors' saves;
* the user asking for a compile (`compile_now`).

Every text change bumps `revision`; the diagnostics carry the revision they belong to, so the
browser never paints stale markers on new text. A successful compile hands the new program to
`on_program` (the run controller reloads every robot); a failed one keeps the old program running
and records the error with its `SourceLocation`.
"""

from __future__ import annotations

import os
import tempfile
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from bbzide.diagnostics import UserError

#: `compile_fn(text, path) -> (compiled_program, bittybuzz_program)`; raises `UserError` on bad
#: input.
CompileFunction = Callable[[str, Path], tuple[Any, Any]]


@dataclass(frozen=True)
class Diagnostic:
    """One marker for the editor: 1-based line, 0-based column (the SourceLocation convention)."""

    line: int
    col: int
    message: str
    severity: str = "error"  # "error" | "warning" | "runtime" (robots stopped there)
    robots: int = 0  # a runtime error: how many robots hit it

    def as_json(self) -> dict[str, Any]:
        return {
            "line": self.line,
            "col": self.col,
            "message": self.message,
            "severity": self.severity,
            "robots": self.robots,
        }


@dataclass
class CompileOutcome:
    """The result of compiling one revision of the text."""

    revision: int
    ok: bool
    diagnostics: list[Diagnostic]
    compiled: Any = None  # CompiledProgram (bo, bdb, basm, ...) when ok
    program: Any = None  # BittyBuzzProgram (bbo, debug_map, ...) when ok
    seconds: float = 0.0
    finished_at: float = field(default_factory=time.monotonic)


def diagnostics_from_error(error: UserError, path: Path) -> list[Diagnostic]:
    """A user error as editor markers; errors located in another (included) file go to line 1."""
    location = error.location
    if location is None:
        return [Diagnostic(1, 0, error.message)]
    if location.file and Path(location.file).name != path.name:
        return [Diagnostic(1, 0, f"{location}: {error.message}")]
    return [Diagnostic(location.line, location.col, error.message)]


def write_atomically(path: Path, text: str) -> None:
    """Replace `path` with `text` in one step: readers see the old file or the new, never half."""
    descriptor, temp_name = tempfile.mkstemp(
        prefix=f".{path.name}.", suffix=".tmp", dir=path.parent
    )
    try:
        with os.fdopen(descriptor, "w", encoding="utf-8", newline="") as handle:
            handle.write(text)
            handle.flush()
            os.fsync(handle.fileno())
        os.replace(temp_name, path)
    except BaseException:
        Path(temp_name).unlink(missing_ok=True)
        raise


class EditConflict(Exception):
    """A browser edit based on an older revision than the current text: nothing was saved."""

    def __init__(self, revision: int, text: str) -> None:
        super().__init__(f"the text changed since (now revision {revision})")
        self.revision = revision
        self.text = text


class ProgramSession:
    """Source text, revisions, compile results and the last good program of one `.bzz` file."""

    def __init__(
        self,
        path: Path,
        compile_fn: CompileFunction,
        on_program: Callable[[Any], None] | None = None,
        lint_fn: Callable[[str, Any], list[Diagnostic]] | None = None,
    ) -> None:
        self.path = path.resolve()
        self._compile_fn = compile_fn
        self._lint_fn = lint_fn
        self._on_program = on_program
        self._listeners: list[Callable[[CompileOutcome], None]] = []
        self._lock = threading.RLock()  # text, revision and outcome change together
        self._compile_lock = threading.Lock()  # one compile at a time
        self.text = self.path.read_text(encoding="utf-8")
        self._disk_text = self.text
        self.revision = 0
        self.outcome: CompileOutcome | None = None
        self.last_good: CompileOutcome | None = None
        self.compiling = False
        # errors of the running robots, for the revision of the program they run
        self._runtime: tuple[int, list[Diagnostic]] = (-1, [])

    # ---- observers -------------------------------------------------------------------------
    def add_listener(self, listener: Callable[[CompileOutcome], None]) -> None:
        """Call `listener(outcome)` after every compile (from the compiling thread)."""
        self._listeners.append(listener)

    def set_program_consumer(self, on_program: Callable[[Any], None]) -> None:
        self._on_program = on_program

    # ---- the three ways the text changes ---------------------------------------------------
    def edit_from_browser(self, text: str, base_revision: int | None = None) -> CompileOutcome:
        """The editor's new text: save it atomically (`save_from_browser`), then compile it
        (unless that revision is compiled already: the same text again reloads no robot)."""
        return self.ensure_compiled(self.save_from_browser(text, base_revision))

    def ensure_compiled(self, revision: int) -> CompileOutcome:
        """The outcome of `revision` (or a newer one), compiling only if there is none yet."""
        with self._lock:
            outcome = self.outcome
        if outcome is not None and outcome.revision >= revision:
            return outcome
        return self._compile(revision)

    def save_from_browser(self, text: str, base_revision: int | None = None) -> int:
        """Save the editor's text atomically; the revision that now holds it.

        With `base_revision` (the revision the editor's text started from), a text that changed
        since raises `EditConflict` instead of being overwritten; an external save not yet seen
        becomes a revision of its own first (and is compiled, as the file watcher would).
        """
        external: int | None = None
        with self._lock:
            disk = self._read_disk()
            if disk is not None and disk != self._disk_text:
                self._disk_text = disk
                if disk != self.text:
                    external = self._accept_text(disk)
            stale = base_revision is not None and base_revision != self.revision
            conflict = EditConflict(self.revision, self.text) if stale and text != self.text \
                else None
            if conflict is None and text != self.text:
                write_atomically(self.path, text)
                self._disk_text = text
                self._accept_text(text)
            revision = self.revision
        if external is not None:
            self._compile(external)
        if conflict is not None:
            raise conflict
        return revision

    def reload_from_disk(self) -> CompileOutcome | None:
        """Re-read the file after an external save; None if its text did not change.

        The file is read under the lock that a browser save writes under: a text read before
        such a save and compared after it would look like an external edit and bring the
        older text back (the file watcher's event for the editor's previous save, read just
        before its next one)."""
        with self._lock:
            text = self._read_disk()
            if text is None:
                return None  # mid-rename or unreadable: the next event will bring it
            if text == self._disk_text:
                return None
            self._disk_text = text
            if text == self.text:
                return None
            revision = self._accept_text(text)
        return self._compile(revision)

    def switch_file(self, path: Path) -> CompileOutcome:
        """Edit another file from now on (a lesson's work copy, a linked scenario's script):
        its text becomes a new revision, so every editor tab fetches it, and is compiled."""
        path = path.resolve()
        text = path.read_text(encoding="utf-8")
        with self._lock:
            self.path = path
            self._disk_text = text
            self._runtime = (-1, [])
            revision = self._accept_text(text)
        return self._compile(revision)

    def _read_disk(self) -> str | None:
        try:
            return self.path.read_text(encoding="utf-8")
        except (OSError, UnicodeDecodeError):
            return None

    def compile_now(self) -> CompileOutcome:
        with self._lock:
            revision = self.revision
        return self._compile(revision)

    def _accept_text(self, text: str) -> int:
        self.text = text
        self.revision += 1
        return self.revision

    # ---- compiling -------------------------------------------------------------------------
    def _compile(self, revision: int) -> CompileOutcome:
        with self._compile_lock:
            with self._lock:
                if revision != self.revision:  # a newer text arrived meanwhile
                    revision, text = self.revision, self.text
                else:
                    text = self.text
                self.compiling = True
            started = time.perf_counter()
            try:
                compiled, program = self._compile_fn(text, self.path)
                warnings = _warnings_of(compiled, program)
                if self._lint_fn is not None:
                    warnings += self._lint_fn(text, program)
                outcome = CompileOutcome(revision, True, warnings, compiled, program)
            except UserError as error:
                outcome = CompileOutcome(revision, False, diagnostics_from_error(error, self.path))
            except Exception as error:  # noqa: BLE001 - a compiler bug must not kill the IDE
                message = f"internal compiler error: {type(error).__name__}: {error}"
                outcome = CompileOutcome(revision, False, [Diagnostic(1, 0, message)])
            outcome.seconds = time.perf_counter() - started
            with self._lock:
                self.compiling = False
                if self.outcome is None or outcome.revision >= self.outcome.revision:
                    self.outcome = outcome
                    if outcome.ok:
                        self.last_good = outcome
        if outcome.ok and self._on_program is not None:
            self._on_program(outcome.program)
        for listener in self._listeners:
            listener(outcome)
        return outcome

    def set_runtime_errors(self, revision: int, errors: list[Diagnostic]) -> None:
        """The robots' runtime errors in this file, for the program of `revision` (the editor
        marks them only while it shows that revision: positions in other text would lie)."""
        with self._lock:
            self._runtime = (revision, list(errors))

    # ---- what the editor polls ---------------------------------------------------------------
    def state(self) -> dict[str, Any]:
        with self._lock:
            outcome = self.outcome
            status = "busy" if self.compiling else "idle"
            summary = ""
            if outcome is not None and not self.compiling:
                status = "ok" if outcome.ok else "error"
                if outcome.ok and outcome.program is not None:
                    summary = f"compiled: {len(outcome.program.bbo)} B .bbo"
            return {
                "revision": self.revision,
                "filename": self.path.name,
                "status": status,
                "summary": summary,
                "diagnostics_revision": outcome.revision if outcome else -1,
                "diagnostics": [d.as_json() for d in outcome.diagnostics] if outcome else [],
                "runtime_revision": self._runtime[0],
                "runtime": [d.as_json() for d in self._runtime[1]],
            }

    def source(self) -> dict[str, Any]:
        with self._lock:
            return {"revision": self.revision, "text": self.text}


#: bo2bbo's warning for an integer outside int16, which names a `.bo` offset: the editor's
#: pitfall check already marks the literal itself (`pitfalls.py`), so the IDE shows that one.
BO2BBO_INT16_WARNING = "out of 16 bit integer range"


def _warnings_of(compiled: Any, program: Any) -> list[Diagnostic]:
    """Compiler and bo2bbo warnings as line-1 markers (they carry no location in the contract),
    except bo2bbo's int16 warnings: one warning per problem, at the literal (pitfalls)."""
    messages = list(getattr(compiled, "warnings", []) or []) + [
        message for message in getattr(program, "warnings", []) or []
        if BO2BBO_INT16_WARNING not in str(message)
    ]
    return [Diagnostic(1, 0, str(message), "warning") for message in messages]
