"""``kinematics record --lerobot-port sim``: a simulated LeRobot arm behind the real vendor SDK, read per Enter."""

from __future__ import annotations

import io
import math
from pathlib import Path

import numpy as np
import pytest

from robocal.backends.sim.lerobot_arms import DEFAULT_TRUTH
from robocal.cli.main import main
from robocal.formats.kinematic_data import read_measurements
from robocal.workflows.kinematics.record import lerobot_joint_map
from robocal.workflows.lerobot import robot_spec

from .test_record import CHAIN, ROBOT, _calibration, _homing

pytest.importorskip("scservo_sdk")

TICK = 2 * math.pi / 4095


def _args(tmp: Path, port: str, *extra: str) -> list[str]:
    return [
        "kinematics", "record", "--lerobot-port", port, "--robot", ROBOT, "--file", str(tmp / "cal.json"),
        "--out", str(tmp / "rec.csv"), *extra,
    ]  # fmt: skip


@pytest.mark.parametrize("port", ["sim", "sim?transport=inproc&seed=4"])
def test_record_reads_a_simulated_arm_through_its_calibration(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch, port: str
) -> None:
    _calibration(tmp_path / "cal.json")
    monkeypatch.setattr("sys.stdin", io.StringIO("\n10 20 30\n\n-5 0 12.5\nq\n"))
    assert main(_args(tmp_path, port)) == 0
    captured = capsys.readouterr()
    assert f"wrote {tmp_path / 'rec.csv'} (2 poses)" in captured.out
    data, _ = read_measurements(tmp_path / "rec.csv", "points", CHAIN)
    assert data.p_world_m is not None
    np.testing.assert_allclose(data.p_world_m, [[0.01, 0.02, 0.03], [-0.005, 0.0, 0.0125]])
    # the calibration was written to the simulated arm first: at rest each joint reads its mid pose (present
    # = actual - Homing_Offset = 2047), through the export-urdf map of that calibration, within the read noise
    h = _homing()
    present = [(DEFAULT_TRUTH[ROBOT][n].mid_ticks - h[n]) % 4096 for n in CHAIN]
    jm = lerobot_joint_map(robot_spec(ROBOT), None, None, tmp_path / "cal.json")
    expected = np.asarray(jm.to_joint(np.array(present, dtype=float)))[: len(CHAIN)]
    assert np.abs(data.q_rad - expected).max() <= 1.0 * TICK + 1e-12


@pytest.mark.parametrize(
    ("port", "message"),
    [
        ("sim?transport=udp", "transport 'udp': expected pty or inproc"),
        ("sim?speed=3", "speed"),
        ("sim?seed=-1", "seed"),
    ],
)
def test_bad_sim_port_options_are_one_error_and_write_nothing(
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
    monkeypatch: pytest.MonkeyPatch,
    port: str,
    message: str,
) -> None:
    _calibration(tmp_path / "cal.json")
    monkeypatch.setattr("sys.stdin", io.StringIO("\n1 2 3\nq\n"))
    assert main(_args(tmp_path, port)) == 2
    err = capsys.readouterr().err
    assert err.count("error:") == 1 and message in err and "Traceback" not in err, err
    assert not (tmp_path / "rec.csv").exists()


def test_a_koch_with_the_shipped_urdf_is_refused_with_the_reason(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """The shipped koch.urdf names its joints joint1…joint5; a LeRobot Koch is read by motor name."""
    code = main(
        ["kinematics", "record", "--lerobot-port", "sim", "--robot", "koch_follower", "--id", "x",
         "--out", str(tmp_path / "k.csv")]
    )  # fmt: skip
    assert code == 2
    err = capsys.readouterr().err
    assert err.count("error:") == 1
    assert (
        "error: koch_follower has no motor(s) joint1, joint2, joint3, joint4, joint5; its motors are" in err
    )
    assert "the URDF's chain joints must carry those names (give --urdf with them)" in err
    assert list(tmp_path.iterdir()) == []


def test_with_a_plan_the_simulated_arm_is_moved_to_each_pose(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    """``record --lerobot-port sim --plan``: a simulated hand moves the arm to each planned pose before the prompt."""
    from .test_record import TARGETS

    _calibration(tmp_path / "cal.json")
    (tmp_path / "plan.csv").write_text(
        "pose," + ",".join(CHAIN) + "\n"
        + "".join(f"{i + 1}," + ",".join(repr(float(v)) for v in r) + "\n" for i, r in enumerate(TARGETS))
    )  # fmt: skip
    monkeypatch.setattr("sys.stdin", io.StringIO("\n1 2 3\n\n4 5 6\n\n7 8 9\n"))
    code = main(_args(tmp_path, "sim?transport=inproc", "--plan", str(tmp_path / "plan.csv")))
    err = capsys.readouterr().err
    assert code == 0, err
    data, _ = read_measurements(tmp_path / "rec.csv", "points", CHAIN)
    # each reading is the planned pose to the servo's tick (±1 tick of read noise, averaged over 5 reads)
    assert np.abs(data.q_rad - TARGETS).max() <= 1.5 * TICK
    assert err.count("off the plan by at most") == 3


@pytest.mark.parametrize(
    ("extra", "message"),
    [
        (("--kind", "foo", "--out", "{tmp}/r.csv"), "error: --kind 'foo'; valid: points, touch, gauge, tag"),
        (("--out", "{tmp}/nodir/r.csv"), "error: --out {tmp}/nodir/r.csv: folder {tmp}/nodir does not exist"),
    ],
)
def test_bad_session_options_are_refused_before_the_arm_is_opened(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], extra: tuple[str, ...], message: str
) -> None:
    """A typo must not switch a real arm's torque off: the port (here one that does not exist) is not opened."""
    _calibration(tmp_path / "cal.json")
    args = ["kinematics", "record", "--lerobot-port", str(tmp_path / "ttyNONE"), "--robot", ROBOT, "--file",
            str(tmp_path / "cal.json"), *(a.format(tmp=tmp_path) for a in extra)]  # fmt: skip
    assert main(args) == 2  # not 3: the port was never opened
    err = capsys.readouterr().err
    assert err.count("error:") == 1 and message.format(tmp=tmp_path) in err, err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["cal.json"]
