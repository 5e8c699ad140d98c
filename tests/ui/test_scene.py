"""The scene without a browser: camera framing on world load, range rings, sampled trails.

Each test reads back what the viser handles would send, so it checks the arrays a browser gets.
"""

from __future__ import annotations

import contextlib
import math
import threading
from collections.abc import Iterator

import numpy as np
import pytest
import viser

from bbzide.ui.scene import (
    ASSUMED_ASPECT,
    TRAIL_SAMPLE_FRAMES,
    TRAIL_SAMPLES,
    SwarmScene,
    camera_pose,
    view_box,
)
from bbzide.ui.world_backend import SwarmFrame, WorldGeometry

#: A 36 m field with 10 m radios and 0.5 m drones flying at 5 m (the M300 world's scale).
FIELD = WorldGeometry(0.5, 10.0, (0.0, 0.0, 36.0, 36.0), np.zeros((0, 2, 2)), height=5.0)


def frame(step: int, positions: np.ndarray) -> SwarmFrame:
    count = len(positions)
    return SwarmFrame(
        step,
        positions,
        np.zeros(count),
        np.full((count, 3), 0.5),
        np.zeros(count, dtype=bool),
        np.zeros((0, 2), dtype=np.int32),
        list(range(count)),
    )


@pytest.fixture
def server() -> Iterator[viser.ViserServer]:
    server = viser.ViserServer(host="127.0.0.1", port=0, verbose=False)
    yield server
    server.stop()


def test_world_load_frames_the_whole_field_in_a_narrow_view(server: viser.ViserServer) -> None:
    corner = np.array([[2.0, 2.0], [4.0, 3.0], [3.0, 5.0]])  # a swarm at the rendezvous corner
    SwarmScene(server).set_world(FIELD, corner)
    look_at = np.asarray(server.initial_camera.look_at)
    position = np.asarray(server.initial_camera.position)
    np.testing.assert_allclose(look_at, [18.0, 18.0, 5.0])  # the field's centre, flight height
    assert view_box(corner, FIELD) == (-3.0, -3.0, 39.0, 39.0)  # field + 6 drone radii
    outside = np.array([[-10.0, 40.0]])  # a drone that flew off the field is framed too
    assert view_box(outside, FIELD) == (-13.0, -3.0, 39.0, 43.0)
    # the 42 m box fits the horizontal field of view of the tall, narrow default view
    fov = float(server.initial_camera.fov)
    height = position[2] - 5.0
    half_width_seen = height * math.tan(fov / 2) * ASSUMED_ASPECT
    assert half_width_seen == pytest.approx(1.1 * 21.0)
    wide = camera_pose(view_box(corner, FIELD), FIELD.height, aspect=2.0, fov=fov)[0]
    assert wide[2] < position[2]  # a wide view fits the box from closer


def test_robots_are_drawn_large_enough_to_see_and_click(server: viser.ViserServer) -> None:
    lab = WorldGeometry(0.05, 20.0, (0.0, 0.0, 6.0, 6.0), np.zeros((0, 2, 2)), height=1.0)
    scene = SwarmScene(server)
    scene.set_world(lab, np.array([[3.0, 3.0]]))
    assert scene.geometry is not None
    assert scene.geometry.robot_radius == pytest.approx(0.018 * (6.0 + 12 * 0.05))
    table = WorldGeometry(0.0165, 0.1, (0.0, 0.0, 1.0, 1.0), np.zeros((0, 2, 2)))
    scene.set_world(table, np.array([[0.0, 0.0], [1.0, 1.0]]))  # the whole table framed
    assert 0.0165 < scene.geometry.robot_radius < 0.025  # Kilobots stay apart on a 5 cm grid
    field_drone = FIELD.robot_radius
    scene.set_world(FIELD, np.array([[18.0, 18.0]]))
    assert scene.geometry.robot_radius == pytest.approx(max(field_drone, 0.018 * 42.0))


def test_a_small_swarm_in_a_large_world_is_framed_with_its_radio_neighbourhood() -> None:
    """25 Kilobots on a 5 cm lattice in the middle of the 1 m table: the camera frames them and
    one IR range around them (0.4 m), not the whole table, where they would be specks."""
    table = WorldGeometry(0.0165, 0.1, (-0.5, -0.5, 0.5, 0.5), np.zeros((0, 2, 2)))
    lattice = np.array([(x, y) for x in np.arange(-0.1, 0.11, 0.05)
                        for y in np.arange(-0.1, 0.11, 0.05)])
    assert view_box(lattice, table) == pytest.approx((-0.2, -0.2, 0.2, 0.2))
    scattered = np.array([[-0.4, -0.4], [0.4, 0.4]])  # a swarm over the table: all of it
    assert view_box(scattered, table) == pytest.approx((-0.599, -0.599, 0.599, 0.599))


def test_the_view_reframes_when_the_robot_count_changes(server: viser.ViserServer) -> None:
    scene = SwarmScene(server)
    scene.set_world(FIELD, np.array([[18.0, 18.0]]))
    before = np.asarray(server.initial_camera.position).copy()
    scene.draw(frame(0, np.array([[18.0, 18.0]])))
    far = np.array([[18.0, 18.0], [80.0, 18.0]])  # a new drone far east of the field
    scene.draw(frame(1, far))
    after = np.asarray(server.initial_camera.position)
    assert after[0] > before[0] and after[2] > before[2]  # moved east and up to see it


def test_range_rings_follow_the_robots(server: viser.ViserServer) -> None:
    scene = SwarmScene(server)
    scene.set_world(FIELD)
    rng = np.random.default_rng(3)
    scene.draw(frame(0, rng.uniform(0, 36, size=(20, 2))))
    scene.set_toggles(ranges=True)
    moved = rng.uniform(0, 36, size=(20, 2))
    scene.draw(frame(1, moved))
    rings = scene._range_rings
    assert rings is not None and rings.visible
    np.testing.assert_allclose(np.asarray(rings.batched_positions)[:, :2], moved, rtol=1e-6)
    scene.set_toggles(ranges=False)
    assert not rings.visible


def test_trails_sample_every_few_frames_into_a_fixed_buffer(server: viser.ViserServer) -> None:
    scene = SwarmScene(server)
    scene.set_world(FIELD)
    scene.set_toggles(trails=True)
    positions = np.array([[1.0, 1.0], [2.0, 2.0]])
    sent = []
    for step in range(2 * TRAIL_SAMPLES * TRAIL_SAMPLE_FRAMES):
        scene.draw(frame(step, positions + [step, 0.0]))
        sent.append(np.asarray(scene._trails.points).copy())
    assert all(points.shape == (TRAIL_SAMPLES * 2, 3) for points in sent[1:])
    # a new sample every TRAIL_SAMPLE_FRAMES frames; the frames between send nothing new
    changes = [k for k in range(1, len(sent)) if not np.array_equal(sent[k], sent[k - 1])]
    assert changes == list(range(TRAIL_SAMPLE_FRAMES, len(sent), TRAIL_SAMPLE_FRAMES))
    # the buffer holds the last TRAIL_SAMPLES samples of robot 0 (the points at y = 1)
    steps = len(sent)
    sampled = range(0, steps, TRAIL_SAMPLE_FRAMES)[-TRAIL_SAMPLES:]
    robot0 = sent[-1][sent[-1][:, 1] == 1.0]
    assert sorted(robot0[:, 0].tolist()) == [1.0 + s for s in sampled]


class _FakeHandle:
    """A scene handle that only keeps what is assigned to it."""

    def __init__(self, name: str) -> None:
        self.name = name


class _FakeClientScene:
    def __init__(self, on_first_ring: object) -> None:
        self.rings: list[_FakeHandle] = []
        self._on_first_ring = on_first_ring

    def add_line_segments(self, name: str, *args: object, **kwargs: object) -> _FakeHandle:
        ring = _FakeHandle(name)
        self.rings.append(ring)
        if len(self.rings) == 1:
            self._on_first_ring()  # type: ignore[operator]
        return ring

    def add_label(self, name: str, *args: object, **kwargs: object) -> _FakeHandle:
        return _FakeHandle(name)


class _FakeClient:
    client_id = 7

    def __init__(self, on_first_ring: object) -> None:
        self.scene = _FakeClientScene(on_first_ring)

    def atomic(self) -> contextlib.AbstractContextManager[None]:
        return contextlib.nullcontext()


class _WatchedLock:
    """A lock that says (through `settled`) when a thread has to wait for it."""

    def __init__(self, settled: threading.Event) -> None:
        self._lock = threading.Lock()
        self._settled = settled

    def __enter__(self) -> None:
        if not self._lock.acquire(blocking=False):
            self._settled.set()
            self._lock.acquire()

    def __exit__(self, *exc: object) -> None:
        self._lock.release()


def test_a_click_and_a_frame_create_one_selection_ring(
        server: viser.ViserServer, monkeypatch: pytest.MonkeyPatch) -> None:
    """While the click's thread is creating the tab's ring, a frame drawn on the simulation
    thread must wait for it instead of creating a second `/selection/ring` (which removes the
    first one, so the next update of the stored handle fails)."""
    scene = SwarmScene(server)
    scene.set_world(FIELD)
    positions = np.array([[1.0, 1.0], [5.0, 5.0], [9.0, 2.0]])
    scene.draw(frame(0, positions))
    settled = threading.Event()  # the frame's thread waits for the lock, or has finished
    frame_thread = threading.Thread(target=lambda: (scene.draw(frame(1, positions + 0.5)),
                                                    settled.set()))

    def draw_a_frame_meanwhile() -> None:
        frame_thread.start()
        settled.wait()

    client = _FakeClient(draw_a_frame_meanwhile)
    monkeypatch.setattr(server, "get_clients", lambda: {client.client_id: client})
    scene._selection_lock = _WatchedLock(settled)  # type: ignore[assignment]
    scene.select(client, 1)  # type: ignore[arg-type]
    frame_thread.join()
    assert [ring.name for ring in client.scene.rings] == ["/selection/ring"]
    ring = client.scene.rings[0]
    assert ring.visible is True
    np.testing.assert_allclose(ring.points.reshape(-1, 3)[:, :2].mean(axis=0), [5.5, 5.5],
                               atol=1e-6)  # moved by the frame drawn after the click
