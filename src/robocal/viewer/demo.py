"""``robocal demo --view``: the simulated Lite, calibrated by the sweep demo, shown in the browser."""

from __future__ import annotations

from importlib import resources
from pathlib import Path

from .session import ViewOptions

__all__ = ["LITE_SHAPES_URDF", "lite_shapes_urdf", "lite_view_options"]

LITE_SHAPES_URDF = "lite_bimanual_shapes.urdf"
"""The Lite example URDF with simple-shape visuals, shipped in ``robocal/data``."""


def lite_shapes_urdf() -> Path:
    """Path of the shipped simple-shape Lite URDF."""
    return Path(str(resources.files("robocal") / "data" / LITE_SHAPES_URDF))


def lite_view_options(
    calibration: Path, source: str, *, host: str = "127.0.0.1", port: int = 8080
) -> ViewOptions:
    """View options for the simulated Lite posed through ``calibration``, the uncalibrated robot as the ghost.

    Args:
        calibration: The calibration the sweep demo wrote.
        source: The demo's simulated robot (the same seed, so the same factory zeros the sweep found).
        host: Interface to serve on.
        port: TCP port.
    """
    return ViewOptions(
        urdf=lite_shapes_urdf(),
        source=source,
        calibration=calibration,
        compare="none",
        host=host,
        port=port,
        keep_moving=True,
    )
