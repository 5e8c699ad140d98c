"""World overlays in the scene: fields as heat planes, targets as dots, relay links as lines.

Design: a world's `overlays()` is plain data (ARCHITECTURE "worlds → ui") whose names differ
per world, so this view draws by *shape*, not by name:
* a mapping with `bounds` (xmin, ymin, xmax, ymax) and a 2D `values` array in 0..1 (the Kilobot
  light field, the M300 belief map) becomes a textured plane under the robots (one viser image,
  ui-stack-notes §2: 0.7-1.1 ms per update), coloured dark blue → yellow;
* `targets`: a list of points or of mappings with `position` and `found` becomes a point cloud
  (red, green once found);
* `relay_links` (or any list of ((x, y), (x, y)) pairs under a name ending in `links`) becomes
  line segments.
Anything else is ignored. `show` skips work when the overlays did not change (by identity of
the data or equality of its JSON-like content), so the live IDE and the replay can call it every
frame.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import viser

#: The heat planes sit just under the robots and above the grid.
FIELD_Z = -0.0003
#: Heat plane colours: dark blue (0) to yellow (1), readable under LED-coloured robots.
LOW_COLOR = np.array([20, 30, 90], dtype=np.float64)
HIGH_COLOR = np.array([250, 220, 60], dtype=np.float64)
TARGET_COLOR = (220, 50, 50)
FOUND_COLOR = (40, 170, 70)
RELAY_COLOR = (230, 120, 20)


def field_image(values: np.ndarray) -> np.ndarray:
    """A (rows, cols) array in 0..1 as an RGB image (row 0 = lowest y, drawn at the bottom)."""
    v = np.clip(np.nan_to_num(np.asarray(values, dtype=np.float64)), 0.0, 1.0)
    rgb = LOW_COLOR + v[..., None] * (HIGH_COLOR - LOW_COLOR)
    return np.ascontiguousarray(rgb[::-1].astype(np.uint8))  # image rows go top-down


def _is_field(value: Any) -> bool:
    if not isinstance(value, dict) or "bounds" not in value or "values" not in value:
        return False
    return np.asarray(value["values"]).ndim == 2


def _targets(value: Any) -> tuple[np.ndarray, np.ndarray] | None:
    if not isinstance(value, list | tuple) or not value:
        return None
    points, found = [], []
    for item in value:
        where = item.get("position", item.get("pose")) if isinstance(item, dict) else item
        try:
            points.append((float(where[0]), float(where[1])))
        except (TypeError, ValueError, IndexError, KeyError):
            return None
        found.append(bool(item.get("found")) if isinstance(item, dict) else False)
    return np.array(points), np.array(found)


class OverlayView:
    def __init__(self, server: viser.ViserServer) -> None:
        self.server = server
        self._last: Any = None
        self._handles: dict[str, Any] = {}

    def show(self, overlays: dict[str, Any] | None, z: float = 0.0) -> None:
        if overlays is self._last:
            return
        self._last = overlays
        scene = self.server.scene
        seen = set()
        for name, value in (overlays or {}).items():
            node = f"/overlays/{name}"
            if _is_field(value):
                x0, y0, x1, y1 = (float(v) for v in value["bounds"])
                self._handles[node] = scene.add_image(
                    node, field_image(np.asarray(value["values"])), x1 - x0, y1 - y0,
                    position=((x0 + x1) / 2, (y0 + y1) / 2, FIELD_Z), cast_shadow=False,
                    receive_shadow=False)
                seen.add(node)
            elif name == "targets" and (targets := _targets(value)) is not None:
                points, found = targets
                colors = np.where(found[:, None], FOUND_COLOR, TARGET_COLOR).astype(np.uint8)
                lifted = np.column_stack([points, np.full(len(points), z + 0.002)])
                self._handles[node] = scene.add_point_cloud(
                    node, lifted.astype(np.float32), colors, point_size=0.03,
                    point_shape="diamond")
                seen.add(node)
            elif name.endswith("links") and isinstance(value, list | tuple) and value:
                try:
                    pairs = np.asarray(value, dtype=np.float64).reshape(-1, 2, 2)
                except ValueError:
                    continue
                lifted = np.concatenate([pairs, np.full((len(pairs), 2, 1), z + 0.003)], axis=2)
                self._handles[node] = scene.add_line_segments(
                    node, lifted.astype(np.float32), RELAY_COLOR, thickness=2.5,
                    thickness_units="screen")
                seen.add(node)
        for node in list(self._handles):
            if node not in seen:
                self._handles.pop(node).remove()
