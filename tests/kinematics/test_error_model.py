"""core.kinematic_errors: exact Jacobian, corrected chains, rpy kept near the nominal triple."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from robocal.core.chain import fk_chain
from robocal.core.kinematic_errors import ErrorModel, rpy_near, so3_right_jacobian
from robocal.core.se3 import matrix_from_rotvec, matrix_from_rpy_urdf

from .conftest import so101_model

MODEL = so101_model()


def test_parameter_layout() -> None:
    names = MODEL.names
    assert len(names) == 6 + 5 * 7 + 6 == 47
    assert names[:7] == ("base.x", "base.y", "base.z", "base.rx", "base.ry", "base.rz", "shoulder_pan.offset")
    assert names[-6:] == ("tool.x", "tool.y", "tool.z", "tool.rx", "tool.ry", "tool.rz")
    assert MODEL.parameters[MODEL.index("elbow_flex.offset")].unit == "rad"


@pytest.mark.slow
@given(st.integers(0, 2**32 - 1))
def test_jacobian_matches_central_differences(seed: int) -> None:
    rng = np.random.default_rng(seed)
    lo, up = MODEL.chain.limits()
    q = rng.uniform(lo, up, (4, 5))
    x = rng.normal(0.0, 0.05, MODEL.n_params)
    _, J = MODEL.point_jacobian(q, x)
    h = 1e-6
    for i in range(MODEL.n_params):
        e = np.zeros(MODEL.n_params)
        e[i] = h
        num = (MODEL.points(q, x + e) - MODEL.points(q, x - e)) / (2 * h)
        np.testing.assert_allclose(J[:, :, i], num, atol=2e-9, err_msg=MODEL.names[i])


def test_nominal_points_are_fk_times_tool() -> None:
    q = np.array([[0.1, -0.2, 0.3, 0.4, -0.5]])
    T = fk_chain(MODEL.chain, q) @ MODEL.T_tip_tool
    np.testing.assert_allclose(MODEL.points(q), T[:, :3, 3], atol=1e-15)


def test_corrected_chain_reproduces_points_with_offsets_folded() -> None:
    rng = np.random.default_rng(3)
    x = rng.normal(0.0, 0.02, MODEL.n_params)
    q = rng.uniform(-1, 1, (20, 5))
    chain, T_wb, T_tt = MODEL.corrected(x)
    p = (T_wb @ fk_chain(chain, q) @ T_tt)[:, :3, 3]
    np.testing.assert_allclose(p, MODEL.points(q, x), atol=1e-14)
    # without folding, the offsets must be added to the readings
    chain2, _, _ = MODEL.corrected(x, fold_offsets=False)
    off = np.array(list(MODEL.offsets(x).values()))
    p2 = (T_wb @ fk_chain(chain2, q + off) @ T_tt)[:, :3, 3]
    np.testing.assert_allclose(p2, p, atol=1e-14)


def test_rpy_near_keeps_the_nominal_triple() -> None:
    ref = np.array([3.14159, 4.18253e-17, -3.14159])  # SO-101 shoulder_pan
    R = matrix_from_rpy_urdf(ref) @ matrix_from_rotvec([1e-3, 0, 0])
    out = rpy_near(R, ref)
    np.testing.assert_allclose(matrix_from_rpy_urdf(out), R, atol=1e-14)
    assert np.max(np.abs(out - ref)) < 2e-3


def test_so3_right_jacobian_identity() -> None:
    r = np.array([0.3, -0.2, 0.5])
    d = np.array([1e-7, 2e-7, -1e-7])
    lhs = matrix_from_rotvec(r + d)
    rhs = matrix_from_rotvec(r) @ matrix_from_rotvec(so3_right_jacobian(r) @ d)
    np.testing.assert_allclose(lhs, rhs, atol=1e-13)
    np.testing.assert_allclose(so3_right_jacobian(np.zeros(3)), np.eye(3))


def test_prismatic_offset_column() -> None:
    from robocal.core.chain import ChainJoint, SerialChain

    chain = SerialChain(
        (
            ChainJoint("rot", "revolute", "b", "l1", axis=(0.0, 0.0, 1.0)),
            ChainJoint(
                "slide", "prismatic", "l1", "l2", (0.1, 0.0, 0.0), axis=(1.0, 0.0, 0.0), lower=0, upper=1
            ),
        ),
        "b",
        "l2",
    )
    model = ErrorModel(chain)
    p, J = model.point_jacobian([[math.pi / 2, 0.2]])
    np.testing.assert_allclose(p[0], [0.0, 0.3, 0.0], atol=1e-15)
    np.testing.assert_allclose(J[0, :, model.index("slide.offset")], [0.0, 1.0, 0.0], atol=1e-15)
    np.testing.assert_allclose(J[0, :, model.index("rot.offset")], [-0.3, 0.0, 0.0], atol=1e-15)
