"""Watches and the stigmergy view in a replay: read from the robots rebuilt at each recorded
step, they equal what the live IDE read after the same steps of the same run (real compiler,
VM, Kilobot world and recorder)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from bbzide.recording.reader import read_recording
from bbzide.ui.replay_session import ReplaySession
from bbzide.ui.watches import BadWatch, Watch, WatchBook
from bbzide.ui.world_adapter import WorldsBackend

BACKEND = WorldsBackend()

#: Robots write the stigmergy key `k` now and then (versions move between them by radio),
#: grow a table (the heap changes) and count by their id.
SCRIPT = """\
var s
var t = {}
var count = 0
function init() {
  s = stigmergy.create(1)
}
function step() {
  count = count + id
  if (count % 3 == 0) { s.put("k", count) }
  t[count % 7] = count
}
"""
STEPS = 14
ROBOTS = 5
WATCHES = (Watch("expression", "count"), Watch("expression", "count * 2 + size(t)"),
           Watch("stigmergy", "k"), Watch("heap", aggregate=True))


def same(a: list[float], b: list[float]) -> bool:
    return len(a) == len(b) and all(x == y or (math.isnan(x) and math.isnan(y))
                                    for x, y in zip(a, b, strict=True))


@pytest.fixture(scope="module")
def recorded(tmp_path_factory: pytest.TempPathFactory
             ) -> tuple[ReplaySession, WatchBook, dict[int, list]]:
    """A live run's watch book and stigmergy versions after every step, and its replay."""
    folder = tmp_path_factory.mktemp("replay-watches")
    script = folder / "stig.bzz"
    script.write_text(SCRIPT)
    _compiled, program = BACKEND.compile(SCRIPT, script, "kilobot")
    sim = BACKEND.create("kilobot", program, ROBOTS, 7)
    sim.source_text = SCRIPT
    sim.start_recording(folder / "stig.rrd")
    book = WatchBook()
    for watch in WATCHES:
        book.add(watch)
    versions = {}
    for _ in range(STEPS):
        sim.step()
        book.sample(sim.step_count, sim.watch_values)
        versions[sim.step_count] = sim.stigmergy_versions(64)
    path = sim.stop_recording()
    assert path is not None
    return ReplaySession(read_recording(path)), book, versions


def test_a_watch_series_in_replay_is_the_live_series(
        recorded: tuple[ReplaySession, WatchBook, dict[int, list]]) -> None:
    session, book, _versions = recorded
    assert session.last_step == STEPS
    for watch in WATCHES:
        steps, table = book.series(watch)
        assert steps.tolist() == list(range(1, STEPS + 1))
        assert not np.all(np.isnan(table))
        for row, step in enumerate(steps.astype(int)):
            assert same(session.watch_values(watch, int(step)), table[row].tolist()), \
                (watch, step)
    # the series the replay shows at step 9: the recorded steps up to it, as live at step 9
    assert list(session.watch_steps(9)) == list(range(session.first_step, 10))
    # read again (from the cache, after the rebuilder moved on): the same values
    _steps, table = book.series(WATCHES[0])
    assert same(session.watch_values(WATCHES[0], 3), table[2].tolist())


def test_the_stigmergy_view_in_replay_is_the_live_view(
        recorded: tuple[ReplaySession, WatchBook, dict[int, list]]) -> None:
    session, _book, versions = recorded
    assert any(len(rows) > 1 for rows in versions.values())  # the view has something to show
    for step in (STEPS, 5, 1, 11):  # out of order: rebuilt back and forth
        assert session.stigmergy_versions(step, 64) == versions[step], step


def test_a_bad_expression_is_said_in_one_line(
        recorded: tuple[ReplaySession, WatchBook, dict[int, list]]) -> None:
    session = recorded[0]
    with pytest.raises(BadWatch, match="count \\+"):
        session.watch_values(Watch("expression", "count +"), 3)
