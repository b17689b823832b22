"""``robocal demo --robot so101|koch --identify``: print the job's results (run by :mod:`robocal.workflows.demo.job`)."""

from __future__ import annotations

from ..workflows.demo.identify import IMAGES_INTRO, IdentifyDemo
from ._common import EXIT_WARNINGS, console, print_warning
from ._kinematics_print import print_identification, print_images

__all__ = ["print_identify_demo"]


def print_identify_demo(found: IdentifyDemo) -> int:
    """Print the identification, its check against the hidden truth and the image part; return the exit code.

    Returns:
        0 ok, 1 a warning (or the image part skipped).
    """
    code = print_identification(found.identification)
    console.print(found.truth_line)
    images = found.images
    if images is not None:
        console.print(IMAGES_INTRO)
        if images.skipped is not None:  # pragma: no cover - OpenCV missing
            print_warning(images.skipped)
            return max(code, EXIT_WARNINGS)
        assert images.result is not None
        console.print(images.camera_line)
        code = max(code, print_images(images.result))
        console.print(images.truth_line)
    return code
