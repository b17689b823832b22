"""The URDF gravity model in the auto-calibration: an SO-101 joint on the physics plant whose gravity is the URDF's
(in the profile's search pose), soft 15 N·m/rad stops; run_autocal with the URDF's model corrects the zero."""

from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path

import pytest

from robocal.backends.sim.physics import PlantParams, Scenario, make_plant
from robocal.core.gravity import GravityModel
from robocal.formats.profiles import load_profile
from robocal.formats.urdf_gravity import gravity_model_from_urdf
from robocal.workflows.autocal.job import AutoCalRequest, joint_gravity_for, run_autocal

from .test_acceptance import bench

DATA = Path(__file__).resolve().parents[2] / "src" / "robocal" / "data"


@pytest.fixture(scope="module")
def so101() -> GravityModel:
    return gravity_model_from_urdf(DATA / "so101_new_calib.urdf")


def _run(model: GravityModel, joint: str, z: float, *, correct: bool) -> tuple[float, float]:
    """Auto-calibrate ``joint`` on a plant whose frame is the URDF frame + z; return the zero and span errors."""
    profile = load_profile("so101_follower")
    assert profile.auto is not None
    aj = profile.auto.joint(joint)
    assert aj is not None
    section = replace(profile.auto, joints=(replace(aj, pose=aj.pose),))
    lo, hi = math.radians(aj.lower_deg or 0.0), math.radians(aj.upper_deg or 0.0)
    jg = joint_gravity_for(model, aj)
    assert jg is not None
    cap = aj.torque_cap_nm
    nominal = PlantParams(
        inertia_kgm2=0.004,
        coulomb_nm=0.03 * cap,
        stiction_nm=0.05 * cap,
        viscous_nms_rad=0.02 * cap,
        stop_lower_rad=lo + z,
        stop_upper_rad=hi + z,
        gravity_nm=jg.amplitude_nm,  # the URDF's τ_g(q) = −A·sin(q − hanging), in the plant frame q + z
        gravity_zero_rad=jg.hanging_rad + z,
        noise_rad=math.radians(0.02),
    )
    plant = make_plant(Scenario(soft_stop=True), nominal, search_torque_nm=cap, seed=3, q0_rad=z + 0.2)
    driver = bench.PlantDriver(joint, plant, cap)
    result = run_autocal(
        {joint: driver},
        AutoCalRequest(
            section, {joint: (lo, hi)}, max_lag_rad=bench.MAX_LAG_RAD, gravity_model=model if correct else None
        ),
    )
    out = result[joint]
    assert out.ok, out.stops.reason
    p = plant.params
    assert p.stop_lower_rad is not None and p.stop_upper_rad is not None
    ideal = 0.5 * (p.stop_lower_rad + p.stop_upper_rad) - 0.5 * (lo + hi)
    return out.stops.offset_rad - ideal, out.stops.span_rad - (p.stop_upper_rad - p.stop_lower_rad)


@pytest.mark.parametrize("z", [0.3, -0.2])
def test_urdf_gravity_corrects_a_soft_loaded_joint(so101: GravityModel, z: float) -> None:
    # the elbow in its search pose (shoulder_lift 0) carries 0.45 N·m at most; near its stops gravity pulls both
    # ways by different amounts, so on 15 N·m/rad stops the plain midpoint is off by ≈ 0.22°
    plain, plain_span = _run(so101, "elbow_flex", z, correct=False)
    fixed, fixed_span = _run(so101, "elbow_flex", z, correct=True)
    assert abs(plain) > math.radians(0.15)
    assert abs(fixed) < 0.2 * abs(plain)
    assert abs(fixed) < math.radians(0.05)
    assert abs(fixed_span) < abs(plain_span)


def test_joint_gravity_for_uses_the_profile_pose(so101: GravityModel) -> None:
    profile = load_profile("so101_follower")
    assert profile.auto is not None
    elbow = profile.auto.joint("elbow_flex")
    assert elbow is not None and dict(elbow.pose) == {"shoulder_lift": 0.0}
    jg = joint_gravity_for(so101, elbow)
    assert jg is not None and jg.amplitude_nm == pytest.approx(0.4528, abs=1e-3)
    pan = profile.auto.joint("shoulder_pan")
    assert pan is not None
    jp = joint_gravity_for(so101, pan)
    assert jp is not None and jp.amplitude_nm < 1e-5  # a vertical axis
    assert joint_gravity_for(None, elbow) is None
