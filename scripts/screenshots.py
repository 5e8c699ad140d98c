"""`make screenshots`: the README's pictures of the IDE, taken in headless Chromium at 1400 x 900.

Design: each picture is one journey's moment, staged through the IDE's own objects (an
`IdeApp` on the real worlds, a tab opened by Playwright with the browser tests' helpers,
tests/ui/browser.py) and photographed as a user would see it. Nothing is drawn by hand, so the
pictures follow the code: run the script again after a UI change. Each shot waits for what it
shows (the compile, the runtime marker, the inspector) before the capture; software WebGL then
needs a moment to draw the last frame (`SETTLE_SECONDS`).

    .venv/bin/python scripts/screenshots.py [OUT_DIR [NAME ...]]   (default docs/screenshots;
                                                                   NAMEs: only those pictures;
                                                                   "lessons" = its four)
"""

from __future__ import annotations

import os
import shutil
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO / "tests" / "ui"))

from browser import (  # noqa: E402
    UI_WAIT_S,
    chromium_context,
    close_browsers,
    dismiss_software_gl_notice,
    free_port,
    open_app_page,
    wait_until,
)

from bbzide.lessons import catalog  # noqa: E402
from bbzide.ui.app import IdeApp  # noqa: E402
from bbzide.ui.breakpoints import LineBreakpoint  # noqa: E402
from bbzide.ui.run_controller import RunSettings  # noqa: E402
from bbzide.ui.teaching_panel import lesson_label  # noqa: E402
from bbzide.ui.watches import Watch  # noqa: E402
from bbzide.ui.world_adapter import WorldsBackend  # noqa: E402

#: The page size the README's pictures show: a 14-inch laptop's browser window.
PAGE = (1400, 900)
#: Seconds for software WebGL to draw the frame after the last change (first frames take 3-13 s
#: on two shared cores; later ones well under a second).
SETTLE_SECONDS = 2.0
#: Steps each world runs before its picture: the gradient has spread, the drones took off.
WARM_STEPS = 40

#: The student's first program: a call of a function that does not exist.
STUDENT_SCRIPT = """\
# My first Buzz program: every Kilobot shows its id's colour.
var colour = 0

function init() {
  colour = id % 7 + 1
}

function step() {
  led(colour)
  blink(colour)
}
"""


def _shoot(world: str, script: Path, out: Path, robots: int | None = None,
           stage: Callable[[IdeApp, object, object], None] | None = None) -> None:
    backend = WorldsBackend()
    settings = RunSettings(world, robots or backend.default_robots(world), 0, 0.0)
    app = IdeApp(script, backend, settings, port=free_port()).start(run=True)
    try:
        with chromium_context(*PAGE) as context:
            page = open_app_page(context, app)
            dismiss_software_gl_notice(page)  # it would cover the top of the 3D view
            # warm steps, or until a robot's error paused the run (Pause on error is on)
            wait_until(lambda: app.controller.status.step >= WARM_STEPS
                       or app.controller.status.paused_at is not None, UI_WAIT_S,
                       message=f"{WARM_STEPS} steps")
            client = next(iter(app.server.get_clients().values()))
            if stage is not None:
                stage(app, page, client)
            time.sleep(SETTLE_SECONDS)
            page.screenshot(path=str(out))  # type: ignore[attr-defined]
    finally:
        app.stop()
    print(out)


def _select_robot(index: int) -> Callable[[IdeApp, object, object], None]:
    def stage(app: IdeApp, page: object, client: object) -> None:
        app.controller.pause()
        app._select(client, index)  # noqa: SLF001 - what a click on the robot does
        inspector = app._inspectors[client.client_id]  # noqa: SLF001  # type: ignore[attr-defined]
        wait_until(lambda: inspector.selected == index, UI_WAIT_S, message="the inspector")
    return stage


def _pick_heap_object(name: str) -> Callable[[IdeApp, object, object], None]:
    """Robot 0 selected, then a click on the heap block of the global `name`'s object."""
    def stage(app: IdeApp, page: object, client: object) -> None:
        _select_robot(0)(app, page, client)
        with app.controller.locked() as sim:
            row = next(r for r in sim.inspect(0).objects if r.name == name)  # type: ignore[union-attr]
        block = page.locator(f'.heap-map rect[data-start="{row.offset}"]').first  # type: ignore[attr-defined]
        block.wait_for(timeout=UI_WAIT_S * 1000)
        block.click()
        picked = page.locator(".bbz-heap-pick")  # type: ignore[attr-defined]
        wait_until(lambda: picked.inner_text().startswith(f"#{row.index} "), UI_WAIT_S,
                   message="the picked object")
        picked.scroll_into_view_if_needed()
    return stage


def _show_robot_ids(app: IdeApp, page: object, client: object) -> None:
    _select_robot(0)(app, page, client)
    page.get_by_text("World setup").click()  # type: ignore[attr-defined]
    page.get_by_label("Robot ids").check()  # type: ignore[attr-defined]
    page.mouse.move(5, PAGE[1] - 5)  # type: ignore[attr-defined]  # the checkbox's hint off
    labels = app.world_setup.labels
    wait_until(lambda: len(labels._labels) > 0, UI_WAIT_S,  # noqa: SLF001
               message="the robot ids")
    page.get_by_text("Inspector").first.scroll_into_view_if_needed()  # type: ignore[attr-defined]


def _wait_for_runtime_marker(app: IdeApp, page: object, client: object) -> None:
    editor = page.frame_locator("iframe.bbzide-editor")  # type: ignore[attr-defined]
    editor.locator(".bbz-markers .runtime-line").wait_for(timeout=UI_WAIT_S * 1000)


def _lesson_shots(out_dir: Path, work: Path) -> None:
    """The Lessons menu open, lesson 2 checked before and after its solution, Save setup."""
    os.environ[catalog.HOME_VARIABLE] = str(work)
    script = work / "start.bzz"
    script.parent.mkdir(parents=True)
    script.write_text("function init() {\n}\nfunction step() {\n}\n")
    lesson = catalog.lesson(2)
    app = IdeApp(script, WorldsBackend(), RunSettings("kilobot", 4, 0, 30.0),
                 port=free_port()).start(run=True)
    teaching = app.teaching

    def shoot(page: object, name: str, show: str) -> None:
        page.get_by_text(show).first.scroll_into_view_if_needed()  # type: ignore[attr-defined]
        time.sleep(SETTLE_SECONDS)
        page.screenshot(path=str(out_dir / name))  # type: ignore[attr-defined]
        print(out_dir / name)

    try:
        with chromium_context(*PAGE) as context:
            page = open_app_page(context, app)
            dismiss_software_gl_notice(page)
            page.locator("input[value='(choose a lesson)']").first.click()  # type: ignore[attr-defined]
            option = page.get_by_role("option", name=lesson_label(lesson))  # type: ignore[attr-defined]
            option.wait_for()
            shoot(page, "lessons-menu.png", "Open lesson")
            option.click()
            page.get_by_role("button", name="Open lesson").click()  # type: ignore[attr-defined]
            wait_until(lambda: app.session.path == catalog.work_path(lesson).resolve(),
                       UI_WAIT_S, message="the lesson open")
            page.get_by_role("button", name="Check").click()  # type: ignore[attr-defined]
            page.get_by_text("FAIL").first.wait_for()  # type: ignore[attr-defined]
            shoot(page, "lesson-check-failed.png", "Reset lesson")
            app.session.edit_from_browser(lesson.solution.read_text())  # as a paste does
            page.get_by_role("button", name="Check").click()  # type: ignore[attr-defined]
            page.get_by_text("PASS").first.wait_for()  # type: ignore[attr-defined]
            shoot(page, "lesson-check-passed.png", "Reset lesson")
            teaching.save_path.value = "my-lesson-2.toml"
            teaching.pin.value = True
            page.get_by_role("button", name="Save setup").click()  # type: ignore[attr-defined]
            page.get_by_text("Saved").first.wait_for()  # type: ignore[attr-defined]
            shoot(page, "save-setup.png", "Saved")
    finally:
        app.stop()


#: The gradient example's line where the debugger picture stops: `gradient = heard + 1`, run
#: by a robot that heard a smaller gradient (the first steps of the spread).
GRADIENT_BREAK_LINE = 20


def _stop_at_breakpoint(app: IdeApp, page: object, client: object) -> None:
    """A breakpoint on the gradient's update (as a gutter click sets it); the run stops there;
    the panel scrolls to the inspector's Stack tab, which shows the robot's frames."""
    session = app.session
    app.controller.reset()  # the spread starts again: the line runs in its first steps
    app.controller.flush()
    app.breakpoints.set(session.revision, [LineBreakpoint(GRADIENT_BREAK_LINE)])
    wait_until(lambda: app.controller.status.paused_at is not None, UI_WAIT_S,
               message="the breakpoint's stop")
    paused = app.controller.status.paused_at
    inspector = app._inspectors[client.client_id]  # noqa: SLF001  # type: ignore[attr-defined]
    wait_until(lambda: "**Paused**" in inspector.stack.content, UI_WAIT_S,
               message="the frames in the Stack tab")
    editor = page.frame_locator("iframe.bbzide-editor")  # type: ignore[attr-defined]
    editor.locator(".cm-line.paused-line").wait_for(timeout=UI_WAIT_S * 1000)
    page.get_by_role("tab", name="Stack").click()  # type: ignore[attr-defined]
    page.get_by_role("button", name="Deselect").evaluate(  # type: ignore[attr-defined]
        "button => button.scrollIntoView({block: 'end'})")  # the frames, under the heap
    assert paused is not None


def _watch_the_gradient(app: IdeApp, page: object, client: object) -> None:
    """Two watches: every robot's `gradient`, and the swarm's heap in use (min, mean, max),
    over the first steps; the Watches folder open."""
    app.controller.reset()
    app.controller.flush()  # from step 0 on
    app.watches.add_watch(Watch("expression", "gradient"))
    app.watches.add_watch(Watch("heap", aggregate=True))
    wait_until(lambda: app.controller.status.step >= WARM_STEPS, UI_WAIT_S,
               message=f"{WARM_STEPS} watched steps")
    app.controller.pause()
    page.get_by_text("Watches", exact=True).click()  # type: ignore[attr-defined]
    wait_until(lambda: len(app.watches._charts) == 2, UI_WAIT_S,  # noqa: SLF001
               message="both charts")
    page.locator(".uplot").nth(1).wait_for()  # type: ignore[attr-defined]
    page.get_by_text("Watches", exact=True).evaluate(  # type: ignore[attr-defined]
        "header => header.scrollIntoView({block: 'start'})")


#: Steps of the recorded leader election the replay picture shows (the swarm agrees by then).
REPLAY_STEPS = 60


def _shoot_replay(scratch: Path, out: Path) -> None:
    """`bbzide replay` of a recorded leader election (examples/kilobot/leader.bzz, 9 Kilobots):
    a watch of every robot's `leader`, and the Stigmergy folder at the last step."""
    from bbzide.recording.reader import read_recording
    from bbzide.ui.replay_app import ReplayApp
    from bbzide.ui.replay_session import ReplaySession

    backend = WorldsBackend()
    script = scratch / "leader.bzz"
    script.parent.mkdir(parents=True, exist_ok=True)
    shutil.copy(REPO / "examples/kilobot/leader.bzz", script)
    text = script.read_text()
    _compiled, program = backend.compile(text, script, "kilobot")
    swarm = backend.create("kilobot", program, 9, 1)
    swarm.source_text = text
    swarm.start_recording(scratch / "leader.rrd")
    for _ in range(REPLAY_STEPS):
        swarm.step()
    path = swarm.stop_recording()
    app = ReplayApp(ReplaySession(read_recording(path)), port=free_port()).start()
    try:
        with chromium_context(*PAGE) as context:
            page = open_app_page(context, app)
            dismiss_software_gl_notice(page)
            app.watches.add_watch(Watch("expression", "leader"))
            app.seek(REPLAY_STEPS)
            page.get_by_text("Watches", exact=True).click()  # type: ignore[attr-defined]
            page.get_by_text("Stigmergy", exact=True).click()  # type: ignore[attr-defined]
            wait_until(lambda: len(app.watches._charts) == 1, UI_WAIT_S,  # noqa: SLF001
                       message="the chart")
            page.locator(".uplot").first.wait_for()  # type: ignore[attr-defined]
            page.get_by_text("Watches", exact=True).evaluate(  # type: ignore[attr-defined]
                "header => header.scrollIntoView({block: 'start'})")
            time.sleep(SETTLE_SECONDS)
            page.screenshot(path=str(out))  # type: ignore[attr-defined]
    finally:
        app.stop()
    print(out)


def main(out_dir: Path, only: set[str]) -> None:
    out_dir.mkdir(parents=True, exist_ok=True)

    def wanted(name: str) -> bool:
        return not only or name in only

    with tempfile.TemporaryDirectory() as folder:
        scratch = Path(folder)
        for world, example, stage in (
                ("kilobot", "examples/kilobot/gradient.bzz", _show_robot_ids),
                ("crazyflie", "examples/crazyflie/consensus.bzz", _select_robot(0)),
                ("m300", "examples/m300/flocking.bzz", _pick_heap_object("nbx"))):
            if not wanted(f"ide-{world}"):
                continue
            script = scratch / world / Path(example).name
            script.parent.mkdir()
            shutil.copy(REPO / example, script)
            _shoot(world, script, out_dir / f"ide-{world}.png", stage=stage)
        if wanted("student-runtime-error"):
            student = scratch / "student" / "first.bzz"
            student.parent.mkdir()
            student.write_text(STUDENT_SCRIPT)
            _shoot("kilobot", student, out_dir / "student-runtime-error.png", robots=9,
                   stage=_wait_for_runtime_marker)
        if wanted("lessons"):
            _lesson_shots(out_dir, scratch / "lessons")
        for name, stage in (("debugger-paused", _stop_at_breakpoint),
                            ("debugger-watches", _watch_the_gradient)):
            if not wanted(name):
                continue
            script = scratch / name / "gradient.bzz"
            script.parent.mkdir()
            shutil.copy(REPO / "examples/kilobot/gradient.bzz", script)
            _shoot("kilobot", script, out_dir / f"{name}.png", robots=9, stage=stage)
        if wanted("replay-watches"):
            _shoot_replay(scratch / "replay", out_dir / "replay-watches.png")


if __name__ == "__main__":
    try:
        main(Path(sys.argv[1]) if len(sys.argv) > 1 else REPO / "docs" / "screenshots",
             set(sys.argv[2:]))
    finally:
        close_browsers()
