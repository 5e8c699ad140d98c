"""Python-side cost of one scene update (SwarmScene.draw) for 100 and 1,000 robots.

Goal: <= 5 ms per update, so the 30 Hz frame budget leaves the simulation thread most of its
time. Measured without a browser attached (the websocket send runs on viser's own thread; the
ui-stack-notes found the same figures with a headless client connected). Each frame moves every
robot, turns it, changes LED colours, and has ~3 radio links per robot; "all overlays" adds the
range rings and trails, and "+ world" the world overlays drawn the way the replay draws them
every frame (`OverlayView.show` with the robots' positions): a 10 x 10 belief heat plane that
changes every 10th frame, 5 targets, and a relay tree of one link per 10 robots.

    PYTHONPATH=. python benchmarks/ui_bench.py
"""

from __future__ import annotations

import socket
import statistics
import time

import numpy as np
import viser

from bbzide.ui.overlay_view import OverlayView
from bbzide.ui.scene import SwarmScene
from bbzide.ui.world_backend import SwarmFrame, WorldGeometry

FRAMES = 150
GOAL_MS = 5.0


def free_port() -> int:
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        return probe.getsockname()[1]


def frames(count: int, rng: np.random.Generator) -> list[SwarmFrame]:
    out = []
    positions = rng.uniform(-0.5, 0.5, size=(count, 2))
    headings = rng.uniform(-np.pi, np.pi, size=count)
    for step in range(FRAMES):
        positions = positions + rng.normal(0, 0.001, size=positions.shape)
        headings = headings + 0.05
        links = rng.integers(0, count, size=(3 * count, 2)).astype(np.int32)
        colors = rng.uniform(0, 1, size=(count, 3))
        failed = rng.uniform(size=count) < 0.02
        out.append(
            SwarmFrame(
                step, positions.copy(), headings.copy(), colors, failed, links, list(range(count))
            )
        )
    return out


def world_overlays(count: int, step: int, rng: np.random.Generator) -> dict:
    """M300-like overlays as a world returns them: a fresh dict per poll."""
    belief = np.full((10, 10), 0.5) * (0.9 ** (step // 10))
    return {
        "belief_map": {"origin": [-0.5, -0.5], "cell": 0.1, "values": belief.tolist()},
        "targets": [[0.1 * k - 0.2, 0.3] for k in range(5)],
        "targets_found": [k < step // 50 for k in range(5)],
        "rendezvous": [-0.4, -0.4],
        "relay_links": [(k, k + 1) for k in range(0, count - 1, 10)],
    }


def measure(
    scene: SwarmScene, view: OverlayView, count: int, overlays: bool, world: bool
) -> list[float]:
    scene.set_toggles(links=True, ranges=overlays, trails=overlays)
    rng = np.random.default_rng(count)
    timings = []
    for frame in frames(count, rng):
        polled = world_overlays(count, frame.step, rng) if world else None
        started = time.perf_counter()
        scene.draw(frame)
        if world:
            view.show(polled, positions=frame.positions)
        timings.append((time.perf_counter() - started) * 1000)
    view.show(None)
    return timings[10:]  # the first frames build the mesh


def main() -> None:
    server = viser.ViserServer(host="127.0.0.1", port=free_port(), verbose=False)
    try:
        scene = SwarmScene(server)
        view = OverlayView(server)
        walls = np.array([[[-0.5, -0.5], [0.5, -0.5]], [[0.5, 0.5], [-0.5, 0.5]]])
        scene.set_world(WorldGeometry(0.0165, 0.1, (-0.5, -0.5, 0.5, 0.5), walls))
        print(f"{'robots':>7} {'overlays':>12} {'median ms':>10} {'p95 ms':>8} {'goal':>6}")
        for count in (100, 1000):
            for overlays, world in ((False, False), (True, False), (True, True)):
                timings = sorted(measure(scene, view, count, overlays, world))
                median = statistics.median(timings)
                p95 = timings[int(0.95 * len(timings))]
                verdict = "ok" if median <= GOAL_MS else "OVER"
                label = "all + world" if world else "all" if overlays else "links only"
                print(
                    f"{count:>7} {label:>12} {median:>10.2f} {p95:>8.2f} {verdict:>6}"
                    f"  ({median / GOAL_MS:.2f} of the {GOAL_MS:.0f} ms goal)"
                )
    finally:
        server.stop()


if __name__ == "__main__":
    main()
