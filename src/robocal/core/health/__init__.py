"""Calibration health, pure numpy (issue 30).

The leader/follower model (``model``) and the dataset check (``offsets``); the live monitor (``monitor``) sits
beside them.
"""

from __future__ import annotations

from .model import feetech_kp_nm_rad, model_band, sag_residual_deg
from .offsets import (
    EndEvidence,
    HealthConfig,
    JointData,
    JointHealth,
    JumpEvent,
    analyse_joint,
    episode_verdicts,
)

__all__ = [
    "EndEvidence",
    "HealthConfig",
    "JointData",
    "JointHealth",
    "JumpEvent",
    "analyse_joint",
    "episode_verdicts",
    "feetech_kp_nm_rad",
    "model_band",
    "sag_residual_deg",
]
