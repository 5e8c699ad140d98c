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
        assert sorted(view._handles) == ["/overlays/belief", "/overlays/relay_links",
                                         "/overlays/targets"]
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
