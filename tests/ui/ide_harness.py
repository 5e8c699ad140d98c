"""Start an IdeApp and a headless Chromium tab on it; shut both down however a test ends."""

from __future__ import annotations

import contextlib
import math
import os
import re
import time
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from browser import (
    UI_WAIT_S,
    chromium_context,
    free_port,
    open_app_page,
    render_barrier,
    wait_until,
)

from bbzide.ui.app import IdeApp
from bbzide.ui.run_controller import RunSettings
from bbzide.ui.scene import BODY_HEIGHT_RADII
from bbzide.ui.world_backend import WorldBackend

#: Screenshots land here so a person (or the report) can look at what a user sees.
SCREENSHOT_DIR = Path(os.environ.get("BBZIDE_SCREENSHOTS", "/tmp/bbzide-ui-screenshots"))


@dataclass
class IdeSession:
    app: IdeApp
    context: object
    page: object

    @property
    def editor(self) -> object:
        return self.page.frame_locator("iframe.bbzide-editor")  # type: ignore[attr-defined]

    def screenshot(self, name: str) -> Path:
        SCREENSHOT_DIR.mkdir(parents=True, exist_ok=True)
        path = SCREENSHOT_DIR / f"{name}.png"
        self.page.screenshot(path=str(path))  # type: ignore[attr-defined]
        return path

    def status_text(self) -> str:
        return self.page.locator("text=/steps\\/s/").first.inner_text()  # type: ignore[attr-defined]

    def shown_step(self) -> int:
        match = re.search(r"step (\d+)", self.status_text())
        assert match, self.status_text()
        return int(match.group(1))

    def settled(self, typed_end: str) -> None:
        """Wait until the text ending in `typed_end` (trailing whitespace aside) is saved and
        compiled. Typing is character by character, and on a loaded machine the editor's 400 ms
        debounce may upload a half-typed line (a prefix such as "i" is a valid program): only
        once this returns do markers and programs belong to the whole edit."""
        session = self.app.session
        wait_until(
            lambda: (
                session.text.rstrip().endswith(typed_end)
                and session.outcome is not None
                and session.outcome.revision == session.revision
            ),
            UI_WAIT_S,
            message=f"the text ending in {typed_end!r} saved and compiled",
        )

    def click_robot(self, page: object, client: object, index: int) -> None:
        """Look straight down at robot `index` and click it, left of the floating control panel.

        The camera looks down at a point of the discs' top plane `shift` metres right of the
        robot, so the robot's top appears at a known pixel offset left of the canvas centre
        (pinhole projection, vertical fov, at the depth of that plane: aimed at the floor
        instead, the click would land 0.24 disc heights right of the spot, 0.14 radii). The click
        goes to a spot of the robot's disc that no other robot covers, stepping on while there is
        none: the world doubles let robots overlap (robot 7's centre of the mechanics swarm is
        under a neighbour at ~7 % of steps), and a click there rightly selects the one on top.
        """
        controller = self.app.controller
        controller.pause()
        with controller.locked() as sim:
            assert sim is not None
            geometry = sim.geometry()
            radius = float(geometry.robot_radius)
            top = float(geometry.height) + BODY_HEIGHT_RADII * radius
        spot = None
        for _step in range(MAX_STEPS_TO_UNCOVER):
            wait_until(  # the pause draws the current step: the scene shows these robots
                lambda: controller.last_frame is not None
                and controller.last_frame.step == controller.status.step,
                UI_WAIT_S,
                message="the paused frame",
            )
            shown = controller.last_frame  # paused: it stays until the step below
            spot = uncovered_spot(shown.positions, index, radius)
            if spot is not None:
                break
            controller.single_step()  # the doubles' robots drive through each other
            wait_until(
                lambda shown=shown: controller.status.step > shown.step,
                UI_WAIT_S,
                message="one step",
            )
        if spot is None:
            raise AssertionError(f"robot {index} stayed under other robots")
        x, y = spot
        height, shift = 0.25, 0.06
        page.bring_to_front()  # type: ignore[attr-defined]  # background tabs stop drawing
        inspector = self.app._inspectors[client.client_id]  # type: ignore[attr-defined]
        for _attempt in range(4):  # a loaded machine may not have drawn the new view yet
            # The view is set on every attempt: a tab that was in the background may report
            # its canvas only now, and a canvas of another shape than the one its camera was
            # aimed for is framed again (`SwarmScene.aim_camera`), which moves the camera.
            client.camera.up_direction = (0.0, 1.0, 0.0)  # type: ignore[attr-defined]
            client.camera.position = (x + shift, y, top + height)  # type: ignore[attr-defined]
            client.camera.look_at = (x + shift, y, top)  # type: ignore[attr-defined]
            # barrier: the client rendered a frame after the camera messages above, so it
            # took the new view (messages reach it in order)
            render_barrier(page, client)
            box = page.locator("canvas").first.bounding_box()  # type: ignore[attr-defined]
            fov = float(client.camera.fov)  # type: ignore[attr-defined]
            pixels_per_metre = box["height"] / (2 * height * math.tan(fov / 2))
            page.mouse.click(  # type: ignore[attr-defined]
                box["x"] + box["width"] / 2 - shift * pixels_per_metre,
                box["y"] + box["height"] / 2,
            )
            deadline = time.monotonic() + 3.0
            while time.monotonic() < deadline and inspector.selected != index:
                time.sleep(0.05)
            if inspector.selected == index:
                return
        raise AssertionError(
            f"clicking robot {index} did not select it (selected: {inspector.selected})"
        )

    def open_tab(self) -> tuple[object, object]:
        """A second browser tab on the same run: (page, its viser client)."""
        known = set(self.app.server.get_clients())
        page = self.context.new_page()  # type: ignore[attr-defined]
        page.goto(self.app.url, wait_until="domcontentloaded")
        client_id = wait_until(
            lambda: set(self.app.server.get_clients()) - known, UI_WAIT_S, message="2nd tab"
        )
        return page, self.app.server.get_clients()[next(iter(client_id))]



#: Robots of the world doubles cross each other (each drives a ~4 cm circle). In 20,000 steps
#: of the 25-robot double (seeds 1-3) no robot was covered whole for more than 5 steps in a row.
MAX_STEPS_TO_UNCOVER = 100


def uncovered_spot(positions: np.ndarray, index: int, radius: float) -> tuple[float, float] | None:
    """A point on robot `index`'s disc at least a tenth of a radius clear of every other disc,
    or None if the others cover it all.

    Candidates are the centre and rings at half and three quarters of the radius, so the point
    stays well inside the robot's own disc; the one farthest from the other robots wins.
    """
    centre = positions[index].astype(float)
    angles = np.linspace(0.0, 2 * np.pi, 16, endpoint=False)
    rings = [np.stack([np.cos(angles), np.sin(angles)], axis=1) * f * radius for f in (0.5, 0.75)]
    candidates = centre + np.vstack([np.zeros((1, 2)), *rings])
    others = np.delete(positions, index, axis=0).astype(float)
    if len(others) == 0:
        return float(centre[0]), float(centre[1])
    clearance = np.min(np.linalg.norm(candidates[:, None, :] - others[None, :, :], axis=2), axis=1)
    best = int(np.argmax(clearance))
    if clearance[best] < 1.1 * radius:
        return None
    return float(candidates[best][0]), float(candidates[best][1])

@contextlib.contextmanager
def running_ide(
    script: Path,
    backend: WorldBackend,
    world: str,
    robots: int,
    speed: float = 30.0,
    run: bool = True,
) -> Iterator[IdeSession]:
    app = IdeApp(script, backend, RunSettings(world, robots, 1, speed), port=free_port()).start(
        run=run
    )
    try:
        with chromium_context() as context:
            yield IdeSession(app, context, open_app_page(context, app))
    finally:
        app.stop()


def editor_text(source: object) -> str:
    """The text the CodeMirror editor shows; `source` is its `#source` locator (the editor
    draws only the visible lines, so the DOM's text is not the document's)."""
    return source.evaluate("() => window.buzzEditor.text()")  # type: ignore[attr-defined]
