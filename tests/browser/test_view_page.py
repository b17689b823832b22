"""``robocal view``'s page in headless Chromium, as a person would check it: from pixels and from page state.

(a) the model moves when the simulated joint moves, (b) a joint with a flipped direction in ``--compare``
shows the ghost diverging, (c) a joint beyond its limit is drawn red.
"""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path
from typing import Any

import browserlib
import numpy as np
import pytest

from robocal.core.jointmap import RobotCalibration
from robocal.viewer import JointMapper, ViewerApp, load_robot_model

pytest.importorskip("viser", reason="viser comes with robocal[view]")

GREEN = (25, 150, 50)
ARM = f"""<?xml version="1.0"?>
<robot name="arm">
  <material name="green"><color rgba="{GREEN[0] / 255:.4f} {GREEN[1] / 255:.4f} {GREEN[2] / 255:.4f} 1"/></material>
  <link name="base"><visual><geometry><box size="0.12 0.12 0.04"/></geometry><material name="green"/></visual></link>
  <link name="upper">
    <visual><origin xyz="0 0 0.15"/><geometry><box size="0.05 0.05 0.3"/></geometry><material name="green"/></visual>
  </link>
  <link name="lower">
    <visual><origin xyz="0 0 0.12"/><geometry><box size="0.04 0.04 0.24"/></geometry><material name="green"/></visual>
  </link>
  <joint name="shoulder" type="revolute">
    <parent link="base"/><child link="upper"/><origin xyz="0 0 0.02"/><axis xyz="0 1 0"/>
    <limit lower="-1.5" upper="1.5" effort="1" velocity="1"/>
  </joint>
  <joint name="elbow" type="revolute">
    <parent link="upper"/><child link="lower"/><origin xyz="0 0 0.3"/><axis xyz="0 1 0"/>
    <limit lower="-2.0" upper="0.5" effort="1" velocity="1"/>
  </joint>
</robot>
"""
GHOST_SEEN = (188, 214, 255)
"""The translucent ghost (GHOST_RGB at 35 % over the white background), as it reaches the screen."""



@pytest.fixture
def arm_app(tmp_path: Path) -> Iterator[ViewerApp]:
    urdf = tmp_path / "arm.urdf"
    urdf.write_text(ARM)
    model = load_robot_model(urdf)
    names = model.actuated
    cal = JointMapper(names, RobotCalibration.identity(names), "calibration.yaml")
    flipped = JointMapper(
        names, RobotCalibration(names, [-1.0, 1.0], [0.0, 0.0]), "previous.yaml (shoulder flipped)"
    )
    app = ViewerApp(model, calibration=cal, compare=flipped, port=0, title="arm").start(loop=False)

    cam = app.server.initial_camera  # looking along +y at the arm's plane of motion (x right, z up)
    cam.position = (0.0, -1.1, 0.3)
    cam.look_at = (0.0, 0.0, 0.3)
    cam.up_direction = (0.0, 0.0, 1.0)
    try:
        yield app
    finally:
        app.stop()


def _show(app: ViewerApp, page: Any, q: tuple[float, float], t_s: float) -> dict[str, Any]:
    app.push(t_s, np.array(q))
    assert app.step()
    n = app.updates
    return browserlib.wait_state(page, lambda s: s["updates"] == n, what=f"page update {n}")


def _scene(page: Any, path: Path | None = None) -> np.ndarray:
    return browserlib.scene_region(page, browserlib.screenshot(page, path))


def _green(img: np.ndarray) -> np.ndarray:
    return browserlib.shade_mask(img, GREEN)


def test_model_moves_ghost_diverges_and_beyond_limit_is_red(
    page: Any, arm_app: ViewerApp, tmp_path: Path
) -> None:
    browserlib.open_viser(page, arm_app.url)

    # Rest pose: the robot and its ghost coincide.
    state = _show(arm_app, page, (0.0, 0.0), 0.0)
    assert [j["q"] for j in state["joints"]] == [0.0, 0.0]
    img0 = browserlib.wait_until(lambda: (im := _scene(page)) is not None and _green(im).sum() > 100 and im)
    c0 = browserlib.centroid(_green(img0))
    assert c0 is not None

    # (a) The simulated shoulder moves to +0.8 rad: the arm swings toward +x, to the right of the screen.
    state = _show(arm_app, page, (0.8, 0.0), 0.1)
    assert state["joints"][0]["q"] == pytest.approx(0.8) and state["joints"][0]["outside"] is False

    def swung() -> np.ndarray | None:
        im = _scene(page)
        c = browserlib.centroid(_green(im))
        return im if c is not None and c[0] > c0[0] + 25 else None

    img1 = browserlib.wait_until(swung, what="the green arm swinging right")
    assert browserlib.reddish_mask(img1).sum() < 20  # nothing is red while within the limits

    # (b) The ghost goes through a calibration with the shoulder's direction flipped: it swings the other
    # way, to the left, while the robot stays right.
    assert state["joints"][0]["q_compare"] == pytest.approx(-0.8)
    ghost = browserlib.color_mask(img1, GHOST_SEEN, tol=30)
    robot = _green(img1)
    cg, cr = browserlib.centroid(ghost), browserlib.centroid(robot)
    assert ghost.sum() > 300 and cg is not None and cr is not None
    assert cg[0] < c0[0] - 25 < cr[0]  # ghost left of the rest position, robot right of it
    browserlib.screenshot(page, browserlib.shot("view_ghost.png", tmp_path))

    # (c) The elbow goes beyond its upper limit (0.5 rad): its link is drawn red, the panel says so.
    state = _show(arm_app, page, (0.8, 1.2), 0.2)
    elbow = state["joints"][1]
    assert elbow["outside"] is True and elbow["color"] == "red" and state["joints"][0]["outside"] is False
    img2 = browserlib.wait_until(
        lambda: (
            (im := _scene(page, browserlib.shot("view_limit.png", tmp_path))) is not None
            and browserlib.reddish_mask(im).sum() > 300
            and im
        ),
        what="the elbow's link drawn red",
    )
    assert page.locator('tr.robocal-joint[data-joint="elbow"][data-outside="1"]').count() == 1
    assert page.locator('tr.robocal-joint[data-joint="shoulder"][data-outside="0"]').count() == 1
    # Only the lower link is red: the red pixels sit above the shoulder's green upper link.
    red = browserlib.centroid(browserlib.reddish_mask(img2))
    green = browserlib.centroid(_green(img2))
    assert red is not None and green is not None and red[1] < green[1]

    # Back within the limits: red again green.
    state = _show(arm_app, page, (0.8, 0.2), 0.3)
    assert state["joints"][1]["outside"] is False
    browserlib.wait_until(
        lambda: browserlib.reddish_mask(_scene(page)).sum() < 20, what="the red link back to green"
    )
