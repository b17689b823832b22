"""sweep --auto end to end over the wire: simulated Robstride motors with physics on virtual CAN channels."""

from __future__ import annotations

import json
import math
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest

pytest.importorskip("can")

from robocal.backends.sim.lite import lite_urdf_text
from robocal.core.stop_search import StopSample
from robocal.errors import UsageError
from robocal.formats import read_calibration
from robocal.workflows.autocal.job import AutoCalFailedError
from robocal.workflows.autocal.sim import SimAutoLite, sim_opener
from robocal.workflows.autocal.sweep import SweepAutoRequest, run_sweep_auto

JOINTS = ["left_wrist_roll", "left_wrist_pitch"]


@pytest.fixture
def urdf(tmp_path: Path) -> Path:
    p = tmp_path / "lite.urdf"
    p.write_text(lite_urdf_text())
    return p


@pytest.mark.slow
def test_recovers_the_true_offsets(urdf: Path, tmp_path: Path) -> None:
    holder: list[SimAutoLite] = []
    out = tmp_path / "cal.yaml"
    rep = tmp_path / "rep.json"
    outcome = run_sweep_auto(
        SweepAutoRequest(
            urdf,
            "sim:lite?seed=4",
            out,
            robot="bhl_arms",
            joints=JOINTS,
            report=rep,
        ),
        open_drivers_fn=sim_opener(holder),
    )
    truth = holder[0].true_offsets()
    cf = read_calibration(out)
    assert set(cf.calibration.joint_names) == set(JOINTS)
    for name in JOINTS:
        got = cf.calibration.homing_offset[cf.calibration.index(name)]
        assert abs(got - truth[name]) < math.radians(0.1), name
    doc = json.loads(rep.read_text())
    auto = doc["auto"]["joints"]["left_wrist_pitch"]
    assert auto["code"] == "ok"
    assert auto["span_deg"] == pytest.approx(90.0, abs=0.5)  # URDF ±0.785 rad
    assert auto["lower"]["test"] in ("torque", "lag")
    assert auto["lower"]["stiffness_nm_per_rad"] == pytest.approx(600, rel=0.4)
    assert outcome.auto.total_time_s < 20
    # every motor is limp (reset mode) at the end, its RAM torque limit back to what it was
    assert all(m.mode == 0 for m in holder[0].motors.values())
    assert all(m.limit_torque_nm in (None, m.limits.t_max_nm) for m in holder[0].motors.values())
    # the firmware limit held the push to the cap + 5 %
    for name in JOINTS:
        plant = holder[0].motors[name].plant
        assert plant.peak_tau_motor_nm <= 1.05 * 0.4 + 1e-9


@pytest.mark.slow
def test_missing_stop_writes_nothing_and_limps(urdf: Path, tmp_path: Path) -> None:
    holder: list[SimAutoLite] = []
    out = tmp_path / "cal.yaml"
    with pytest.raises(AutoCalFailedError, match="left_wrist_pitch: missing_stop") as info:
        run_sweep_auto(
            SweepAutoRequest(
                urdf,
                "sim:lite?seed=4&missing=left_wrist_pitch",
                out,
                robot="bhl_arms",
                joints=JOINTS,
            ),
            open_drivers_fn=sim_opener(holder),
        )
    assert info.value.exit_code == 3
    assert not out.exists()
    assert all(m.mode == 0 for m in holder[0].motors.values())


@pytest.mark.slow
def test_partial_writes_the_joints_that_passed(urdf: Path, tmp_path: Path) -> None:
    out = tmp_path / "cal.yaml"
    outcome = run_sweep_auto(
        SweepAutoRequest(
            urdf,
            "sim:lite?seed=4&snag=left_wrist_pitch",
            out,
            robot="bhl_arms",
            joints=JOINTS,
            partial=True,
        ),
    )
    assert outcome.exit_code == 1
    assert outcome.auto["left_wrist_pitch"].stops.code == "span_mismatch"
    assert read_calibration(out).calibration.joint_names == ("left_wrist_roll",)


class _Interrupt:
    def __init__(self, after: int) -> None:
        self.n = after

    def joint_start(self, name: str, cap_nm: float, speed_rad_s: float) -> None:
        pass

    def sample(self, name: str, phase: str, side: str, sample: StopSample) -> None:
        self.n -= 1
        if self.n == 0:
            raise KeyboardInterrupt

    def joint_done(self, outcome: Any) -> None:
        pass


@pytest.mark.parametrize("after", [5, 300, pytest.param(900, marks=pytest.mark.slow)])
def test_ctrl_c_at_any_step_leaves_every_motor_limp_and_files_unchanged(
    urdf: Path, tmp_path: Path, after: int
) -> None:
    holder: list[SimAutoLite] = []
    out = tmp_path / "cal.yaml"
    out.write_text("left_wrist_roll:\n  id: 16\n  direction: -1\n  homing_offset: 0.25\n")
    before = out.read_bytes()
    with pytest.raises(KeyboardInterrupt):
        run_sweep_auto(
            SweepAutoRequest(
                urdf,
                "sim:lite?seed=2",
                out,
                robot="bhl_arms",
                joints=JOINTS,
            ),
            view=_Interrupt(after),
            open_drivers_fn=sim_opener(holder),
        )
    assert out.read_bytes() == before
    assert all(m.mode == 0 for m in holder[0].motors.values())
    # reset mode: the firmware applies no torque at all
    assert all(m.drive().tau_max_nm == 0.0 for m in holder[0].motors.values())


def test_not_confirmed_moves_nothing(urdf: Path, tmp_path: Path) -> None:
    asked: list[tuple[str, ...]] = []

    def no(names: Any, caps: Any) -> bool:
        asked.append(tuple(names))
        assert caps["left_wrist_roll"] == pytest.approx(0.4)
        assert caps.models["left_wrist_roll"] == ("RS05", 1.6)  # the prompt: 25 % of the RS05's 1.6 N·m
        assert caps.host_loss == (  # the prompt says what stops the motors if robocal is killed
            "If robocal is killed or the CAN bus is lost, each moving motor's CAN timeout puts it in reset mode "
            "within 0.5 s."
        )
        return False

    with pytest.raises(UsageError, match="not confirmed: nothing moved"):
        run_sweep_auto(
            SweepAutoRequest(
                urdf,
                "sim:lite",
                tmp_path / "c.yaml",
                robot="bhl_arms",
                joints=JOINTS,
            ),
            confirm_start=no,
        )
    assert asked == [tuple(JOINTS)]  # in the profile's search order


@pytest.mark.slow
def test_cli_sweep_auto(urdf: Path, tmp_path: Path) -> None:
    out = tmp_path / "cal.yaml"
    cmd = [
        sys.executable,
        "-m",
        "robocal",
        "sweep",
        "--auto",
        "--urdf",
        str(urdf),
        "--source",
        "sim:lite?seed=1",
        "--out",
        str(out),
        "--robot",
        "bhl_arms",
        "--joints",
        ",".join(JOINTS),
        "--yes",
    ]
    r = subprocess.run(cmd, capture_output=True, text=True, timeout=300)
    assert r.returncode in (0, 1), r.stderr
    assert "q_stop−" in r.stdout and "left_wrist_pitch" in r.stdout
    assert out.exists()
    bad = subprocess.run(
        [*cmd[:-1], "--partial"], capture_output=True, text=True, timeout=300, stdin=subprocess.DEVNULL
    )
    assert bad.returncode == 2
    assert "pass --yes" in bad.stderr and "Traceback" not in bad.stderr
    fail = subprocess.run(
        [*cmd[:8], "sim:lite?seed=1&missing=left_wrist_roll", *cmd[9:]],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert fail.returncode == 3
    assert fail.stderr.count("error:") == 1 and "left_wrist_roll: missing_stop" in fail.stderr


@pytest.mark.slow
def test_cli_demo_auto(tmp_path: Path) -> None:
    r = subprocess.run(
        [sys.executable, "-m", "robocal", "demo", "--auto", "--out", str(tmp_path)],
        capture_output=True,
        text=True,
        timeout=900,
    )
    assert r.returncode == 0, r.stderr[-2000:]
    assert "right_shoulder_pitch" in r.stdout and "largest error" in r.stdout
    cal = read_calibration(tmp_path / "calibration.yaml")
    assert len(cal.calibration.joint_names) == 14
    doc = json.loads((tmp_path / "sweep_report.json").read_text())
    assert doc["auto"]["total_time_s"] < 180.0


@pytest.mark.slow
def test_joints_not_searched_keep_their_entries(urdf: Path, tmp_path: Path) -> None:
    out = tmp_path / "cal.yaml"
    out.write_text("right_elbow_pitch:\n  id: 24\n  direction: 1\n  homing_offset: 0.125\n")
    outcome = run_sweep_auto(SweepAutoRequest(urdf, "sim:lite?seed=6", out, robot="bhl_arms", joints=JOINTS))
    cal = read_calibration(out).calibration
    assert set(cal.joint_names) == {"right_elbow_pitch", *JOINTS}
    assert cal.homing_offset[cal.index("right_elbow_pitch")] == 0.125
    assert {j.name for j in outcome.result.joints} == set(JOINTS)
