"""The browser harness itself, on a tiny viser scene started here: pixels and page state follow the server."""

from __future__ import annotations

import json
from collections.abc import Iterator
from typing import Any

import browserlib
import numpy as np
import pytest

viser = pytest.importorskip("viser", reason="viser comes with robocal[view]")


@pytest.fixture
def scene() -> Iterator[Any]:
    server = viser.ViserServer(host="127.0.0.1", port=0, verbose=False)
    server.gui.configure_theme(show_logo=False)
    server.scene.set_up_direction("+z")
    server.scene.configure_environment_map(hdri=None)  # image-based lighting: ~20 s per load on SwiftShader
    server.scene.add_light_ambient("/ambient", intensity=1.0)
    server.scene.add_light_directional("/sun", intensity=2.0, position=(1.0, -3.0, 4.0))
    box = server.scene.add_box(
        "/box", color=(230, 20, 20), dimensions=(0.6, 0.6, 0.6), position=(0.0, 0.0, 0.0)
    )
    value = server.gui.add_text("value", initial_value="0.000", disabled=True)
    state = server.gui.add_html('<div id="robocal-status" data-status=\'{"seq": 0}\'></div>')

    @server.on_client_connect
    def _(client: Any) -> None:
        client.camera.position = (0.0, -4.0, 0.0)
        client.camera.look_at = (0.0, 0.0, 0.0)
        client.camera.up_direction = (0.0, 0.0, 1.0)

    def publish(seq: int, x: float) -> None:
        box.position = (x, 0.0, 0.0)
        value.value = f"{x:.3f}"
        state.content = f"<div id=\"robocal-status\" data-status='{json.dumps({'seq': seq, 'x': x})}'></div>"

    try:
        yield server, publish
    finally:
        server.stop()


def test_pixels_and_page_state_follow_the_server(page: Any, scene: Any) -> None:
    server, publish = scene
    browserlib.open_viser(page, f"http://127.0.0.1:{server.get_port()}")
    browserlib.wait_state(page, lambda s: s["seq"] == 0)

    def red_centroid() -> tuple[float, float] | None:
        img = browserlib.scene_region(page, browserlib.screenshot(page))
        mask = browserlib.reddish_mask(img)
        return browserlib.centroid(mask) if mask.sum() > 500 else None

    x0, _ = browserlib.wait_until(red_centroid, what="the red box on the canvas")

    publish(1, 0.8)  # the box moves to +x: to the right of the screen, seen from -y with z up
    state = browserlib.wait_state(page, lambda s: s["seq"] == 1)
    assert state["x"] == pytest.approx(0.8)
    assert browserlib.gui_value(page, "value") == "0.800"
    x1, _ = browserlib.wait_until(
        lambda: (c := red_centroid()) and c[0] > x0 + 30 and c, what="the box moving right"
    )
    assert x1 > x0 + 30

    publish(2, -0.8)
    browserlib.wait_state(page, lambda s: s["seq"] == 2)
    x2, _ = browserlib.wait_until(
        lambda: (c := red_centroid()) and c[0] < x0 - 30 and c, what="the box moving left"
    )
    assert x2 < x0 - 30
    assert browserlib.gui_value(page, "value") == "-0.800"
    assert browserlib.gui_value(page, "no such control") is None


def test_color_helpers() -> None:
    img = np.zeros((4, 4, 3), dtype=np.uint8)
    img[1, 2] = (200, 30, 40)
    img[3, 0] = (200, 180, 170)  # light, not red
    assert browserlib.reddish_mask(img).sum() == 1
    assert browserlib.centroid(browserlib.reddish_mask(img)) == (2.0, 1.0)
    assert browserlib.color_mask(img, (205, 25, 45), tol=10).sum() == 1
    assert browserlib.centroid(np.zeros((2, 2), dtype=bool)) is None
