"""Calibration health (issue 30), the public facade: the live monitor for a control loop.

>>> import numpy as np
>>> from robocal.health import Monitor, monitor_config
>>> monitor = Monitor(monitor_config(["shoulder_pan"], [-1.9], [1.9], max_speed_rad_s=6.0))
>>> monitor.update(0.00, np.array([0.50]))
()
>>> monitor.update(0.02, np.array([2.10]))[0].message
'shoulder_pan: reading +120.32° is past its stop (+110.86° with the margin)'

Only re-exports: the logic lives in :mod:`robocal.core.health` (numpy alone). See ``docs/health.md``.
"""

from __future__ import annotations

from ..core.health import FLAG_KINDS, HealthFlag, Monitor, MonitorConfig, monitor_config

__all__ = ["FLAG_KINDS", "HealthFlag", "Monitor", "MonitorConfig", "monitor_config"]
