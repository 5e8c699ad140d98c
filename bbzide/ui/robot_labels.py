"""Robot ids (and roles) written over the robots on demand, and the legend of the 3D view.

viser has no batched labels: each robot's label is its own scene node, so labels are made only
while the "Robot ids" box is ticked, for at most `MAX_LABELLED_ROBOTS` robots, and moved every
`LABEL_EVERY_FRAMES` frames (a label trailing its robot by a few frames is still read as its
own; moving hundreds of nodes 30 times a second is not worth the websocket traffic). A label
is rewritten only when its text changes (a role change), so a still swarm sends nothing.

The legend says what every colour and marker of the scene means, in the colours the scene
(`bbzide.ui.scene`) and the overlays (`bbzide.ui.overlay_view`) draw with.
"""

from __future__ import annotations

import threading

import numpy as np
import viser

from bbzide.ui.overlay_view import FOUND_COLOR, POINT_COLOR, RELAY_COLOR, TARGET_COLOR
from bbzide.ui.scene import FAILED_COLOR, LINK_COLOR, RANGE_COLOR, SELECTION_COLOR
from bbzide.ui.world_backend import SwarmFrame

#: Labels for the first this many robots: 100 labels fit a 1400 x 900 view before they cover
#: each other; a larger swarm is read by clicking a robot (its label is the selection's).
MAX_LABELLED_ROBOTS = 100
#: Labels move every 5th frame: 6 times a second at the scene's 30 frames per second.
LABEL_EVERY_FRAMES = 5


class RobotLabels:
    """`robot 7 · relay` over each robot while shown (see the module docstring)."""

    def __init__(self, server: viser.ViserServer) -> None:
        self.server = server
        self.visible = False
        self._lock = threading.Lock()  # the GUI thread toggles, the simulation thread draws
        self._labels: list[viser.LabelHandle] = []
        self._texts: list[str] = []
        self._frames = 0

    def set_visible(self, visible: bool, frame: SwarmFrame | None, lift: float) -> None:
        with self._lock:
            self.visible = visible
            if not visible:
                for label in self._labels:
                    label.remove()
                self._labels, self._texts = [], []
                return
        if frame is not None:
            self.draw(frame, lift, force=True)

    def draw(self, frame: SwarmFrame, lift: float, force: bool = False) -> None:
        """Move the labels onto the robots of `frame`, `lift` metres above their centres."""
        with self._lock:
            if not self.visible:
                return
            self._frames += 1
            count = min(frame.count, MAX_LABELLED_ROBOTS)
            if not force and len(self._labels) == count and \
                    self._frames % LABEL_EVERY_FRAMES != 0:
                return
            texts = label_texts(frame)[:count]
            positions = np.asarray(frame.positions[:count], dtype=np.float64)
            with self.server.atomic():
                while len(self._labels) > count:
                    self._labels.pop().remove()
                    self._texts.pop()
                for index in range(count):
                    x, y = float(positions[index, 0]), float(positions[index, 1])
                    if index == len(self._labels):
                        self._labels.append(self.server.scene.add_label(
                            f"/robot_ids/{index}", texts[index], position=(x, y, lift)))
                        self._texts.append(texts[index])
                        continue
                    label = self._labels[index]
                    label.position = (x, y, lift)
                    if self._texts[index] != texts[index]:
                        label.text = self._texts[index] = texts[index]


def label_texts(frame: SwarmFrame) -> list[str]:
    """Each robot's Buzz `id`, with its role when the world gives robots roles and they tell
    robots apart (a script that never sets roles leaves every drone "landed": no news)."""
    ids = frame.robot_ids or list(range(frame.count))
    roles = frame.roles if len(frame.roles) == frame.count else [""] * frame.count
    if len(set(roles)) < 2:
        roles = [""] * frame.count
    return [f"{robot_id} · {role}" if role else str(robot_id)
            for robot_id, role in zip(ids, roles, strict=False)]


def _swatch(rgb: tuple[int, int, int], shape: str = "square") -> str:
    radius = "50%" if shape == "dot" else "2px"
    height = "3px" if shape == "line" else "10px"
    return (f'<span style="display:inline-block;width:12px;height:{height};border-radius:{radius};'
            f'vertical-align:middle;background:rgb{rgb}"></span>')


def _ring(rgb: tuple[int, int, int]) -> str:
    return (f'<span style="display:inline-block;width:9px;height:9px;border-radius:50%;'
            f'vertical-align:middle;border:2px solid rgb{rgb}"></span>')


def legend_html() -> str:
    """What the scene's colours and markers mean (the View folder's legend)."""
    rows = [
        (_swatch((140, 140, 148)), "a robot, in its LED's colour (grey: LED off)"),
        (_swatch((30, 30, 30), "line"), "its heading"),
        (_swatch(LINK_COLOR, "line"), "a radio link (a message went through this step)"),
        (_ring(RANGE_COLOR), "radio range (View › Radio ranges)"),
        (_ring(FAILED_COLOR), "a robot whose VM stopped with an error (click it)"),
        (_ring(SELECTION_COLOR), "the robot this tab inspects"),
        ('<span style="display:inline-block;width:40px;height:8px;vertical-align:middle;'
         'background:linear-gradient(90deg,rgb(20,30,90),rgb(250,220,60))"></span>',
         "a world field, low to high (Kilobot light; M300 belief map)"),
        (_swatch(TARGET_COLOR, "dot") + _swatch(FOUND_COLOR, "dot"), "a target; found"),
        (_swatch(POINT_COLOR, "dot"), "a meeting point (the M300 rendezvous)"),
        (_swatch(RELAY_COLOR, "line"), "the relay tree"),
    ]
    body = "".join(f"<div>{mark} {text}</div>" for mark, text in rows)
    return f'<div class="bbz-scene-legend" style="font-size:11px;line-height:1.7">{body}</div>'
