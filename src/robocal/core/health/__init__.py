"""Calibration health, pure numpy (issue 30).

The leader/follower model (``model``) and the dataset check (``offsets``); the live monitor (``monitor``) sits
beside them. Importable with numpy alone (a control loop imports it); the monitor's public path is
:mod:`robocal.health`.
"""

from __future__ import annotations

from .model import feetech_kp_nm_rad, model_band, sag_offset_fit, sag_residual_deg
from .monitor import Monitor
from .monitor_types import FLAG_KINDS, HealthFlag, MonitorConfig, monitor_config
from .offsets import (
    EndEvidence,
    HealthConfig,
    JointData,
    JointHealth,
    JumpEvent,
    analyse_joint,
    drift_reason,
    episode_verdicts,
)

__all__ = [
    "FLAG_KINDS",
    "EndEvidence",
    "HealthConfig",
    "HealthFlag",
    "JointData",
    "JointHealth",
    "JumpEvent",
    "Monitor",
    "MonitorConfig",
    "analyse_joint",
    "drift_reason",
    "episode_verdicts",
    "feetech_kp_nm_rad",
    "model_band",
    "monitor_config",
    "sag_offset_fit",
    "sag_residual_deg",
]
