"""The 3D view of the swarm: robots, headings, LEDs, radio links, ranges, trails, world overlay.

All robots are ONE batched mesh (one instanced draw call; one array assignment per frame:
`ui-stack-notes` §2 measured N separate nodes at 43-53 ms per frame for 1000 robots, batched at
0.4 ms). The robot body is a low-poly cylinder (8 sides: 24-sided bodies dropped software-GL
browsers to 1-4 fps at 1000 robots) coloured by its LED. Range circles are a second batched mesh
(a flat ring per robot), so a frame sends only their N positions, not 16 segments per robot.
Headings, links and failure rings are line segments; trails are a point cloud sampled every
`TRAIL_SAMPLE_FRAMES` frames into a preallocated ring buffer and sent only when a sample is
added. Everything shared is in `server.scene` and updated in one `server.atomic()` block per
frame (viser itself skips arrays that did not change); the selection ring and label live in each
client's own scene, so every tab has its own selection (and camera).

When a world is loaded, and when the number of robots changes, the default camera and every
open tab's camera frame the world's area of interest (its bounds and every robot), fitted to the
tab's canvas (the 3D view between the docked panels is tall and narrow at 1400 x 900). Robots
are drawn at least `MIN_DRAWN_RADIUS_SHARE` of that view wide, so a Crazyflie in its 6 m lab is
a disc one can see and click, not a dot.
"""

from __future__ import annotations

import dataclasses
import math
import threading
from collections.abc import Callable

import numpy as np
import viser

from bbzide.ui.world_backend import SwarmFrame, WorldGeometry

#: Sides of the robot cylinder (see the module docstring for why so few).
BODY_SIDES = 8
#: The cylinder's height in robot radii: a flat disc, like a Kilobot, yet with walls to see.
BODY_HEIGHT_RADII = 0.6
#: Segments approximating a range circle: round enough at table scale, 16 lines per robot.
CIRCLE_SEGMENTS = 16
#: Trails keep one sample every 3 frames, 15 samples per robot: at 30 Hz about 1.5 s of history,
#: a third of the points (and of the bytes per update) of sampling every frame.
TRAIL_SAMPLE_FRAMES = 3
TRAIL_SAMPLES = 15
#: A range ring's width, as a share of the radio range: thin, yet visible from above.
RANGE_RING_WIDTH = 0.03
#: The camera frames the world's area of interest: its bounds and every robot (drones may fly
#: outside the bounds), grown by this many robot radii so a robot on the edge is whole.
CAMERA_MARGIN_RADII = 6.0
#: A swarm whose radio neighbourhood spans less than half the world's width and depth is
#: framed alone (`view_box`): drones crossing a field fill more, and keep the whole field.
SWARM_FRAME_SHARE = 0.5
#: The box must fit the view with this much room to spare (10 %).
CAMERA_SLACK = 1.1
#: A tab whose canvas size is not known yet (the first camera message has not arrived) is
#: assumed this narrow: the 3D view between the docked editor (600 px) and control panel at a
#: 1400 x 900 window is about 420 x 880 px. A wider view then just shows more around the box.
ASSUMED_ASPECT = 0.45
#: A tab's camera is aimed again when its canvas's width/height differs from the one it was
#: aimed for by more than this share (10 %): a resized window, or a first real size far from
#: the assumed one; not for every camera message, so a camera the user moved stays.
REAIM_ASPECT_CHANGE = 0.1
#: A robot is drawn with a radius of at least this share of the framed box's larger side: at
#: the narrowest view (about 420 px for 1.1 times the box) a disc of about 14 px, visible and
#: clickable on a light floor. Crazyflies (4.6 cm in a 6 m lab) are drawn 2.5 times their size;
#: Kilobots (1.65 cm on a 1 m table) 1.3 times, 4.3 cm: still apart on the 5 cm lattice.
MIN_DRAWN_RADIUS_SHARE = 0.018
#: Robots in error get a red ring; links and ranges are drawn in these colours (RGB 0..255).
FAILED_COLOR = (224, 49, 49)
LINK_COLOR = (60, 140, 230)
RANGE_COLOR = (150, 170, 200)
HEADING_COLOR = (30, 30, 30)
SELECTION_COLOR = (255, 170, 0)
#: A robot whose LED is off is drawn in this grey (black bodies vanish on a dark table).
LED_OFF_COLOR = np.array([0.55, 0.55, 0.58])


def cylinder_mesh(
    radius: float, height: float, sides: int = BODY_SIDES
) -> tuple[np.ndarray, np.ndarray]:
    """Vertices and faces of a closed cylinder standing on z = 0 (caps and walls)."""
    angles = np.linspace(0.0, 2.0 * math.pi, sides, endpoint=False)
    ring = np.stack([radius * np.cos(angles), radius * np.sin(angles)], axis=1)
    bottom = np.column_stack([ring, np.zeros(sides)])
    top = np.column_stack([ring, np.full(sides, height)])
    centres = np.array([[0.0, 0.0, 0.0], [0.0, 0.0, height]])
    vertices = np.vstack([bottom, top, centres]).astype(np.float32)
    bottom_centre, top_centre = 2 * sides, 2 * sides + 1
    faces = []
    for i in range(sides):
        j = (i + 1) % sides
        faces += [(i, j, sides + j), (i, sides + j, sides + i)]  # wall
        faces += [(bottom_centre, j, i), (top_centre, sides + i, sides + j)]  # caps
    return vertices, np.array(faces, dtype=np.uint32)


def heading_quaternions(headings: np.ndarray) -> np.ndarray:
    """(N, 4) wxyz rotations about +z."""
    half = 0.5 * headings.astype(np.float32)
    wxyz = np.zeros((headings.shape[0], 4), dtype=np.float32)
    wxyz[:, 0] = np.cos(half)
    wxyz[:, 3] = np.sin(half)
    return wxyz


def ring_mesh(
    radius: float, width: float, sides: int = CIRCLE_SEGMENTS
) -> tuple[np.ndarray, np.ndarray]:
    """Vertices and faces of a flat ring (annulus) around the origin at z = 0, facing up."""
    angles = np.linspace(0.0, 2.0 * math.pi, sides, endpoint=False)
    unit = np.stack([np.cos(angles), np.sin(angles), np.zeros(sides)], axis=1)
    vertices = np.vstack([unit * radius, unit * max(radius - width, 0.0)]).astype(np.float32)
    faces = []
    for i in range(sides):
        j = (i + 1) % sides
        faces += [(i, sides + i, j), (j, sides + i, sides + j)]  # counter-clockwise from above
    return vertices, np.array(faces, dtype=np.uint32)


def camera_pose(
    box: tuple[float, float, float, float], z: float, aspect: float = ASSUMED_ASPECT,
    fov: float = math.radians(75.0),
) -> tuple[tuple[float, float, float], tuple[float, float, float]]:
    """(position, look_at) of a camera above and a little south of `box`, seeing all of it in a
    view of `aspect` (width / height) and vertical field of view `fov` (radians): the box's width
    must fit the horizontal field of view, its depth the vertical one."""
    xmin, ymin, xmax, ymax = box
    half_vertical = math.tan(fov / 2)
    half_horizontal = half_vertical * max(aspect, 1e-3)
    distance = CAMERA_SLACK * max((xmax - xmin) / (2 * half_horizontal),
                                  (ymax - ymin) / (2 * half_vertical))
    centre = ((xmin + xmax) / 2, (ymin + ymax) / 2)
    return (centre[0], centre[1] - 0.35 * distance, z + distance), (centre[0], centre[1], z)


def view_box(
    positions: np.ndarray | None, geometry: WorldGeometry
) -> tuple[float, float, float, float]:
    """The box the camera frames: the world's bounds and every robot, with a margin; or, when
    the swarm and its radio neighbourhood fill less than `SWARM_FRAME_SHARE` of the world's
    width and depth (25 Kilobots on a 5 cm lattice in the middle of a 1 m table), the swarm
    and one radio range around it, so the robots are not specks in the middle of the view."""
    xmin, ymin, xmax, ymax = geometry.bounds
    margin = CAMERA_MARGIN_RADII * geometry.robot_radius
    if positions is not None and len(positions):
        points = np.asarray(positions, dtype=np.float64)
        (pxmin, pymin), (pxmax, pymax) = points.min(axis=0), points.max(axis=0)
        reach = max(margin, geometry.comm_range)
        near = (float(pxmin) - reach, float(pymin) - reach,
                float(pxmax) + reach, float(pymax) + reach)
        if (near[2] - near[0] < SWARM_FRAME_SHARE * (xmax - xmin)
                and near[3] - near[1] < SWARM_FRAME_SHARE * (ymax - ymin)):
            return near
        xmin, ymin = min(xmin, float(pxmin)), min(ymin, float(pymin))
        xmax, ymax = max(xmax, float(pxmax)), max(ymax, float(pymax))
    return xmin - margin, ymin - margin, xmax + margin, ymax + margin


def drawn_radius(box: tuple[float, float, float, float], robot_radius: float) -> float:
    """The radius robots are drawn with in a view of `box`: their own, or large enough to see
    and click (`MIN_DRAWN_RADIUS_SHARE`)."""
    xmin, ymin, xmax, ymax = box
    return max(robot_radius, MIN_DRAWN_RADIUS_SHARE * max(xmax - xmin, ymax - ymin))


def circle_segments(centres: np.ndarray, radius: float, z: float) -> np.ndarray:
    """(N * CIRCLE_SEGMENTS, 2, 3) segments of a circle of `radius` around each centre."""
    angles = np.linspace(0.0, 2.0 * math.pi, CIRCLE_SEGMENTS + 1)
    unit = np.stack([np.cos(angles), np.sin(angles)], axis=1) * radius  # (S+1, 2)
    points = centres[:, None, :] + unit[None, :, :]  # (N, S+1, 2)
    starts, ends = points[:, :-1, :], points[:, 1:, :]
    segments = np.stack([starts, ends], axis=2).reshape(-1, 2, 2)
    return np.concatenate([segments, np.full(segments.shape[:2] + (1,), z)], axis=2).astype(
        np.float32
    )


def _lift(points_2d: np.ndarray, z: float) -> np.ndarray:
    """(..., 2) points as (..., 3) float32 at height z (one allocation)."""
    lifted = np.empty(points_2d.shape[:-1] + (3,), dtype=np.float32)
    lifted[..., :2] = points_2d
    lifted[..., 2] = z
    return lifted


#: Line segment nodes cannot be empty in viser: an invisible zero-length segment stands in.
_NO_SEGMENTS = np.zeros((1, 2, 3), dtype=np.float32)


class SwarmScene:
    """Draws `SwarmFrame`s into a viser server; reports robot clicks as (client, robot index)."""

    def __init__(
        self,
        server: viser.ViserServer,
        on_robot_click: Callable[[viser.ClientHandle, int], None] | None = None,
    ) -> None:
        self.server = server
        self._on_robot_click = on_robot_click
        self._lock = threading.Lock()
        self._selection_lock = threading.Lock()  # see `select`
        self.geometry: WorldGeometry | None = None
        self.show_links = True
        self.show_ranges = False
        self.show_trails = False
        self._robots: viser.BatchedMeshHandle | None = None
        self._range_rings: viser.BatchedMeshHandle | None = None
        self._robot_count = -1
        self._trail: np.ndarray | None = None  # (TRAIL_SAMPLES, N, 3) ring buffer
        self._trail_frames = 0  # frames drawn since the trail was (re)started
        self._view_box: tuple[float, float, float, float] | None = None
        self._selection: dict[int, int] = {}  # client id -> selected robot index
        self._selection_marks: dict[int, tuple[viser.LineSegmentsHandle, viser.LabelHandle]] = {}
        self._aimed_aspects: dict[int, float] = {}  # client id -> canvas aspect last aimed for
        self.last_frame: SwarmFrame | None = None
        server.scene.set_up_direction("+z")
        self._headings = server.scene.add_line_segments(
            "/swarm/headings", _NO_SEGMENTS, HEADING_COLOR, thickness=2.0, thickness_units="screen"
        )
        self._failures = server.scene.add_line_segments(
            "/swarm/failures", _NO_SEGMENTS, FAILED_COLOR, thickness=3.0, thickness_units="screen"
        )
        self._links = server.scene.add_line_segments(
            "/swarm/links", _NO_SEGMENTS, LINK_COLOR, thickness=1.5, thickness_units="screen"
        )
        self._trails = server.scene.add_point_cloud(
            "/swarm/trails",
            np.zeros((1, 3), dtype=np.float32),
            (120, 120, 140),
            point_size=0.004,
            point_shape="circle",
            visible=False,
        )

    # ---- world -------------------------------------------------------------------------------
    def set_world(self, geometry: WorldGeometry, positions: np.ndarray | None = None) -> None:
        """Draw the floor, grid and overlay of a world, and frame the swarm at `positions`
        (N, 2) with the default camera and every open tab's camera."""
        with self._lock:
            self._view_box = view_box(positions, geometry)
            # robots (and their rings, headings, selection) drawn at a visible size
            self.geometry = dataclasses.replace(
                geometry, robot_radius=drawn_radius(self._view_box, geometry.robot_radius))
            self._robot_count = -1  # rebuild the robot and range meshes at the new size
            self._trail = None
        xmin, ymin, xmax, ymax = geometry.bounds
        width, depth = xmax - xmin, ymax - ymin
        centre = ((xmin + xmax) / 2, (ymin + ymax) / 2)
        scene = self.server.scene
        scene.add_grid(
            "/world/grid",
            width=width,
            height=depth,
            plane="xy",
            cell_size=max(width, depth) / 20,
            section_size=max(width, depth) / 4,
            position=(centre[0], centre[1], -0.0005),
        )
        if geometry.overlay_segments.size:
            scene.add_line_segments(
                "/world/overlay",
                _lift(geometry.overlay_segments, 0.001),
                (90, 90, 110),
                thickness=3.0,
                thickness_units="screen",
            )
        else:
            scene.add_line_segments("/world/overlay", _NO_SEGMENTS, (90, 90, 110), visible=False)
        self._aim_every_camera()

    def _aim_every_camera(self) -> None:
        """The default camera (new tabs) and every open tab's camera onto the view box."""
        if self.geometry is None or self._view_box is None:
            return
        initial = self.server.initial_camera
        position, look_at = camera_pose(self._view_box, self.geometry.height,
                                        fov=float(initial.fov))
        initial.position = position
        initial.look_at = look_at
        initial.up = (0.0, 0.0, 1.0)
        for client in list(self.server.get_clients().values()):
            self.aim_camera(client)

    def aim_camera(self, client: viser.ClientHandle) -> None:
        """Point this tab's camera at the world's area of interest, fitted to its canvas; again
        when the tab reports a canvas whose shape differs from the one aimed for (its real size
        arrives after it connects; a resized window)."""
        if client.client_id not in self._aimed_aspects:
            self._aimed_aspects[client.client_id] = ASSUMED_ASPECT

            @client.camera.on_update
            def _(camera: viser.CameraHandle) -> None:
                aimed = self._aimed_aspects.get(client.client_id)
                if aimed is None or camera.image_height <= 0:
                    return
                aspect = camera.image_width / camera.image_height
                if abs(aspect / aimed - 1.0) > REAIM_ASPECT_CHANGE:
                    self.aim_camera(client)  # (a camera the user moved is left alone)

        if self.geometry is None or self._view_box is None:
            return
        try:  # viser knows a tab's canvas once its first camera message has arrived
            aspect, fov = float(client.camera.aspect), float(client.camera.fov)
        except (AssertionError, ZeroDivisionError):
            aspect, fov = ASSUMED_ASPECT, float(self.server.initial_camera.fov)
        self._aimed_aspects[client.client_id] = aspect
        position, look_at = camera_pose(self._view_box, self.geometry.height, aspect, fov)
        with client.atomic():
            client.camera.up_direction = (0.0, 0.0, 1.0)
            client.camera.position = position
            client.camera.look_at = look_at

    # ---- toggles -------------------------------------------------------------------------------
    def set_toggles(
        self, links: bool | None = None, ranges: bool | None = None, trails: bool | None = None
    ) -> None:
        if links is not None:
            self.show_links = links
            self._links.visible = links
        if ranges is not None:
            self.show_ranges = ranges
            if self._range_rings is not None:
                self._range_rings.visible = ranges
        if trails is not None:
            self.show_trails = trails
            self._trails.visible = trails
        if self.last_frame is not None:
            self.draw(self.last_frame, resend_trail=True)

    # ---- per frame -------------------------------------------------------------------------------
    def draw(self, frame: SwarmFrame, resend_trail: bool = False) -> None:
        """Push one frame to every browser (one atomic batch of array updates)."""
        geometry = self.geometry
        if geometry is None:
            return
        with self._lock:
            self.last_frame = frame
            radius, z = geometry.robot_radius, geometry.height
            top = z + BODY_HEIGHT_RADII * radius + 0.0005
            positions = _lift(frame.positions, z)
            wxyzs = heading_quaternions(frame.headings)
            colors = led_colors_to_rgb(frame.led_colors)
            reframe = self._robots is not None and self._robot_count != frame.count
            if reframe:  # more or fewer robots: frame them all again (bounds and robots)
                self._view_box = view_box(frame.positions, geometry)
            with self.server.atomic():
                if self._robots is None or self._robot_count != frame.count:
                    self._build_robot_meshes(frame.count, geometry, wxyzs, positions, colors)
                else:
                    self._robots.batched_positions = positions
                    self._robots.batched_wxyzs = wxyzs
                    self._robots.batched_colors = colors
                    if self.show_ranges and self._range_rings is not None:
                        self._range_rings.batched_positions = _lift(frame.positions, z + 0.0003)
                self._headings.points = self._heading_segments(frame, radius, top)
                self._failures.points = (
                    circle_segments(frame.positions[frame.failed], radius * 1.35, top)
                    if frame.failed.any()
                    else _NO_SEGMENTS
                )
                if self.show_links:
                    self._links.points = (
                        _lift(frame.positions[frame.links], top)
                        if frame.links.shape[0]
                        else _NO_SEGMENTS
                    )
                self._sample_trail(frame, z + 0.0002, resend_trail)
            self._draw_selections(frame)
        if reframe:
            self._aim_every_camera()

    def _sample_trail(self, frame: SwarmFrame, z: float, resend: bool) -> None:
        """Keep one position sample every `TRAIL_SAMPLE_FRAMES` frames; send the trail only
        when a sample was added (or on request), and only while trails are shown."""
        count = frame.count
        if self._trail is None or self._trail.shape[1] != count:
            self._trail = np.empty((TRAIL_SAMPLES, count, 3), dtype=np.float32)
            self._trail[:] = _lift(frame.positions, z)  # unfilled samples sit on the robots
            self._trail_frames = 0
        added = self._trail_frames % TRAIL_SAMPLE_FRAMES == 0
        if added:
            slot = (self._trail_frames // TRAIL_SAMPLE_FRAMES) % TRAIL_SAMPLES
            self._trail[slot, :, :2] = frame.positions
        self._trail_frames += 1
        if self.show_trails and (added or resend):
            self._trails.points = self._trail.reshape(-1, 3)

    def _heading_segments(self, frame: SwarmFrame, radius: float, top: float) -> np.ndarray:
        segments = np.empty((frame.count, 2, 3), dtype=np.float32)
        segments[:, 0, :2] = frame.positions
        segments[:, 1, 0] = frame.positions[:, 0] + 1.1 * radius * np.cos(frame.headings)
        segments[:, 1, 1] = frame.positions[:, 1] + 1.1 * radius * np.sin(frame.headings)
        segments[:, :, 2] = top
        return segments

    def _build_robot_meshes(
        self,
        count: int,
        geometry: WorldGeometry,
        wxyzs: np.ndarray,
        positions: np.ndarray,
        colors: np.ndarray,
    ) -> None:
        """The robots' mesh and the range rings' mesh, built for `count` instances."""
        for handle in (self._robots, self._range_rings):
            if handle is not None:
                handle.remove()
        radius = geometry.robot_radius
        vertices, faces = cylinder_mesh(radius, BODY_HEIGHT_RADII * radius)
        self._robots = self.server.scene.add_batched_meshes_simple(
            "/swarm/robots",
            vertices,
            faces,
            batched_wxyzs=wxyzs,
            batched_positions=positions,
            batched_colors=colors,
            lod="off",
            cast_shadow=False,
            receive_shadow=False,
        )
        ring_vertices, ring_faces = ring_mesh(
            geometry.comm_range, RANGE_RING_WIDTH * geometry.comm_range
        )
        ring_positions = positions.copy()
        ring_positions[:, 2] = geometry.height + 0.0003
        self._range_rings = self.server.scene.add_batched_meshes_simple(
            "/swarm/ranges",
            ring_vertices,
            ring_faces,
            batched_wxyzs=np.tile(np.array([1.0, 0.0, 0.0, 0.0], dtype=np.float32), (count, 1)),
            batched_positions=ring_positions,
            batched_colors=RANGE_COLOR,
            lod="off",
            cast_shadow=False,
            receive_shadow=False,
            side="double",
            visible=self.show_ranges,
        )
        self._robot_count = count
        self._trail = None

        @self._robots.on_click
        def _(event: viser.SceneNodePointerEvent) -> None:
            index = event.instance_index
            if index is not None and self._on_robot_click is not None:
                self._on_robot_click(event.client, int(index))

    # ---- per-client selection ----------------------------------------------------------------
    # A click arrives on viser's thread while frames are drawn on the simulation thread: both
    # move the selection marks, and both would create `/selection/ring` if they found none (the
    # second creation removes the first handle, which the other thread then updates: "Cannot
    # assign to 'points' on a removed LineSegmentsHandle"). `_selection_lock` makes "find or
    # create, then update" one step.

    def select(self, client: viser.ClientHandle, index: int | None) -> None:
        with self._selection_lock:
            if index is None:
                self._selection.pop(client.client_id, None)
            else:
                self._selection[client.client_id] = index
            if self.last_frame is not None:
                self._draw_selection(client, self.last_frame)

    def forget_client(self, client_id: int) -> None:
        self._aimed_aspects.pop(client_id, None)
        with self._selection_lock:
            self._selection.pop(client_id, None)
            self._selection_marks.pop(client_id, None)

    def _draw_selections(self, frame: SwarmFrame) -> None:
        clients = self.server.get_clients()
        with self._selection_lock:
            for client_id in list(self._selection):
                client = clients.get(client_id)
                if client is not None:
                    self._draw_selection(client, frame)

    def _draw_selection(self, client: viser.ClientHandle, frame: SwarmFrame) -> None:
        """Move this tab's ring and label onto its robot (created once, then only updated);
        called with `_selection_lock` held."""
        index = self._selection.get(client.client_id)
        geometry = self.geometry
        marks = self._selection_marks.get(client.client_id)
        if marks is None:
            ring = client.scene.add_line_segments(
                "/selection/ring",
                _NO_SEGMENTS,
                SELECTION_COLOR,
                thickness=3.0,
                thickness_units="screen",
                visible=False,
            )
            label = client.scene.add_label("/selection/label", "", visible=False)
            marks = self._selection_marks[client.client_id] = (ring, label)
        ring, label = marks
        if index is None or geometry is None or index >= frame.count:
            ring.visible = label.visible = False
            return
        radius = geometry.robot_radius
        top = geometry.height + BODY_HEIGHT_RADII * radius + 0.001
        centre = frame.positions[index : index + 1]
        robot_id = frame.robot_ids[index] if index < len(frame.robot_ids) else index
        with client.atomic():
            ring.points = circle_segments(centre, radius * 1.7, top)
            label.text = f"robot {robot_id}"
            label.position = (float(centre[0, 0]), float(centre[0, 1]) + 2.2 * radius, top)
            ring.visible = label.visible = True


def led_colors_to_rgb(led_colors: np.ndarray) -> np.ndarray:
    """LED colours (0..1) as uint8 body colours; an LED that is off shows as light grey."""
    colors = np.asarray(led_colors, dtype=np.float32).copy()
    off = colors.max(axis=1) < 0.02
    colors[off] = LED_OFF_COLOR
    return (np.clip(colors, 0.0, 1.0) * 255).astype(np.uint8)
