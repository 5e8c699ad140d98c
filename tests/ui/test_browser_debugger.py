"""The debugger in headless Chromium on the real compiler, VM, debugger and Kilobot world.

A click in the editor's breakpoint gutter pauses the swarm at that line: the editor marks the
line, the tab's inspector selects the robot that stopped, the Build listing marks its pc. The
breakpoint's form narrows it to one robot; the Debug folder's buttons then step that robot
into, over and out of a function and through a listener lambda, each move seen in the editor;
a step back returns to the previous line with the robot's state byte for byte as it was there.
"""

from __future__ import annotations

from collections.abc import Iterator

import pytest
from browser import UI_WAIT_MS, UI_WAIT_S, wait_until
from ide_harness import IdeSession, running_ide

from bbzide.ui.world_adapter import WorldsBackend

BACKEND = WorldsBackend()

ROBOTS = 4
SCRIPT = """\
var heard = 255
function bump(v) {
  var y = v * 2
  return y + 1
}
function init() {
  neighbors.listen("g", function(vid, value, rid) {
    heard = bump(value)
  })
}
function step() {
  neighbors.broadcast("g", id)
  var x = bump(id)
  led(x % 7 + 1)
}
"""
BREAK_LINE = 13
#: The line of the editor that carries the paused band (None when there is none).
PAUSED_LINE_JS = """() => {
  const el = document.querySelector('.cm-line.paused-line');
  if (!el) return null;
  const view = window.buzzEditor.view;
  return view.state.doc.lineAt(view.posAtDOM(el)).number;
}"""


@pytest.fixture(scope="module")
def ide(tmp_path_factory: pytest.TempPathFactory) -> Iterator[IdeSession]:
    script = tmp_path_factory.mktemp("debugger") / "bump.bzz"
    script.write_text(SCRIPT)
    with running_ide(script, BACKEND, "kilobot", ROBOTS) as session:
        yield session


def paused_line(ide: IdeSession) -> int | None:
    return ide.editor.locator("#source").evaluate(PAUSED_LINE_JS)  # type: ignore[no-any-return]


def wait_for_line(ide: IdeSession, line: int, what: str) -> None:
    wait_until(lambda: paused_line(ide) == line, UI_WAIT_S,
               message=f"{what}: the editor's paused band on line {line}")


def robot_state(ide: IdeSession, robot_id: int) -> bytes:
    with ide.app.controller.locked() as sim:
        state = sim.sim.state_of(robot_id)  # type: ignore[union-attr]
        return state.robot.comparable(state.robot.snapshot())  # type: ignore[no-any-return]


def click_debug(ide: IdeSession, label: str, line: int) -> None:
    """Click a Debug button and wait for the stop it makes, shown on `line` in the editor."""
    stops = ide.app.controller.status.stops
    ide.page.get_by_role("button", name=label, exact=True).click()  # type: ignore[attr-defined]
    wait_until(lambda: ide.app.controller.status.stops > stops, UI_WAIT_S,
               message=f"the stop after {label}")
    wait_for_line(ide, line, label)


def test_a_gutter_click_pauses_the_swarm_at_that_line(ide: IdeSession) -> None:
    app = ide.app
    gutter = ide.editor.locator(".bbz-breakpoints .cm-gutterElement")
    gutter.nth(BREAK_LINE).click()  # the first element is the gutter's spacer
    ide.editor.locator(".bbz-breakpoints .breakpoint").wait_for(timeout=UI_WAIT_MS)
    wait_until(lambda: app.controller.status.paused_at is not None, UI_WAIT_S,
               message="the breakpoint's stop")
    paused = app.controller.status.paused_at
    assert paused is not None and (paused.line, paused.reason) == (BREAK_LINE, "breakpoint")
    assert paused.robot_index == 0  # the first robot to run the line this step
    wait_for_line(ide, BREAK_LINE, "the hit")
    client = next(iter(app.server.get_clients().values()))
    inspector = app._inspectors[client.client_id]  # noqa: SLF001
    wait_until(lambda: inspector.selected == paused.robot_index, UI_WAIT_S,
               message="the stopped robot selected")
    wait_until(lambda: f"**Robot {paused.robot_id}**" in inspector.header.content, UI_WAIT_S,
               message="its inspector")
    wait_until(lambda: "**Paused** (breakpoint)" in inspector.stack.content, UI_WAIT_S,
               message="its frames in the Stack tab")
    assert "**#0 `step`**" in inspector.stack.content
    wait_until(lambda: f'data-pc="{paused.pc}" class="current-pc"' in app.listing.content,
               UI_WAIT_S, message="the pc marked in the Build listing")
    wait_until(lambda: f"robot **{paused.robot_id}**" in app.debug.where.content, UI_WAIT_S,
               message="the Debug folder naming the robot")
    ide.screenshot("debugger_breakpoint_hit")


def test_stepping_one_robot_through_a_function_and_a_listener(ide: IdeSession) -> None:
    app = ide.app
    last = ROBOTS - 1
    gutter = ide.editor.locator(".bbz-breakpoints .cm-gutterElement")
    gutter.nth(BREAK_LINE).click(button="right")
    form = ide.editor.locator("#breakpoint-form")
    form.wait_for(timeout=UI_WAIT_MS)
    form.locator("#bp-robot").fill(str(last))
    form.locator("#bp-save").click()
    wait_until(lambda: [b.robot for b in app.breakpoints.items] == [last], UI_WAIT_S,
               message="the breakpoint for one robot")
    ide.editor.locator(".breakpoint-conditional").wait_for(timeout=UI_WAIT_MS)
    stops = app.controller.status.stops
    ide.page.get_by_role("button", name="Continue", exact=True).click()
    wait_until(lambda: app.controller.status.stops > stops, UI_WAIT_S, message="the hit")
    paused = app.controller.status.paused_at
    assert paused is not None and (paused.robot_id, paused.line) == (last, BREAK_LINE)
    client = next(iter(app.server.get_clients().values()))
    inspector = app._inspectors[client.client_id]  # noqa: SLF001
    wait_until(lambda: inspector.selected == paused.robot_index, UI_WAIT_S,
               message="the stopped robot selected: the one the buttons step")
    click_debug(ide, "Into", 3)          # into bump(id)
    click_debug(ide, "Over", 4)
    click_debug(ide, "Out", BREAK_LINE + 1)  # back in step, after the call
    click_debug(ide, "Over", 8)          # the end of step: next, the listener lambda
    paused = app.controller.status.paused_at
    assert paused is not None and paused.frames[0].function == "lambda at line 7"
    assert paused.robot_id == last and paused.frames[0].locals["vid"] == '"g"'
    in_lambda = robot_state(ide, last)
    click_debug(ide, "Into", 3)          # into bump(value), called from the lambda
    assert [f.function for f in app.controller.status.paused_at.frames] == [  # type: ignore
        "bump", "lambda at line 7"]
    click_debug(ide, "Line", 8)          # step back: the lambda's line again
    assert robot_state(ide, last) == in_lambda  # heap, stack and pc as they were there
    ide.screenshot("debugger_stepped_back")
