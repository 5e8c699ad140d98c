"""`bbzide replay` in headless Chromium: the timeline moves the scene (toy firmware recording).

A swarm of `ToyRobot`s on the real engine and Kilobot table is recorded, opened in the replay
app, and driven like a user would: drag the step slider, press +1, play, jump to an event. The
step label in the page and the robot positions the scene sends to the browser follow the
recording (the same checks on a real Buzz recording are in tests/recording/test_real_vm.py).
"""

from __future__ import annotations

import re
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest
from browser import UI_WAIT_S, chromium_context, free_port, open_app_page, wait_until

from bbzide.recording.reader import read_recording
from bbzide.recording.rebuild import RobotRebuilder
from bbzide.recording.recorder import MissionRecorder
from bbzide.ui.replay_app import ReplayApp
from bbzide.ui.replay_session import JUMP_KINDS, ReplaySession
from tests.recording.doubles import ToyRobot
from tests.recording.test_recording import toy_swarm

STEPS = 150


def toy_replay_session(path: Path, steps: int) -> ReplaySession:
    """A replay of the toy swarm recorded for `steps` steps at `path` (rebuilt as ToyRobots)."""
    sim, recordable = toy_swarm()
    with MissionRecorder(path, sim, recordable) as recorder:
        for _ in range(steps):
            sim.step()
            recorder.record_step()
    recording = read_recording(path)
    return ReplaySession(recording, RobotRebuilder(recording, build=ToyRobot))


@pytest.fixture(scope="module")
def replay(tmp_path_factory: pytest.TempPathFactory) -> Iterator[tuple[ReplayApp, object]]:
    session = toy_replay_session(tmp_path_factory.mktemp("replay") / "toy.rrd", STEPS)
    app = ReplayApp(session, port=free_port()).start()
    try:
        with chromium_context() as context:
            page = open_app_page(context, app)
            page.context.foreign = context.foreign_requests  # type: ignore[attr-defined]
            yield app, page
    finally:
        app.stop()


def status_text(page: object) -> str:
    return page.locator("text=/of \\d+\\.\\.\\d+/").first.inner_text()  # type: ignore[attr-defined]


def player_idle(app: object) -> None:
    """Wait two turns of the replay's player thread: a paused player has then stopped."""
    turns = app.player_turns  # type: ignore[attr-defined]
    wait_until(lambda: app.player_turns >= turns + 2, UI_WAIT_S,  # type: ignore[attr-defined]
               message="two turns of the player")


def shown_step(page: object) -> int:
    text = status_text(page)
    match = re.search(r"step (\d+)", text)
    assert match, text
    return int(match.group(1))


def sent_positions(app: ReplayApp) -> np.ndarray:
    """The robot positions the scene last sent to the browsers (x, y)."""
    return np.asarray(app.scene._robots.batched_positions)[:, :2]  # type: ignore[union-attr]


def assert_scene_shows(app: ReplayApp, step: int) -> None:
    row = app.session.recording.row(step)
    expected = app.session.recording.positions[row, :, :2]
    np.testing.assert_allclose(sent_positions(app), expected, atol=1e-5)


def test_dragging_the_slider_moves_the_step_and_the_robots(replay: tuple) -> None:
    app, page = replay
    assert shown_step(page) == 0
    start = sent_positions(app).copy()
    thumb = page.get_by_role("slider").first.bounding_box()
    track = page.locator(".mantine-Slider-root").first.bounding_box()
    y = thumb["y"] + thumb["height"] / 2
    page.mouse.move(thumb["x"] + thumb["width"] / 2, y)
    page.mouse.down()
    for fraction in (0.2, 0.4, 0.6, 0.7):
        page.mouse.move(track["x"] + track["width"] * fraction, y, steps=4)
    page.mouse.up()
    wait_until(lambda: app.step > STEPS // 3, UI_WAIT_S, message="the slider to seek")
    wait_until(lambda: shown_step(page) == app.step, UI_WAIT_S, message="the step label to follow")
    assert_scene_shows(app, app.step)
    assert np.abs(sent_positions(app) - start).max() > 1e-3, "robots did not move"
    page.screenshot(path="/tmp/bbzide-ui-screenshots/replay_slider.png")
    assert page.context.foreign == []


def test_step_buttons_play_and_jumps(replay: tuple) -> None:
    app, page = replay
    app.seek(40)
    wait_until(lambda: shown_step(page) == 40, UI_WAIT_S, message="seek 40")
    page.get_by_role("button", name="+1").click()
    wait_until(lambda: shown_step(page) == 41, UI_WAIT_S, message="+1")
    assert_scene_shows(app, 41)
    page.get_by_role("button", name="−1").click()
    wait_until(lambda: shown_step(page) == 40, UI_WAIT_S, message="-1")
    page.get_by_role("combobox", name="Speed").click()
    page.get_by_role("option", name="16×").click()
    wait_until(lambda: app.speed == 16.0, UI_WAIT_S, message="speed 16x")
    page.get_by_role("button", name="▶ Play").click()
    wait_until(lambda: shown_step(page) > 60, UI_WAIT_S, message="playing")
    page.get_by_role("button", name="❚❚ Pause").click()
    wait_until(lambda: not app.playing, UI_WAIT_S, message="paused")
    player_idle(app)  # a seek in flight at the pause has landed
    paused = app.step
    player_idle(app)
    assert app.step == paused


def test_jump_to_the_robot_error(replay: tuple) -> None:
    app, page = replay
    app.seek(10)
    wait_until(lambda: shown_step(page) == 10, UI_WAIT_S, message="seek 10")
    errors = app.session.event_steps("error")
    assert len(errors) == 1
    kinds = [kind for kind, _ in app.session.jump_kinds()]
    assert kinds == ["error"]  # the toy run has no targets and no roles: those rows are hidden
    assert all(label not in page.locator("body").inner_text()
               for kind, label in JUMP_KINDS if kind != "error")
    page.get_by_role("button", name="next ▶").nth(kinds.index("error")).click()
    wait_until(lambda: shown_step(page) == errors[0], UI_WAIT_S, message="jump to the error")
    assert "1 in error" in page.locator("text=/of \\d+\\.\\.\\d+/").first.inner_text()
    page.get_by_role("button", name="◀ previous").nth(kinds.index("error")).click()
    wait_until(lambda: "no earlier robot error" in status_text(page), UI_WAIT_S,
               message="the status line to say there is no earlier error")
    assert app.step == errors[0]  # no earlier error: stays


def test_every_seek_shows_its_step_and_records_its_latency(replay: tuple) -> None:
    """How fast a seek is (the goal: well under a second) is record_bench's figure."""
    app, _ = replay
    for step in (5, 140, 77, 3, 149):
        app.seek(step)
        assert app.step == step and app.last_seek_seconds > 0
        assert_scene_shows(app, step)


def test_replay_command_rejects_foreign_files(tmp_path: Path) -> None:
    from bbzide.cli import main

    foreign = tmp_path / "x.rrd"
    foreign.write_text("hello")
    assert main(["replay", str(foreign), "--no-browser"]) == 1


def test_choosing_an_event_seeks_to_its_step(replay: tuple) -> None:
    app, page = replay
    app.seek(3)
    wait_until(lambda: shown_step(page) == 3, UI_WAIT_S, message="seek 3")
    [error_step] = app.session.event_steps("error")
    [(text, step)] = [(t, s) for t, s in app.session.event_choices() if s == error_step]
    page.get_by_role("tab", name="Mission").click()
    page.get_by_role("combobox", name="Go to event").click()
    page.get_by_role("option", name=text).click()
    wait_until(lambda: shown_step(page) == step, UI_WAIT_S, message="the event's step")
    assert_scene_shows(app, step)
    page.screenshot(path="/tmp/bbzide-ui-screenshots/replay_event_list.png")
