"""``robocal ur view`` in headless Chromium: the error number on the page is ``robocal ur verify``'s."""

from __future__ import annotations

import re
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import browserlib
import numpy as np
import pytest

from robocal.cli.main import main
from robocal.formats.ur_kinematics import read_dh
from robocal.viewer.ur_page import ARROW_RGB, CALIBRATED_RGB, UrViewModel, UrViewPage

pytest.importorskip("viser", reason="viser comes with robocal[view]")

FIXTURES = Path(__file__).resolve().parents[1] / "fixtures" / "ur"
DH_FILE = FIXTURES / "dh_ur_calibration_docs.yaml"  # a UR10e's calibration as ur_calibration documents it
Q = (0.1, -1.0, 1.2, 0.3, 0.5, 0.7)
Q_TEXT = ",".join(str(v) for v in Q)


def _verify_number(capsys: pytest.CaptureFixture[str], *args: str) -> str:
    """The ``max Δp (m)`` cell that ``robocal ur verify`` prints."""
    capsys.readouterr()
    assert main(["ur", "verify", *args]) == 1  # warns: the calibrated YAML differs from the nominal model
    out = capsys.readouterr().out
    row = next(line for line in out.splitlines() if "kinematics YAML" in line)
    cells = row.split()
    return cells[-3]  # ... samples, max Δp, max Δrot, hash


@pytest.fixture
def ur_page() -> Iterator[UrViewPage]:
    page = UrViewPage(UrViewModel(read_dh(DH_FILE), "ur10e"), source=str(DH_FILE), q_rad=Q, port=0).start()
    try:
        yield page
    finally:
        page.stop()


def test_page_error_numbers_equal_ur_verify(
    page: Any, ur_page: UrViewPage, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    cal = tmp_path / "cal.yaml"
    assert main(["ur", "correct", "--dh", str(DH_FILE), "--out", str(cal)]) == 0
    at_q = _verify_number(capsys, str(cal), "--model", "ur10e", "--q", Q_TEXT)
    over_samples = _verify_number(capsys, str(cal), "--model", "ur10e")
    assert re.fullmatch(r"0\.00\d+", at_q) and re.fullmatch(r"0\.00\d+", over_samples)  # millimetres, not 0

    browserlib.open_viser(page, ur_page.url)
    state = browserlib.wait_state(page, lambda s: s["view"] == "ur" and s["q"] == list(Q))
    # The numbers shown in the panel, as a person reads them, and in the page state.
    assert browserlib.gui_value(page, "Δp at q (m)") == at_q
    assert browserlib.gui_value(page, "max Δp, 1000 samples (m)") == over_samples
    assert state["error_text"] == at_q and state["verify"]["text"] == over_samples
    assert float(browserlib.gui_value(page, "Δp at q (mm)") or "nan") == pytest.approx(
        float(at_q) * 1e3, rel=5e-3
    )

    # The scaled arrow and both arms are drawn.
    img = browserlib.scene_region(page, browserlib.screenshot(page, browserlib.shot("view_ur.png", tmp_path)))
    assert browserlib.shade_mask(img, ARROW_RGB).sum() > 30
    orange = browserlib.shade_mask(img, CALIBRATED_RGB)
    assert orange.sum() > 200
    before = browserlib.centroid(orange)

    # Moving a joint slider in the page moves the calibrated arm and changes the number to ur verify's there.
    _type_slider(page, "shoulder_lift_joint", "-2")
    q2 = (Q[0], -2.0, *Q[2:])
    state = browserlib.wait_state(page, lambda s: s["q"][1] == -2.0)
    at_q2 = _verify_number(capsys, str(cal), "--model", "ur10e", "--q", ",".join(str(v) for v in q2))
    assert at_q2 != at_q
    assert state["error_text"] == at_q2
    browserlib.wait_until(lambda: browserlib.gui_value(page, "Δp at q (m)") == at_q2, what="the new Δp")

    def moved() -> bool:
        img2 = browserlib.scene_region(page, browserlib.screenshot(page))
        c = browserlib.centroid(browserlib.shade_mask(img2, CALIBRATED_RGB))
        return (
            c is not None and before is not None and float(np.hypot(c[0] - before[0], c[1] - before[1])) > 10
        )

    browserlib.wait_until(moved, what="the calibrated arm moving on the canvas")


def _type_slider(page: Any, label: str, value: str) -> None:
    """Type ``value`` into the number box of viser's slider labelled ``label`` and press Enter."""
    row = page.locator(".mantine-Flex-root", has=page.locator("label", has_text=label)).last
    box = row.locator("input:not([type=range]):not([type=hidden])").last
    box.fill(value)
    box.press("Enter")


