"""The joint bounds planned poses are drawn in: URDF limits shrunk by a margin (points and tag plans alike)."""

from __future__ import annotations

import numpy as np
import pytest

from robocal.errors import UsageError
from robocal.formats.urdf import read_urdf
from robocal.formats.urdf_chain import chain_from_urdf
from robocal.workflows.kinematics.plan import sampling_bounds

from .conftest import SO101_URDF


def test_bounds_are_the_limits_shrunk_by_the_margin_and_a_too_wide_margin_names_the_joint() -> None:
    chain = chain_from_urdf(read_urdf(str(SO101_URDF)), tip_link="gripper_link")
    lo, up = sampling_bounds(chain, 0.1)
    lim_lo, lim_up = chain.limits()
    np.testing.assert_allclose(lo, np.asarray(lim_lo) + 0.1)
    np.testing.assert_allclose(up, np.asarray(lim_up) - 0.1)
    narrowest = chain.joint_names[int(np.argmin(np.asarray(lim_up) - np.asarray(lim_lo)))]
    margin = 0.5 * float(np.min(np.asarray(lim_up) - np.asarray(lim_lo))) + 0.01
    with pytest.raises(UsageError, match=rf"joint {narrowest}: its range is narrower than twice the"):
        sampling_bounds(chain, margin)


def test_touch_plans_draw_their_starts_inside_the_same_bounds(tmp_path) -> None:
    """A touch plan's random starts come from the same bounds: a margin wider than a joint's range is refused."""
    from robocal.workflows.kinematics.plan import PlanRequest, plan

    chain = chain_from_urdf(read_urdf(str(SO101_URDF)), tip_link="gripper_link")
    lim_lo, lim_up = (np.asarray(v) for v in chain.limits())
    narrowest = chain.joint_names[int(np.argmin(lim_up - lim_lo))]
    margin = 0.5 * float(np.min(lim_up - lim_lo)) + 0.01
    out = tmp_path / "plan.csv"
    with pytest.raises(UsageError, match=rf"joint {narrowest}: its range is narrower than twice the"):
        plan(PlanRequest(
            SO101_URDF, out, kind="touch", tip_link="gripper_link", touch_points_m=[(0.2, 0.0, 0.1)],
            margin_rad=margin, poses=10,
        ))  # fmt: skip
    assert not out.exists()
