"""World overlays in the scene: fields as heat planes, targets as dots, relay links as lines.

Design: a world's `overlays()` is plain data (ARCHITECTURE "worlds → ui") whose names differ
per world, so this view draws by *shape*, not by name:
* a mapping with a 2D `values` array in 0..1 and `bounds` (xmin, ymin, xmax, ymax) or `origin`
  + `cell` size (the Kilobot light field, the M300 belief map) becomes a textured plane under
  the robots (one viser image, ui-stack-notes §2: 0.7-1.1 ms per update), dark blue → yellow;
* `targets`: a list of points or of mappings with `position` and `found` (or a parallel
  `targets_found` list of flags) becomes a point cloud (red, green once found);
* `relay_links` (any name ending in `links`): ((x, y), (x, y)) point pairs, or (i, j) robot
  index pairs drawn between the robots' current positions, become line segments.
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


def _field_bounds(value: Any) -> tuple[float, float, float, float] | None:
    """(xmin, ymin, xmax, ymax) of a raster overlay: given as `bounds`, or as `origin` + `cell`
    size (the M300 belief map), else None (not a raster)."""
    if not isinstance(value, dict) or "values" not in value:
        return None
    values = np.asarray(value["values"])
    if values.ndim != 2:
        return None
    if "bounds" in value:
        x0, y0, x1, y1 = (float(v) for v in value["bounds"])
        return x0, y0, x1, y1
    if "origin" in value and "cell" in value:
        x0, y0 = (float(v) for v in value["origin"])
        cell = float(value["cell"])
        rows, cols = values.shape
        return x0, y0, x0 + cols * cell, y0 + rows * cell
    return None


def _targets(value: Any, flags: Any = None) -> tuple[np.ndarray, np.ndarray] | None:
    if not isinstance(value, list | tuple) or not value:
        return None
    points, found = [], []
    for k, item in enumerate(value):
        where = item.get("position", item.get("pose")) if isinstance(item, dict) else item
        try:
            points.append((float(where[0]), float(where[1])))
        except (TypeError, ValueError, IndexError, KeyError):
            return None
        if isinstance(flags, list | tuple) and k < len(flags):
            found.append(bool(flags[k]))
        else:
            found.append(bool(item.get("found")) if isinstance(item, dict) else False)
    return np.array(points), np.array(found)


class OverlayView:
    def __init__(self, server: viser.ViserServer) -> None:
        self.server = server
        self._last: Any = None
        self._handles: dict[str, Any] = {}
        self._drawn_fields: dict[str, Any] = {}  # node -> the overlays object it was drawn from

    def show(self, overlays: dict[str, Any] | None, z: float = 0.0,
             positions: np.ndarray | None = None) -> None:
        """Draw `overlays`; `positions` (N, 2) resolve links given as robot index pairs."""
        if overlays is self._last and positions is None:
            return
        self._last = overlays
        scene = self.server.scene
        seen = set()
        for name, value in (overlays or {}).items():
            node = f"/overlays/{name}"
            bounds = _field_bounds(value)
            if bounds is not None:
                if overlays is self._drawn_fields.get(node):
                    seen.add(node)
                    continue
                x0, y0, x1, y1 = bounds
                self._handles[node] = scene.add_image(
                    node, field_image(np.asarray(value["values"])), x1 - x0, y1 - y0,
                    position=((x0 + x1) / 2, (y0 + y1) / 2, FIELD_Z), cast_shadow=False,
                    receive_shadow=False)
                self._drawn_fields[node] = overlays
                seen.add(node)
            elif name == "targets" and (
                    targets := _targets(value, overlays.get("targets_found"))) is not None:
                points, found = targets
                colors = np.where(found[:, None], FOUND_COLOR, TARGET_COLOR).astype(np.uint8)
                lifted = np.column_stack([points, np.full(len(points), z + 0.002)])
                self._handles[node] = scene.add_point_cloud(
                    node, lifted.astype(np.float32), colors, point_size=0.03,
                    point_shape="diamond")
                seen.add(node)
            elif name.endswith("links") and isinstance(value, list | tuple) and value:
                pairs = _link_segments(value, positions)
                if pairs is None:
                    continue
                lifted = np.concatenate([pairs, np.full((len(pairs), 2, 1), z + 0.003)], axis=2)
                self._handles[node] = scene.add_line_segments(
                    node, lifted.astype(np.float32), RELAY_COLOR, thickness=2.5,
                    thickness_units="screen")
                seen.add(node)
        for node in list(self._handles):
            if node not in seen:
                self._handles.pop(node).remove()
                self._drawn_fields.pop(node, None)


def _link_segments(value: Any, positions: np.ndarray | None) -> np.ndarray | None:
    """Links as (K, 2, 2) segments: given as point pairs, or as robot index pairs."""
    try:
        array = np.asarray(value, dtype=np.float64)
    except ValueError:
        return None
    if array.ndim == 3 and array.shape[1:] == (2, 2):
        return array
    if array.ndim == 2 and array.shape[1] == 2 and positions is not None:
        index = array.astype(int)
        if index.size and (index.min() < 0 or index.max() >= len(positions)):
            return None
        return np.asarray(positions, dtype=np.float64)[index]
    return None
