"""Calibration health, pure numpy (issue 30).

The leader/follower model (``model``), the dataset check (``offsets``), the follower's rest level (``level``) and the
sag-pattern fit (``sag``); the live monitor (``monitor``) sits
beside them. Importable with numpy alone (a control loop imports it); the monitor's public path is
:mod:`robocal.health`.
"""

from __future__ import annotations

from .ends import end_bands, end_raw_caps
from .level import RestLevel, rest_level
from .model import fitted_sag, model_band, sag_residual_deg, sag_slopes
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
    fitted_joint,
)
from .sag import SagFit, SagFrames, fit_sag_offsets, last_direction, loaded_joints, t_quantile

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
    "RestLevel",
    "SagFit",
    "SagFrames",
    "analyse_joint",
    "drift_reason",
    "end_bands",
    "end_raw_caps",
    "episode_verdicts",
    "fit_sag_offsets",
    "fitted_joint",
    "fitted_sag",
    "last_direction",
    "loaded_joints",
    "model_band",
    "monitor_config",
    "rest_level",
    "sag_residual_deg",
    "sag_slopes",
    "t_quantile",
]
