"""``lerobot calibrate --auto`` corrects the stops with the arm's URDF gravity model (issue 11).

The simulated SO-101 carries its shipped URDF's weight (``so101_new_calib.urdf``'s masses, each joint in its
profile search pose); on soft stops the elbow sinks into its stops by ``τ_g/k`` and the plain midpoint is off.
``--port sim`` gives the correction the same URDF by default, ``--urdf`` names one for a real arm.
"""

from __future__ import annotations

import math
from pathlib import Path

import pytest

from robocal.cli.main import main
from robocal.workflows.autocal.job import joint_gravity_for
from robocal.workflows.lerobot import robot_spec
from robocal.workflows.lerobot.auto import AutoCalibrationRequest, auto_calibrate, auto_section
from robocal.workflows.lerobot.auto_sim import auto_gravity_model, open_auto_arm, sim_gravity_model

pytestmark = pytest.mark.timeout(600)

DATA = Path(__file__).resolve().parents[2] / "src" / "robocal" / "data"
PORT = "sim?seed=1&soft=elbow_flex&gravity=elbow_flex&transport=inproc"  # the pty's packets, no polling


def _run(with_gravity: bool) -> tuple[object, float]:
    """elbow_flex on soft stops: its outcome and the ideal offset (driver frame) from the simulator's truth."""
    spec = robot_spec("so101_follower")
    section = auto_section("so101_follower")
    model = sim_gravity_model(spec) if with_gravity else None
    with open_auto_arm(spec, PORT, section) as arm:
        res = auto_calibrate(
            arm.bus,
            AutoCalibrationRequest(
                spec,
                section,
                joints=["elbow_flex"],
                gravity_model=model,
            ),
            clock=arm.clock,
        )
        plant = arm.plants["elbow_flex"]  # type: ignore[index]
        t = arm.sim.truth["elbow_flex"]
    per_rad = 4096 / (2 * math.pi)
    p = plant.params
    true_mid = t.mid_ticks / per_rad + 0.5 * (p.stop_lower_rad + p.stop_upper_rad)  # the contact surfaces
    joint = section.joint("elbow_flex")
    assert joint is not None and joint.lower_deg is not None and joint.upper_deg is not None
    ideal = true_mid - math.radians(0.5 * (joint.lower_deg + joint.upper_deg))
    return res.auto["elbow_flex"], ideal


def _wrap(x: float) -> float:
    return (x + math.pi) % (2 * math.pi) - math.pi


@pytest.mark.slow
def test_gravity_model_moves_the_zero_by_the_sink_into_the_stops() -> None:
    plain, ideal = _run(False)
    fixed, ideal2 = _run(True)
    assert ideal == ideal2  # the same seeded arm
    assert plain.ok and fixed.ok  # type: ignore[attr-defined]
    ps, fs = plain.stops, fixed.stops  # type: ignore[attr-defined]
    lo, hi = ps.lower, ps.upper
    assert math.isfinite(lo.stiffness_nm_per_rad) and math.isfinite(hi.stiffness_nm_per_rad)
    # the correction: each stop less τ_g(q_joint)/k̂, τ_g the URDF's in the profile pose (shoulder_lift 0)
    jg = joint_gravity_for(
        sim_gravity_model(robot_spec("so101_follower")), auto_section("so101_follower").joint("elbow_flex")
    )  # type: ignore[arg-type]
    assert jg is not None
    sink_lo = jg(lo.q_stop_rad - ps.offset_rad) / lo.stiffness_nm_per_rad
    sink_hi = jg(hi.q_stop_rad - ps.offset_rad) / hi.stiffness_nm_per_rad
    expected_shift = -0.5 * (sink_lo + sink_hi)
    assert abs(math.degrees(expected_shift)) > 0.05  # a visible effect on 15 N·m/rad stops
    assert fs.offset_rad - ps.offset_rad == pytest.approx(expected_shift, abs=math.radians(0.005))
    assert fs.span_rad - ps.span_rad == pytest.approx(-(sink_hi - sink_lo), abs=math.radians(0.005))
    # and the corrected zero is the truer one
    err_plain, err_fixed = abs(_wrap(ps.offset_rad - ideal)), abs(_wrap(fs.offset_rad - ideal))
    assert err_fixed < 0.7 * err_plain  # measured: 0.15° → 0.08°
    assert math.degrees(err_fixed) < 0.1


def test_urdf_option_resolution() -> None:
    spec = robot_spec("so101_follower")
    section = auto_section("so101_follower")
    assert auto_gravity_model(spec, "/dev/ttyACM0", section, None) is None  # a real arm without --urdf
    sim = auto_gravity_model(spec, "sim?seed=2", section, None)
    assert sim is not None and "elbow_flex" in sim.joint_names
    given = auto_gravity_model(spec, "/dev/ttyACM0", section, DATA / "so101_new_calib.urdf")
    assert given is not None and given.joint_names == sim.joint_names
    koch = robot_spec("koch_follower")
    assert (
        auto_gravity_model(koch, "sim", auto_section("koch_follower"), None) is None
    )  # koch.urdf: no masses


@pytest.mark.parametrize(
    ("extra", "message"),
    [
        (["--urdf", str(DATA / "so101_new_calib.urdf")], "--urdf only apply with --auto"),
        (["--auto", "--yes", "--urdf", str(DATA / "koch.urdf")], "no link has an <inertial> mass"),
        (
            ["--auto", "--yes", "--urdf", str(DATA / "lite_bimanual_shapes.urdf")],
            "no link has an <inertial> mass",
        ),
    ],
)
def test_bad_urdf_option_is_one_error_line(
    extra: list[str], message: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    code = main(
        [
            "lerobot",
            "calibrate",
            "--robot",
            "so101_follower",
            "--port",
            "sim",
            "--id",
            "g",
            "--calibration-dir",
            str(tmp_path),
            *extra,
        ]
    )
    err = capsys.readouterr().err
    assert code == 2 and message in err and "Traceback" not in err
    assert [ln for ln in err.splitlines() if ln.startswith("error:")] == [
        ln for ln in err.splitlines() if ln.strip()
    ][:1]
    assert not list(tmp_path.rglob("*.json"))
