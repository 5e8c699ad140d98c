"""The World setup folder: world options and the firmware loop, robot ids, and the legend.

The options are what `bbzide run --set KEY=VALUE` sets (a Kilobot table's `layout`, `light`,
`width`; an M300 field's `targets`, `search`; …), typed as `KEY=VALUE` words in one text field
and parsed by the same function as the command line's (`bbzide.worlds.commands`), so the two
accept the same words. A change rebuilds the world (step 0); an option the world does not take
is the registry's one-line error in the status line, and the running world stays. The firmware
loop is `bbzide run --loop`: `pop` drops each step's return value, `robot` keeps it on the stack
as the Kilobot firmware does (the stack then grows until STACK).

Shared by every tab like the run controls (one swarm); robot ids are drawn in the shared scene.
"""

from __future__ import annotations

import importlib
from collections.abc import Mapping
from typing import Any

import viser

from bbzide.diagnostics import UserError
from bbzide.ui.robot_labels import RobotLabels, legend_html
from bbzide.ui.run_controller import RunController
from bbzide.ui.scene import SwarmScene

#: The firmware loops the engine runs (`bbzide run --loop`), with what each does to the stack.
LOOP_CHOICES = {
    "pop: drop each step's result (default)": "pop",
    "robot: keep it, as the Kilobot firmware (stack grows)": "robot",
}


def options_text(options: Mapping[str, Any]) -> str:
    """`KEY=VALUE` words, the text field's form of a world's options."""
    return " ".join(f"{key}={value}" for key, value in options.items())


def parse_options_text(text: str) -> dict[str, Any]:
    """The text field's words as options (the command line's `--set` parsing); a word that is
    not KEY=VALUE is a `UserError`."""
    words = text.replace(",", " ").split()
    parse = importlib.import_module("bbzide.worlds.commands").parse_world_options
    return dict(parse(words))


class WorldSetupPanel:
    def __init__(self, server: viser.ViserServer, controller: RunController,
                 scene: SwarmScene, world_choice: viser.GuiDropdownHandle) -> None:
        self.controller = controller
        self.scene = scene
        self.labels = RobotLabels(server)
        settings = controller.settings
        pinned = getattr(settings.scenario, "world_options", None) or settings.world_options
        gui = server.gui
        with gui.add_folder("World setup", order=2.5, expand_by_default=False):
            self.options = gui.add_text(
                "World options", initial_value=options_text(pinned),
                hint=self._options_hint(settings.world))
            self.loop = gui.add_dropdown(
                "Firmware loop", tuple(LOOP_CHOICES),
                initial_value=next(k for k, v in LOOP_CHOICES.items() if v == settings.loop),
                hint="bbzide run --loop: what the firmware does with each step's return value")
            self.robot_ids = gui.add_checkbox(
                "Robot ids", initial_value=False,
                hint="Write each robot's id (and role, where the world has roles) over it")
            gui.add_html(legend_html())
        self.options.on_update(lambda _: self._apply_options())
        self.loop.on_update(
            lambda _: controller.update_settings(loop=LOOP_CHOICES[str(self.loop.value)]))
        self.robot_ids.on_update(lambda _: self._toggle_ids())
        world_choice.on_update(lambda _: self._world_changed(str(world_choice.value)))

    def _options_hint(self, world: str) -> str:
        return (f"KEY=VALUE words, as `bbzide run --world {world} --set KEY=VALUE` "
                "(e.g. layout=random light=spot for the Kilobot table); empty: the defaults")

    def _apply_options(self) -> None:
        try:
            options = parse_options_text(str(self.options.value))
        except UserError as error:
            self.controller.status.error = error.message
            return
        if options != self.controller.settings.world_options:
            self.controller.update_settings(world_options=options)

    def _world_changed(self, world: str) -> None:
        """Options belong to one world: another world starts from its defaults."""
        self.options.hint = self._options_hint(world)
        if str(self.options.value):
            self.options.value = ""  # (the app resets the settings' options with the world)

    def _toggle_ids(self) -> None:
        self.labels.set_visible(bool(self.robot_ids.value), self.scene.last_frame,
                                self.label_lift())

    def label_lift(self) -> float:
        """Labels float above the robots' tops (drawn radii: a drone's altitude included)."""
        geometry = self.scene.geometry
        if geometry is None:
            return 0.0
        return geometry.height + 1.5 * geometry.robot_radius

    def draw(self, frame: Any) -> None:
        """Called with each frame the scene draws (the simulation thread)."""
        self.labels.draw(frame, self.label_lift())
