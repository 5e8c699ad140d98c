"""Breakpoints on the server: what the editor page may send, the lines that keep them across
recompiles (the ones with code in the new program), and the state every poll carries."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from bbzide.compiler import compile_source
from bbzide.ui.breakpoints import (
    MAX_BREAKPOINTS,
    BadBreakpoint,
    BreakpointBook,
    LineBreakpoint,
    code_lines,
    parse_breakpoints,
)
from bbzide.ui.editor_server import EditorSocket
from bbzide.ui.program_session import ProgramSession

SCRIPT = """\
# a comment
var x = 0

function step() {
  x = x + 1

  log(x)
}
"""


def program_of(text: str, path: Path) -> object:
    return compile_source(text, str(path)).to_bbo()


def test_the_page_list_is_read_one_per_line() -> None:
    items = parse_breakpoints([
        {"line": 5},
        {"line": 2, "condition": "  x > 3 ", "robot": 4, "hit_count": 2},
        {"line": 5, "condition": ""},
    ])
    assert items == [LineBreakpoint(2, "x > 3", 4, 2), LineBreakpoint(5)]
    assert items[0].describe() == "line 2 · robot 4 · when x > 3 · from hit 2"


@pytest.mark.parametrize("bad", [
    {"line": 0}, {"line": "3"}, {"line": True}, {}, {"line": 2, "robot": -1},
    {"line": 2, "hit_count": 0}, {"line": 2, "condition": 7}, "line 2",
])
def test_a_malformed_breakpoint_is_refused(bad: object) -> None:
    with pytest.raises(BadBreakpoint):
        parse_breakpoints([bad])


def test_too_many_breakpoints_are_refused() -> None:
    with pytest.raises(BadBreakpoint, match="at most"):
        parse_breakpoints([{"line": n} for n in range(1, MAX_BREAKPOINTS + 2)])


def test_code_lines_are_the_lines_instructions_map_to(tmp_path: Path) -> None:
    lines = code_lines(program_of(SCRIPT, tmp_path / "s.bzz"))
    assert {2, 5, 7} <= lines
    assert not {1, 6} & lines  # the comment and the blank line hold no code


def test_breakpoints_on_lines_without_code_go_at_the_recompile(tmp_path: Path) -> None:
    changes: list[list[LineBreakpoint]] = []
    book = BreakpointBook(on_change=changes.append)
    book.set(3, [LineBreakpoint(5), LineBreakpoint(7), LineBreakpoint(6)])
    assert [b.line for b in book.items] == [5, 6, 7]  # no program of revision 3 known yet
    book.program_compiled(3, program_of(SCRIPT, tmp_path / "s.bzz"))
    assert [b.line for b in book.items] == [5, 7]
    assert changes[-1] == book.items
    # the same lines sent for the next revision, whose program is known: filtered at once
    edited = SCRIPT.replace("  log(x)\n", "  # no log\n")
    book.program_compiled(4, program_of(edited, tmp_path / "s.bzz"))
    book.set(4, [LineBreakpoint(5), LineBreakpoint(7)])
    assert [b.line for b in book.items] == [5]
    # a list for an older revision arriving late changes nothing
    generation = book.generation
    book.set(3, [LineBreakpoint(2)])
    assert [b.line for b in book.items] == [5] and book.generation == generation


def test_the_socket_takes_breakpoints_and_every_state_carries_them(tmp_path: Path) -> None:
    path = tmp_path / "main.bzz"
    path.write_text(SCRIPT)
    session = ProgramSession(path, lambda text, p: (None, program_of(text, p)))
    book = BreakpointBook()
    session.add_listener(lambda outcome: book.program_compiled(outcome.revision,
                                                               outcome.program))
    session.compile_now()
    paused = {"line": 5, "robot": 2, "reason": "breakpoint", "revision": 0}
    socket = EditorSocket(session, lambda: "kilobot", book, lambda: paused)

    def ask(**request: object) -> dict[str, object]:
        return socket.answer(json.dumps({"id": 1, **request}))

    reply = ask(op="breakpoints", revision=0,
                breakpoints=[{"line": 5, "condition": "x > 2"}, {"line": 1}])
    assert reply["code"] == 200
    assert reply["breakpoints"] == [{"line": 5, "condition": "x > 2", "robot": None,
                                     "hit_count": None}]
    state = ask(op="state")
    assert state["breakpoints_revision"] == 0 and len(state["breakpoints"]) == 1
    assert state["paused"] == paused
    bad = ask(op="breakpoints", revision=0, breakpoints=[{"line": -2}])
    assert bad["code"] == 400 and "line" in bad["error"]
    assert ask(op="breakpoints", breakpoints=[])["code"] == 400  # no revision
    assert len(ask(op="state")["breakpoints"]) == 1  # refused messages changed nothing
