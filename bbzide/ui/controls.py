"""Run controls and the status line (shared by every browser tab: one swarm, one set of controls).

Each control only sends a command to the run controller; nothing here waits for the simulation.
The status line is refreshed by the app's ticker from `RunController.status`, which the
simulation thread writes without locks (plain attribute stores), so it stays live even while a
robot is stuck in a long step.
"""

from __future__ import annotations

import html
import time
from pathlib import Path

import viser

from bbzide.ui.run_controller import RunController, RunStatus
from bbzide.ui.scene import SwarmScene

#: Upper end of the speed slider; 0 on the slider means "as fast as the machine goes".
MAX_STEPS_PER_SECOND = 500
#: A step that has run this long is called out in the status line (a loop in the script?).
SLOW_STEP_SECONDS = 1.0
#: The largest swarm the robot-count field offers: the scene update is measured for 1,000 robots
#: with every overlay (~1 ms, README "Status"); `bbzide ide --robots` is held to it too.
MAX_ROBOTS = 1000


class RunControls:
    def __init__(
        self,
        server: viser.ViserServer,
        controller: RunController,
        scene: SwarmScene,
        world_names: list[str],
        max_robots: int = MAX_ROBOTS,
    ) -> None:
        self.controller = controller
        self.scene = scene
        gui = server.gui
        settings = controller.settings
        with gui.add_folder("Run", order=1):
            self.status_line = gui.add_markdown("*starting…*")
            self.play = gui.add_button("Play", icon=viser.Icon.PLAYER_PLAY, color="green")
            self.pause = gui.add_button("Pause", icon=viser.Icon.PLAYER_PAUSE)
            self.step = gui.add_button(
                "Step",
                icon=viser.Icon.PLAYER_TRACK_NEXT,
                hint="Run one control step of every robot",
            )
            self.reset = gui.add_button(
                "Reset",
                icon=viser.Icon.REFRESH,
                hint="Restart the world from step 0 with the current program",
            )
            self.speed = gui.add_slider(
                "Steps/s (0 = max)",
                min=0,
                max=MAX_STEPS_PER_SECOND,
                step=1,
                initial_value=int(settings.steps_per_second),
            )
            self.world = gui.add_dropdown("World", tuple(world_names), initial_value=settings.world)
            self.load_example = gui.add_button(
                "Open this world's example",
                icon=viser.Icon.FILE_IMPORT,
                hint="Replace the editor's text with the example script of the world chosen "
                "above (the file is saved)",
            )
            self.robots = gui.add_number(
                "Robots", initial_value=settings.robots, min=1, max=max_robots, step=1
            )
            self.seed = gui.add_number(
                "Seed", initial_value=settings.seed, min=0, max=2**31 - 1, step=1
            )
            self.record = gui.add_checkbox(
                "Record",
                initial_value=False,
                hint="Write the run to a new .rrd (replay it with `bbzide replay FILE.rrd`)",
            )
            # always one line, so ticking Record moves nothing under the mouse
            self.recording_note = gui.add_html(recording_note(controller.status))
            self.keep_state = gui.add_checkbox(
                "Keep world on reload",
                initial_value=settings.keep_state_on_reload,
                hint="A new program keeps positions (on) or resets the world (off)",
            )
        with gui.add_folder("View", order=2, expand_by_default=False):
            self.links = gui.add_checkbox("Radio links", initial_value=scene.show_links)
            self.ranges = gui.add_checkbox("Radio ranges", initial_value=scene.show_ranges)
            self.trails = gui.add_checkbox("Trails", initial_value=scene.show_trails)
            self.overlays = gui.add_checkbox(
                "World overlays",
                initial_value=True,
                hint="Light field, belief map, targets, relay links (what the world offers)",
            )
        self._wire()

    def _wire(self) -> None:
        controller = self.controller
        self.play.on_click(lambda _: controller.play())
        self.pause.on_click(lambda _: controller.pause())
        self.step.on_click(lambda _: controller.single_step())
        self.reset.on_click(lambda _: controller.reset())
        self.speed.on_update(
            lambda _: controller.update_settings(steps_per_second=float(self.speed.value))
        )
        self.robots.on_update(
            lambda _: controller.update_settings(robots=max(1, int(self.robots.value)))
        )
        self.seed.on_update(lambda _: controller.update_settings(seed=int(self.seed.value)))
        self.keep_state.on_update(
            lambda _: controller.update_settings(keep_state_on_reload=bool(self.keep_state.value))
        )
        self.links.on_update(lambda _: self.scene.set_toggles(links=self.links.value))
        self.ranges.on_update(lambda _: self.scene.set_toggles(ranges=self.ranges.value))
        self.trails.on_update(lambda _: self.scene.set_toggles(trails=self.trails.value))

    def refresh_status(self, compile_note: str = "") -> None:
        text = status_text(self.controller.status, self.controller.has_program)
        if compile_note:
            text += f"  \n{compile_note}"
        if self.status_line.content != text:
            self.status_line.content = text
        note = recording_note(self.controller.status)
        if self.recording_note.content != note:
            self.recording_note.content = note


#: The note under Record always takes two lines of the panel (a long file name is cut with an
#: ellipsis), so ticking Record moves nothing under the mouse.
RECORDING_NOTE_STYLE = (
    "font-size:12px;line-height:1.4;height:2.8em;overflow:hidden;color:#495057;"
    "margin:-4px 0 2px;padding-left:10px"
)


def recording_note(status: RunStatus) -> str:
    """The note under Record: the file being written, else the last one written (its path
    stays after the stop, to replay it), else where a recording would go."""
    if status.recording:
        head, path = "recording to", _short_path(status.recording)
    elif status.last_recording:
        head, path = "last recording:", _short_path(status.last_recording)
    else:
        head, path = "not recording;", "a new .rrd goes to recordings/ beside the script"
    dot = '<span style="color:#e03131">●</span> ' if status.recording else ""
    return (f'<div class="bbz-recording-note" style="{RECORDING_NOTE_STYLE}">{dot}'
            f"{html.escape(head)}"
            '<div style="white-space:nowrap;overflow:hidden;text-overflow:ellipsis;'
            f'font-family:ui-monospace,monospace">{html.escape(path)}</div></div>')


def _short_path(path: str) -> str:
    """`recordings/<file>.rrd`: the folder beside the script and the file, on one line."""
    return f"{Path(path).parent.name}/{Path(path).name}"


def status_text(status: RunStatus, has_program: bool) -> str:
    if not has_program:
        waiting = "**no program yet**: fix the errors in the editor"
        return f"{waiting}  \n{status.notice}" if status.notice else waiting
    state = "running" if status.running else "paused"
    rate = f"{status.steps_per_second:.0f} steps/s" if status.running else "0 steps/s"
    parts = [f"**step {status.step}**", state, rate, f"{status.robots} robots"]
    errors = status.robots_in_error
    parts.append(
        f"<span style='color:#c92a2a'>**{errors} in error**</span>" if errors else "0 in error"
    )
    text = " · ".join(parts)
    started = status.step_started_at
    if started is not None and time.monotonic() - started > SLOW_STEP_SECONDS:
        text += (
            f"  \n⚠ one step has run for {time.monotonic() - started:.1f} s (a loop in the script?)"
        )
    if status.notice:
        text += f"  \n{status.notice}"
    if status.error:
        text += f"  \n**world error:** `{status.error}`"
    return text
