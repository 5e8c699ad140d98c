"""Editor markers for real Buzz syntax errors land where the reference `bzzparse` put them.

Every script of the conformance corpus's compiler/errors/ goes through ProgramSession with the
real compiler front end (`compile_to_basm`), as the editor's text would. For each `.err` that
names a position (`$DIR/NAME.bzz:LINE:COL: message`) the session's first marker must be at that
line and column with the same message; end-of-file errors (no position) must still give a
marker (the editor puts it on the last line). The assembler-only error (`asm_newline_escape`)
is caught after the front end, and the script that crashes the reference gives a clean error.
"""

from __future__ import annotations

import re
import shutil
from pathlib import Path

from corpus import COMPILER_ERRORS_DIR

from bbzide.compiler.frontend import compile_to_basm
from bbzide.ui.program_session import ProgramSession

POSITIONED = re.compile(r"^\$DIR/(?P<name>[^:]+\.bzz):(?P<line>\d+):(?P<col>\d+): (?P<msg>.*)$")


def front_end(text: str, path: Path) -> tuple[object, object]:
    result = compile_to_basm(path, source=text, reference_quirks=True)
    return result, result


def test_markers_match_the_reference_positions(tmp_path: Path, monkeypatch) -> None:
    monkeypatch.chdir(tmp_path)  # includes resolve against the working directory (notes §A.1)
    scripts = sorted(COMPILER_ERRORS_DIR.glob("*.bzz"))
    assert len(scripts) == 21
    positioned = eof = other = 0
    for script in scripts:
        target = tmp_path / script.name
        shutil.copyfile(script, target)
        session = ProgramSession(target, front_end)
        outcome = session.compile_now()
        expected = (COMPILER_ERRORS_DIR / f"{script.stem}.err").read_text().splitlines()
        rc = int((COMPILER_ERRORS_DIR / f"{script.stem}.rc").read_text())
        match = POSITIONED.match(expected[0]) if expected else None
        if match:
            assert not outcome.ok, script.name
            first = outcome.diagnostics[0]
            assert (first.line, first.col) == (int(match["line"]), int(match["col"])), script.name
            assert first.message.startswith(match["msg"]), script.name
            positioned += 1
        elif rc == 1 and expected and "end of file" in expected[0]:
            assert not outcome.ok and outcome.diagnostics, script.name
            eof += 1
        else:
            # asm_newline_escape (an assembler error: the front end succeeds with a warning)
            # and bare_identifier_at_eof (the reference crashes): no traceback, a clear result.
            assert outcome.ok or outcome.diagnostics[0].message, script.name
            other += 1
    print(
        f"compiler/errors: {positioned} markers at the reference line:col, {eof} end-of-file "
        f"errors marked, {other} others handled, of {len(scripts)}"
    )
    assert (positioned, eof, other) == (17, 2, 2)
