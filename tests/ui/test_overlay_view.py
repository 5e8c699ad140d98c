"""Overlay drawing rules: fields as images (y up), targets, relay links; unchanged data is free."""

from __future__ import annotations

import numpy as np
import viser

from bbzide.ui.overlay_view import HIGH_COLOR, LOW_COLOR, OverlayView, field_image


def test_field_rows_go_bottom_up_and_colours_span_the_ramp() -> None:
    values = np.array([[0.0, 0.0], [1.0, 1.0]])  # row 0 is the lowest y
    image = field_image(values)
    assert image.shape == (2, 2, 3) and image.dtype == np.uint8
    assert image[0, 0].tolist() == HIGH_COLOR.astype(np.uint8).tolist()  # top of the image
    assert image[1, 0].tolist() == LOW_COLOR.astype(np.uint8).tolist()


def test_overlays_by_shape_and_removal() -> None:
    server = viser.ViserServer(host="127.0.0.1", port=0, verbose=False)
    try:
        view = OverlayView(server)
        overlays = {
            "belief": {"bounds": (0, 0, 2, 1), "values": np.full((4, 8), 0.5)},
            "targets": [{"position": (0.5, 0.5), "found": True}, (1.5, 0.2)],
            "relay_links": [((0, 0), (1, 1))],
            "ceiling": 3.0,  # not drawable: ignored
        }
        view.show(overlays)
        assert sorted(view._handles) == [
            "/overlays/belief",
            "/overlays/relay_links",
            "/overlays/targets",
        ]
        colors = np.asarray(view._handles["/overlays/targets"].colors)
        assert colors[0].tolist() == [40, 170, 70] and colors[1].tolist() == [220, 50, 50]
        view.show({"targets": overlays["targets"]})
        assert sorted(view._handles) == ["/overlays/targets"]
    finally:
        server.stop()


def test_m300_style_overlays_origin_cell_flags_and_index_links() -> None:
    server = viser.ViserServer(host="127.0.0.1", port=0, verbose=False)
    try:
        view = OverlayView(server)
        overlays = {
            "belief_map": {"origin": [0.0, 0.0], "cell": 5.0, "values": [[0.1, 0.9]] * 3},
            "targets": [[10.0, 5.0], [2.0, 2.0]],
            "targets_found": [False, True],
            "relay_links": [(2, 0), (1, 2)],
        }
        positions = np.array([[0.0, 0.0], [1.0, 1.0], [2.0, 0.0]])
        view.show(overlays, positions=positions)
        image = view._handles["/overlays/belief_map"]
        assert (image.render_width, image.render_height) == (10.0, 15.0)
        colors = np.asarray(view._handles["/overlays/targets"].colors)
        assert colors[0].tolist() == [220, 50, 50] and colors[1].tolist() == [40, 170, 70]
        segments = np.asarray(view._handles["/overlays/relay_links"].points)[:, :, :2]
        np.testing.assert_allclose(segments, [[[2, 0], [0, 0]], [[1, 1], [2, 0]]])
    finally:
        server.stop()


def test_only_changes_are_sent_markers_scale_and_the_toggle_hides() -> None:
    server = viser.ViserServer(host="127.0.0.1", port=0, verbose=False)
    try:
        view = OverlayView(server)
        view.set_scale(0.5)  # M300 drones: targets 2 m across in a 36 m field

        def m300(found: bool) -> dict:  # a fresh dict each poll, as worlds return them
            return {
                "belief_map": {"origin": [0.0, 0.0], "cell": 3.6, "values": [[0.2] * 10] * 10},
                "targets": [[10.0, 5.0]],
                "targets_found": [found],
                "rendezvous": [1.0, 2.0],
                "relay_links": [(0, 1)],
            }

        positions = np.array([[0.0, 0.0], [4.0, 3.0]])
        view.show(m300(False), positions=positions)
        image = view._handles["/overlays/belief_map"]
        targets = view._handles["/overlays/targets"]
        assert targets.point_size == 2.0
        assert image.image.shape[0] >= 128  # 10 x 10 cells drawn as crisp 13 px squares
        np.testing.assert_allclose(view._handles["/overlays/rendezvous"].points[0, :2], [1, 2])
        view.show(m300(False), positions=positions + 1.0)
        assert view._handles["/overlays/belief_map"] is image  # same values: not re-sent
        assert view._handles["/overlays/targets"] is targets
        links = np.asarray(view._handles["/overlays/relay_links"].points)[:, :, :2]
        np.testing.assert_allclose(links, [[[1, 1], [5, 4]]])  # links follow the robots
        view.show(m300(True), positions=positions)
        assert view._handles["/overlays/targets"] is not targets  # found: redrawn green
        view.set_visible(False)
        assert not any(handle.visible for handle in view._handles.values())
        view.show({**m300(True), "other_links": [(1, 0)]}, positions=positions)
        assert not view._handles["/overlays/other_links"].visible
    finally:
        server.stop()
