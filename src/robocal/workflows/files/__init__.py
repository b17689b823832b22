"""Calibration files: ``robocal convert`` and ``robocal check`` (entry points in :mod:`job`)."""
