"""Calibration files: read, write and detect every joint-map format robocal converts between.

=====================  ==========================================================================================
``lite-json``          Lite-Lowlevel-Python ``calibration.json``: ``{joint: {id, direction, homing_offset}}``
``lite-yaml``          Humanoid-Control ``calibration.yaml``, same schema; updated in place keeping comments
``berkeley-offsets``   Berkeley-Humanoid-Lite-Lowlevel ``{"position_offsets": [...]}``: joint-frame, positional
``ros2-transmission``  URDF ``<transmission>`` with ``SimpleTransmission`` (``mechanical_reduction``, ``offset``)
``lerobot-legacy``     LeRobot legacy array JSON (read only); DEGREE joints convert exactly
``robocal``            robocal's canonical joint map YAML (direction, homing_offset, scale per joint)
=====================  ==========================================================================================

One module per format (``lite_json``, ``lite_yaml``, ``berkeley``, ``transmission``, ``lerobot_legacy``,
``canonical``), each defining a ``SPEC``; :mod:`.registry` maps names, suffixes and content sniffing to them and
is the only path callers use. Every reader validates the whole file before returning; every writer validates
before writing, writes atomically and keeps ``NAME.bak``.
"""

from __future__ import annotations

from ._base import CalibrationFile, FormatSpec, Traits
from .registry import FORMATS, detect_format, read_calibration, read_existing_output, write_calibration

__all__ = [
    "FORMATS",
    "CalibrationFile",
    "FormatSpec",
    "Traits",
    "detect_format",
    "read_calibration",
    "read_existing_output",
    "write_calibration",
]
