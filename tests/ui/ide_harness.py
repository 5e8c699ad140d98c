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

from browser import chromium_context, free_port, open_app_page, wait_until

from bbzide.ui.app import IdeApp
from bbzide.ui.run_controller import RunSettings
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

    def click_robot(self, page: object, client: object, index: int) -> None:
        """Look straight down at robot `index` and click it, left of the floating control panel.

        The camera looks at a point `shift` metres right of the robot, so the robot appears at a
        known pixel offset left of the canvas centre (pinhole projection, vertical fov).
        """
        self.app.controller.pause()
        time.sleep(0.3)
        with self.app.controller.locked() as sim:
            assert sim is not None
            x, y = (float(v) for v in sim.frame().positions[index])
        height, shift = 0.25, 0.06
        client.camera.up_direction = (0.0, 1.0, 0.0)  # type: ignore[attr-defined]
        client.camera.position = (x + shift, y, height)  # type: ignore[attr-defined]
        client.camera.look_at = (x + shift, y, 0.0)  # type: ignore[attr-defined]
        page.bring_to_front()  # type: ignore[attr-defined]  # background tabs stop drawing
        inspector = self.app._inspectors[client.client_id]  # type: ignore[attr-defined]
        for _attempt in range(4):  # a loaded machine may not have drawn the new view yet
            time.sleep(1.0)
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
        raise AssertionError(f"clicking robot {index} did not select it")

    def open_tab(self) -> tuple[object, object]:
        """A second browser tab on the same run: (page, its viser client)."""
        known = set(self.app.server.get_clients())
        page = self.context.new_page()  # type: ignore[attr-defined]
        page.goto(self.app.url, wait_until="domcontentloaded")
        client_id = wait_until(
            lambda: set(self.app.server.get_clients()) - known, 30, message="2nd tab"
        )
        return page, self.app.server.get_clients()[next(iter(client_id))]


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
