"""Calibration files in and out; validation happens here."""

from __future__ import annotations

from .calibration import FORMATS as FORMATS
from .calibration import CalibrationFile as CalibrationFile
from .calibration import detect_format as detect_format
from .calibration import read_calibration as read_calibration
from .calibration import write_calibration as write_calibration

__all__ = ["FORMATS", "CalibrationFile", "detect_format", "read_calibration", "write_calibration"]
