"""The replay's debugger rows and Watches folder in headless Chromium, on a real Buzz recording:
Into steps a robot from the shown step and the Program tab marks its line; a watch draws its
chart of the recorded steps up to the shown one."""

from __future__ import annotations

from collections.abc import Iterator

import pytest
from browser import UI_WAIT_MS, UI_WAIT_S, chromium_context, free_port, open_app_page, wait_until

from bbzide.recording.reader import read_recording
from bbzide.recording.recorder import MissionRecorder
from bbzide.ui.replay_app import ReplayApp
from bbzide.ui.replay_session import ReplaySession
from bbzide.ui.watches import Watch
from bbzide.ui.world_adapter import WorldsBackend
from tests.debugger.swarms import ROBOTS, STEPPING_SCRIPT, TABLE

BACKEND = WorldsBackend()

RECORDED_STEPS = 6


@pytest.fixture(scope="module")
def replay(tmp_path_factory: pytest.TempPathFactory) -> Iterator[tuple[ReplayApp, object]]:
    folder = tmp_path_factory.mktemp("replay-debug")
    script = folder / "swarm.bzz"
    script.write_text(STEPPING_SCRIPT)
    _compiled, program = BACKEND.compile(STEPPING_SCRIPT, script, "kilobot")
    handle = BACKEND.create("kilobot", program, ROBOTS, 1, world_options=TABLE)
    with MissionRecorder(folder / "swarm.rrd", handle.sim, handle.recordable,
                         source_of=lambda _program: STEPPING_SCRIPT) as recorder:
        for _ in range(RECORDED_STEPS):
            handle.sim.step()
            recorder.record_step()
    app = ReplayApp(ReplaySession(read_recording(recorder.path)), port=free_port()).start()
    try:
        with chromium_context() as context:
            yield app, open_app_page(context, app)
    finally:
        app.stop()


def test_into_marks_the_paused_line_in_the_program_tab(replay: tuple) -> None:
    app, page = replay
    app.seek(2)
    page.get_by_role("button", name="Into", exact=True).click()
    page.get_by_role("tab", name="Program").click()
    marked = page.locator(".bbzide-paused-line")
    marked.wait_for(timeout=UI_WAIT_MS)
    # robot 0's first line of recorded step 3: the listener (it hears the others) or `step`
    assert marked.inner_text().split("│")[0].strip() in ("9", "13")
    assert app.debugger is not None and app.debugger.paused_at.robot == 0
    page.get_by_role("button", name="+1", exact=True).click()  # a seek ends the stepping
    wait_until(lambda: app.debugger is None, UI_WAIT_S, message="stepping ended")
    marked.wait_for(state="detached", timeout=UI_WAIT_MS)


def test_a_watch_draws_the_recorded_series(replay: tuple) -> None:
    app, page = replay
    app.seek(RECORDED_STEPS)
    page.get_by_text("Watches", exact=True).click()
    app.watches.what.value = "total"  # as typed in the folder's Watch field
    page.get_by_role("button", name="Add watch", exact=True).click()
    page.locator(".uplot").first.wait_for(timeout=UI_WAIT_MS)
    steps, table = app.watch_book.series(Watch("expression", "total"))
    assert steps.tolist() == list(range(app.session.first_step, RECORDED_STEPS + 1))
    assert table.shape == (len(steps), ROBOTS)
