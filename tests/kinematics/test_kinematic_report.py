"""workflows.kinematics.report: the report parts ``identify`` and ``identify_images`` share, on the SO-101 chain."""

from __future__ import annotations

import dataclasses
import json
import math
import types

import numpy as np

from robocal.workflows.kinematics.fit import PriorSigmas
from robocal.workflows.kinematics.report import (
    CONDITION_LIMIT,
    chain_summary,
    condition_warnings,
    error_stats,
    finite,
    origin_changed,
    prior_summary,
)

from .conftest import so101_model

MODEL = so101_model()


def test_error_stats_scales_mean_and_max_and_is_none_without_poses() -> None:
    assert error_stats(np.array([0.001, 0.003]), 1e3) == {"mean": 2.0, "max": 3.0}
    assert error_stats(np.array([0.5, 1.5, 4.0])) == {"mean": 2.0, "max": 4.0}
    assert error_stats(np.zeros(0), 1e3) is None


def test_chain_summary_names_links_and_joints_in_order() -> None:
    assert chain_summary(MODEL.chain) == {
        "base_link": "base_link",
        "tip_link": "gripper_link",
        "joints": ["shoulder_pan", "shoulder_lift", "elbow_flex", "wrist_flex", "wrist_roll"],
    }


def test_origin_changed_flags_only_the_moved_joint() -> None:
    chain = MODEL.chain
    elbow = next(j for j in chain.joints if j.name == "elbow_flex")
    moved = dataclasses.replace(elbow, origin_xyz_m=(elbow.origin_xyz_m[0] + 1e-6, *elbow.origin_xyz_m[1:]))
    new = dataclasses.replace(chain, joints=tuple(moved if j is elbow else j for j in chain.joints))
    assert origin_changed(chain, new) == {n: n == "elbow_flex" for n in chain.joint_names}
    assert not any(origin_changed(chain, chain).values())


def test_finite_replaces_nan_and_inf_by_none_at_any_depth() -> None:
    report = {"a": math.nan, "b": [1.0, math.inf, (2, -math.inf)], "c": {"d": "x", "e": 3}}
    cleaned = finite(report)
    assert cleaned == {"a": None, "b": [1.0, None, [2, None]], "c": {"d": "x", "e": 3}}
    assert json.loads(json.dumps(cleaned, allow_nan=False)) == cleaned


def test_condition_warnings_only_above_the_limit() -> None:
    def result(condition: float) -> object:
        obs = types.SimpleNamespace(condition=condition)
        return types.SimpleNamespace(identifiability=types.SimpleNamespace(observability=obs))

    assert CONDITION_LIMIT == 100.0
    assert condition_warnings(result(100.0), "move more") == []  # type: ignore[arg-type]
    assert condition_warnings(result(250.4), "move more") == [  # type: ignore[arg-type]
        "condition number 250 is above 100: move more"
    ]


def test_prior_summary_in_mm_and_degrees_with_noise_only_when_asked() -> None:
    prior = PriorSigmas(
        length_m=0.002, angle_rad=math.radians(0.5), offset_rad=math.radians(2.0), noise_m=0.0003
    )
    summary = prior_summary(prior, noise=True)
    assert summary is not None
    assert summary["length_mm"] == 2.0 and math.isclose(summary["angle_deg"], 0.5)
    assert math.isclose(summary["offset_deg"], 2.0) and math.isclose(summary["noise_mm"], 0.3)
    assert "noise_mm" not in (prior_summary(prior, noise=False) or {})
    assert prior_summary(dataclasses.replace(prior, noise_m=None), noise=True)["noise_mm"] is None  # type: ignore[index]
    assert prior_summary(None, noise=True) is None
