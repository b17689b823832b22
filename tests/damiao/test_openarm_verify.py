"""``sweep --auto --verify`` on the OpenArm (issue 31 item 4, the health issue's ``--verify``): the stops touched
again, each motor's stored zero compared with the zero they give, nothing written. The stored calibration is the
zero in the motors with LeRobot's file (offsets 0, as ``--write-zero`` leaves it); the simulated motors' zeros are
moved by a known amount (``sim:openarm?zeroed=1&zero_drift=...``) and the drift found must be within 0.3° of it."""

from __future__ import annotations

import math
from pathlib import Path

import pytest

pytest.importorskip("can")

from robocal.cli.main import main
from robocal.formats import write_calibration
from robocal.formats.urdf import read_urdf
from robocal.workflows.autocal.sweep import SweepAutoRequest

from .openarm_session import URDF, openarm_session, session_file

J5, GRIPPER = "openarm_right_joint5", "openarm_right_gripper_motor"


def _lerobot_file(path: Path) -> bytes:
    write_calibration(path, session_file(), "openarm-lerobot", urdf=read_urdf(URDF), robot="openarm_follower_right")
    return path.read_bytes()


def test_verify_finds_a_moved_motor_zero_within_0_3_degrees_and_writes_nothing(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "arm.json"
    before = _lerobot_file(out)
    source = f"sim:openarm?seed=3&zeroed=1&zero_drift={J5}:3.0,{GRIPPER}:-1.2"
    request = SweepAutoRequest(URDF, source, out, robot="openarm_follower_right", fmt="openarm-lerobot",
                               joints=(J5, GRIPPER), verify=True)
    with openarm_session(request) as (outcome, sim):
        arm = sim.arm
        # the injected drift as the simulator holds it: each motor reads that much more than its joint
        assert math.degrees(arm.zero_error_rad("joint_5")) == pytest.approx(3.0, abs=1e-6)
        assert math.degrees(arm.zero_error_rad("gripper")) == pytest.approx(-1.2, abs=1e-6)
        assert all(m.flash_writes == 0 and not m.enabled for m in arm.motors.values())
    drifts = {d.name: d for d in outcome.drifts}
    assert set(drifts) == {J5, GRIPPER}
    assert drifts[J5].drift_deg == pytest.approx(3.0, abs=0.3) and drifts[J5].flagged
    assert drifts[GRIPPER].drift_deg == pytest.approx(-1.2, abs=0.3) and not drifts[GRIPPER].flagged
    assert outcome.exit_code == 1 and outcome.out is None
    assert out.read_bytes() == before and sorted(p.name for p in tmp_path.iterdir()) == ["arm.json"]
    # the CLI: the drift table, exit 1, nothing written
    rc = main(["sweep", "--auto", "--verify", "--robot", "openarm_follower_right", "--urdf", str(URDF), "--source",
               source, "--out", str(out), "--format", "openarm-lerobot", "--yes", "--joints", J5])
    printed, err = capsys.readouterr()
    rows = {line.split()[1]: line.split() for line in printed.splitlines() if line.startswith("│ openarm_right")}
    assert rc == 1 and float(rows[J5][3]) == pytest.approx(3.0, abs=0.3) and "DRIFTED" in rows[J5], printed
    assert f"warning: {J5} drifted more than 2°" in err
    assert out.read_bytes() == before


@pytest.mark.parametrize(
    ("option", "message"),
    [
        ("zero_drift=openarm_right_joint9:1", "sim:openarm zero_drift: expected joint:degrees with a joint of the profile"),
        ("zero_drift=openarm_right_joint5:x", "sim:openarm zero_drift: expected joint:degrees"),
        ("zeroed=2", "sim:openarm zeroed='2': expected 0 or 1"),
    ],
)
def test_bad_simulator_options_are_one_error_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], option: str, message: str
) -> None:
    out = tmp_path / "arm.json"
    before = _lerobot_file(out)
    rc = main(["sweep", "--auto", "--verify", "--robot", "openarm_follower_right", "--urdf", str(URDF), "--source",
               f"sim:openarm?seed=1&{option}", "--out", str(out), "--format", "openarm-lerobot", "--yes", "--joints", J5])
    err = capsys.readouterr().err
    assert rc == 2 and err.count("error:") == 1 and message in err, err
    assert out.read_bytes() == before


@pytest.mark.parametrize(
    ("text", "why"),
    [
        ("hello: world\n", "not a calibration format robocal knows"),
        ("joints:\n  openarm_right_joint5: {offset: 0.1}\n", "it looks like"),
    ],
)
def test_verify_of_an_out_that_is_not_the_calibration_says_verify_reads_it(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], text: str, why: str
) -> None:
    """Before: "... move it away or choose another --out", advice for a file about to be written; --verify writes
    nothing to --out, it reads the calibration to check there."""
    out = tmp_path / "arm.json"
    out.write_text(text)
    rc = main(["sweep", "--auto", "--verify", "--robot", "openarm_follower_right", "--urdf", str(URDF), "--source",
               "sim:openarm?seed=1", "--out", str(out), "--format", "openarm-lerobot", "--yes", "--joints", J5])
    err = capsys.readouterr().err
    assert rc == 2 and err.count("\n") == 1, err
    assert err.startswith(f"error: --out {out}: exists but is not a openarm-lerobot calibration file ({why}"), err
    assert err.endswith("); --verify reads the calibration to check from --out: name the file the calibration was "
                        "written to (and its --format)\n"), err
    assert "another --out" not in err and out.read_text() == text
    assert sorted(p.name for p in tmp_path.iterdir()) == ["arm.json"]
