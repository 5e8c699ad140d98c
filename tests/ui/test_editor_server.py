"""The editor's server side: the reference it hands the page (completion and hover), the world
in every state, the reference page's Markdown, and a clear page when the bundle is not built."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from doubles import FakeBackend

from bbzide.ui import editor_server
from bbzide.ui.editor_server import (
    BUNDLE_MISSING,
    EDITOR_PATH,
    REFERENCE_PATH,
    EditorSocket,
    bundle_pages,
    editor_routes,
)
from bbzide.ui.program_session import ProgramSession
from bbzide.worlds.reference import HOST_FUNCTIONS

REPO = Path(__file__).resolve().parents[2]


def make_session(tmp_path: Path) -> ProgramSession:
    path = tmp_path / "main.bzz"
    path.write_text("function step() {\n  x = 1\n}\n")
    backend = FakeBackend()
    return ProgramSession(path, lambda text, p: backend.compile(text, p, "fake-table"))


def ask(socket: EditorSocket, **request: object) -> dict[str, object]:
    return socket.answer(json.dumps({"id": 7, **request}))


def test_the_reference_follows_the_world_the_program_runs_in(tmp_path: Path) -> None:
    world = ["kilobot"]
    socket = EditorSocket(make_session(tmp_path), lambda: world[0])
    assert ask(socket, op="state")["world"] == "kilobot"
    reply = ask(socket, op="reference")
    assert reply["code"] == 200 and reply["id"] == 7 and reply["world"] == "kilobot"
    by_name = {item["name"]: item for item in reply["items"]}  # type: ignore[union-attr]
    motion = next(e for e in HOST_FUNCTIONS["kilobot"] if e.name == "motion")
    assert by_name["motion"]["signature"] == motion.signature
    assert by_name["motion"]["doc"] == motion.doc
    assert by_name["neighbors.broadcast"]["memory"]  # a built-in with its memory cost
    assert "takeoff" not in by_name
    world[0] = "crazyflie"
    assert ask(socket, op="compile")["world"] == "crazyflie"
    names = {item["name"] for item in ask(socket, op="reference")["items"]}  # type: ignore[union-attr]
    assert {"takeoff", "goTo"} <= names and "motion" not in names


def test_an_unknown_op_lists_the_ones_there_are(tmp_path: Path) -> None:
    reply = ask(EditorSocket(make_session(tmp_path)), op="teleport")
    assert reply["code"] == 400 and "reference" in str(reply["error"])


def test_the_reference_page_is_the_repositorys_reference(tmp_path: Path) -> None:
    pages = editor_routes(make_session(tmp_path)).pages
    markdown = pages[REFERENCE_PATH + ".md"]
    assert markdown.body.decode() == (REPO / "docs/buzz-reference.md").read_text()
    assert b"dist/reference.js" in pages[REFERENCE_PATH].body
    assert b"dist/editor.js" in pages[EDITOR_PATH].body


def test_a_missing_bundle_says_how_to_build_it(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                               capsys: pytest.CaptureFixture[str]) -> None:
    monkeypatch.setattr(editor_server, "BUNDLE_DIR", tmp_path / "not-built")
    pages = bundle_pages()
    script = pages[EDITOR_PATH + "dist/editor.js"].body.decode()
    assert "make setup" in script and script.startswith("document.body.textContent")
    assert capsys.readouterr().err.strip() == BUNDLE_MISSING
