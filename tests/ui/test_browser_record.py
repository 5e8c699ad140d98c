"""Record in headless Chromium: ticking it moves nothing under the mouse, and the file's path
stays on screen after the recording stops (to replay it)."""

from __future__ import annotations

import shutil
from collections.abc import Iterator
from pathlib import Path

import pytest
from browser import UI_WAIT_S, set_checkbox, wait_until
from ide_harness import IdeSession, running_ide

from bbzide.ui.world_adapter import WorldsBackend

BACKEND = WorldsBackend()

REPO = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def ide(tmp_path_factory: pytest.TempPathFactory) -> Iterator[IdeSession]:
    script = tmp_path_factory.mktemp("record") / "gradient.bzz"
    shutil.copy(REPO / "examples" / "kilobot" / "gradient.bzz", script)
    with running_ide(script, BACKEND, "kilobot", 9) as session:
        yield session


def test_record_moves_nothing_and_its_path_stays(ide: IdeSession) -> None:
    app, page = ide.app, ide.page
    record = page.get_by_label("Record")  # type: ignore[attr-defined]
    below = page.get_by_label("Keep world on reload")  # type: ignore[attr-defined]
    before = (record.bounding_box()["y"], below.bounding_box()["y"])
    set_checkbox(record, True)
    wait_until(lambda: app.controller.status.recording is not None, UI_WAIT_S,
               message="the recording")
    name = Path(app.controller.status.recording).name
    note = page.locator(".bbz-recording-note")  # type: ignore[attr-defined]
    wait_until(lambda: " ".join(note.inner_text().split()) ==
               f"● recording to recordings/{name}", UI_WAIT_S, message="the note")
    assert (record.bounding_box()["y"], below.bounding_box()["y"]) == before
    ide.screenshot("record-on")
    set_checkbox(record, False)
    wait_until(lambda: app.controller.status.recording is None, UI_WAIT_S, message="the stop")
    wait_until(lambda: " ".join(note.inner_text().split()) ==
               f"last recording: recordings/{name}", UI_WAIT_S, message="the path kept")
    assert (record.bounding_box()["y"], below.bounding_box()["y"]) == before
    assert (Path(app.session.path).parent / "recordings" / name).is_file()
