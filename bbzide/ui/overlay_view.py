"""World overlays in the scene: fields as heat planes, targets as dots, relay links as lines.

Design: a world's `overlays()` is plain data (ARCHITECTURE "worlds → ui") whose names differ
per world, so this view draws by *shape*, not by name:
* a mapping with a 2D `values` array in 0..1 and `bounds` (xmin, ymin, xmax, ymax) or `origin`
  + `cell` size (the Kilobot light field, the M300 belief map) becomes a textured plane under
  the robots (one viser image, ui-stack-notes §2: 0.7-1.1 ms per update), dark blue → yellow;
  small rasters are enlarged by repeating pixels, so a 10 x 10 belief map shows its cells
  instead of the browser's blurred interpolation;
* `targets`: a list of points or of mappings with `position` and `found` (or a parallel
  `targets_found` list of flags) becomes a point cloud (red, green once found), sized to the
  world's robots (`set_scale`), so a target in a 36 m field is as visible as one on a table;
* any other name whose value is one point (x, y) (the M300 `rendezvous`) becomes a marker;
* `relay_links` (any name ending in `links`): ((x, y), (x, y)) point pairs, or (i, j) robot
  index pairs drawn between the robots' current positions, become line segments.
Anything else is ignored. `show` is called every frame by the replay (links follow the robots)
and every second by the live IDE, so it sends only what changed: a raster is re-sent only when
its values differ from the drawn ones, targets when their points or flags differ, and links
update the existing node's points (viser itself skips an array equal to the last one).
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
POINT_COLOR = (160, 60, 200)
#: Target and point markers are this many robot radii across (default: a Kilobot's radius).
MARKER_RADII = 4.0
DEFAULT_ROBOT_RADIUS = 0.0165
#: Rasters are enlarged (nearest neighbour) to at least this many pixels across.
FIELD_MIN_PIXELS = 128


def field_image(values: np.ndarray, min_pixels: int = 1) -> np.ndarray:
    """A (rows, cols) array in 0..1 as an RGB image (row 0 = lowest y, drawn at the bottom),
    each cell repeated so the image is at least `min_pixels` across (crisp cells)."""
    v = np.clip(np.nan_to_num(np.asarray(values, dtype=np.float64)), 0.0, 1.0)
    rgb = (LOW_COLOR + v[..., None] * (HIGH_COLOR - LOW_COLOR)).astype(np.uint8)[::-1]
    repeat = max(1, -(-min_pixels // max(v.shape)))  # ceiling division
    if repeat > 1:
        rgb = np.repeat(np.repeat(rgb, repeat, axis=0), repeat, axis=1)
    return np.ascontiguousarray(rgb)  # image rows go top-down


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
        self._drawn: dict[str, Any] = {}  # node -> what it shows (to skip unchanged data)
        self.marker_size = MARKER_RADII * DEFAULT_ROBOT_RADIUS
        self.visible = True

    def set_visible(self, visible: bool) -> None:
        """The "World overlays" toggle: hide or show every overlay node (kept up to date)."""
        self.visible = visible
        for handle in self._handles.values():
            handle.visible = visible

    def set_scale(self, robot_radius: float) -> None:
        """Size markers for a world whose robots have `robot_radius` metres (redraws them)."""
        size = MARKER_RADII * robot_radius
        if size != self.marker_size:
            self.marker_size = size
            for node in [n for n, d in self._drawn.items() if isinstance(d, tuple)]:
                self._drawn.pop(node)  # markers are re-added at the new size on the next show
            self._last = None

    def show(self, overlays: dict[str, Any] | None, z: float = 0.0,
             positions: np.ndarray | None = None) -> None:
        """Draw `overlays`; `positions` (N, 2) resolve links given as robot index pairs."""
        if overlays is self._last and positions is None:
            return
        self._last = overlays
        seen = set()
        for name, value in (overlays or {}).items():
            node = f"/overlays/{name}"
            bounds = _field_bounds(value)
            if bounds is not None:
                self._show_field(node, np.asarray(value["values"]), bounds)
            elif name == "targets" and (
                    targets := _targets(value, overlays.get("targets_found"))) is not None:
                self._show_targets(node, *targets, z)
            elif name.endswith("links") and isinstance(value, list | tuple) and value:
                pairs = _link_segments(value, positions)
                if pairs is None:
                    continue
                self._show_links(node, pairs, z)
            elif (point := _point(value)) is not None:
                self._show_points(node, point[None, :], np.zeros(1, dtype=bool), z, POINT_COLOR)
            else:
                continue
            seen.add(node)
        for node in list(self._handles):
            if node not in seen:
                self._handles.pop(node).remove()
                self._drawn.pop(node, None)

    def _show_field(self, node: str, values: np.ndarray,
                    bounds: tuple[float, float, float, float]) -> None:
        drawn = self._drawn.get(node)
        if drawn is not None and drawn[0] == bounds and np.array_equal(drawn[1], values):
            return
        x0, y0, x1, y1 = bounds
        self._handles[node] = self.server.scene.add_image(
            node, field_image(values, FIELD_MIN_PIXELS), x1 - x0, y1 - y0, format="png",
            position=((x0 + x1) / 2, (y0 + y1) / 2, FIELD_Z), cast_shadow=False,
            receive_shadow=False, visible=self.visible)
        self._drawn[node] = (bounds, values.copy())

    def _show_targets(self, node: str, points: np.ndarray, found: np.ndarray, z: float) -> None:
        self._show_points(node, points, found, z, TARGET_COLOR)

    def _show_points(self, node: str, points: np.ndarray, found: np.ndarray, z: float,
                     color: tuple[int, int, int]) -> None:
        drawn = self._drawn.get(node)
        if drawn is not None and np.array_equal(drawn[0], points) and np.array_equal(
                drawn[1], found):
            return
        colors = np.where(found[:, None], FOUND_COLOR, color).astype(np.uint8)
        lifted = np.column_stack([points, np.full(len(points), z + 0.002)]).astype(np.float32)
        self._handles[node] = self.server.scene.add_point_cloud(
            node, lifted, colors, point_size=self.marker_size, point_shape="diamond",
            visible=self.visible)
        self._drawn[node] = (points, found)

    def _show_links(self, node: str, pairs: np.ndarray, z: float) -> None:
        lifted = np.empty((len(pairs), 2, 3), dtype=np.float32)
        lifted[:, :, :2] = pairs
        lifted[:, :, 2] = z + 0.003
        handle = self._handles.get(node)
        if handle is not None:
            handle.points = lifted  # one array update; viser skips it when unchanged
            return
        self._handles[node] = self.server.scene.add_line_segments(
            node, lifted, RELAY_COLOR, thickness=2.5, thickness_units="screen",
            visible=self.visible)
        self._drawn[node] = True


def _point(value: Any) -> np.ndarray | None:
    """One (x, y) point given as two numbers, else None."""
    if not isinstance(value, list | tuple) or len(value) != 2:
        return None
    if not all(isinstance(v, int | float) and not isinstance(v, bool) for v in value):
        return None
    return np.array([float(value[0]), float(value[1])])


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
