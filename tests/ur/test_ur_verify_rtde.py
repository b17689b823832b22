"""``ur verify --rtde``: the RTDE receive client against ``robocal sim ur``'s RTDE server over loopback TCP."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest
from tests.net import free_port

from robocal.backends import load_backend
from robocal.backends.sim.ur_arm_state import UrArmState
from robocal.backends.sim.ur_rtde import SimUrRtde
from robocal.backends.ur_rtde_client import RtdeReceiveClient
from robocal.cli.main import main
from robocal.core.dh import DHParameters, fk_dh
from robocal.core.se3 import rotvec_from_matrix
from robocal.core.ur import correct_kinematics, nominal_dh
from robocal.errors import DeviceError
from robocal.formats.ur_kinematics import write_kinematics
from robocal.workflows.ur.verify import RtdeVerifyRequest, verify_rtde

from .conftest import calibrated_dh


@pytest.fixture
def still_arm() -> Iterator[tuple[DHParameters, tuple[str, int]]]:
    """A calibrated UR10e (delta set 2) standing at q = 0, served on a free loopback port."""
    dh = calibrated_dh(2)
    with SimUrRtde(dh, UrArmState(), moving=False) as server:
        yield dh, server.address


def test_registered_as_ur_rtde() -> None:
    assert load_backend("ur_rtde") is RtdeReceiveClient


def test_client_reads_the_simulators_pose(still_arm: tuple[DHParameters, tuple[str, int]]) -> None:
    dh, (host, port) = still_arm
    with RtdeReceiveClient(host, port, timeout_s=10.0) as client:
        sample = client.read_sample()
    T = fk_dh(dh, [0.0] * 6)
    assert sample.q_rad == (0.0,) * 6
    assert sample.tcp_xyz_m == (float(T[0, 3]), float(T[1, 3]), float(T[2, 3]))
    assert sample.tcp_rotvec_rad == tuple(float(v) for v in rotvec_from_matrix(T[:3, :3]))
    assert sample.tcp_offset == (0.0,) * 6


def test_moving_arm_pose_matches_its_joints() -> None:
    dh = nominal_dh("ur5e")
    with SimUrRtde(dh, UrArmState(), moving=True) as server, RtdeReceiveClient(*server.address) as client:
        got = client.read_pose_samples(5)
    assert len({s.q_rad for s in got}) > 1  # the arm moved between packages
    for s in got:
        T = fk_dh(dh, list(s.q_rad))
        assert np.allclose(s.tcp_xyz_m, T[:3, 3], atol=1e-12, rtol=0)


def test_right_calibration_passes(tmp_path: Path, still_arm: tuple[DHParameters, tuple[str, int]]) -> None:
    dh, (host, port) = still_arm
    cal = tmp_path / "cal.yaml"
    write_kinematics(cal, correct_kinematics(dh, "urdf"))
    (report,) = verify_rtde(RtdeVerifyRequest(host, port=port, kinematics_path=cal, samples=3))
    assert report.samples == 3
    assert report.max_position_error_m < 1e-9
    assert report.warnings == ()
    assert main(["ur", "verify", str(cal), "--rtde", f"{host}:{port}", "--controller-samples", "3"]) == 0


def test_wrong_calibration_shows_the_error_in_mm(
    still_arm: tuple[DHParameters, tuple[str, int]], capsys: pytest.CaptureFixture[str]
) -> None:
    dh, (host, port) = still_arm
    nominal = nominal_dh("ur10e")
    expected_mm = 1000.0 * float(np.linalg.norm(fk_dh(dh, [0.0] * 6)[:3, 3] - fk_dh(nominal, [0.0] * 6)[:3, 3]))
    assert expected_mm > 1.0  # the delta set moves the flange by millimetres at q = 0
    (report,) = verify_rtde(RtdeVerifyRequest(host, port=port, dh=nominal, samples=2))
    assert report.max_position_error_m * 1000.0 == pytest.approx(expected_mm, abs=1e-9)
    assert "FK differs" in report.warnings[0]
    assert main(["ur", "verify", "--model", "ur10e", "--rtde", f"{host}:{port}", "--controller-samples", "2"]) == 1
    out = capsys.readouterr()
    assert f"{expected_mm / 1000.0:.3g} m" in out.err + out.out


def test_unreachable_host_is_one_error_line_exit_3(capsys: pytest.CaptureFixture[str]) -> None:
    port = free_port()
    with pytest.raises(DeviceError, match="cannot connect"):
        verify_rtde(RtdeVerifyRequest("127.0.0.1", port=port, dh=nominal_dh("ur5e"), timeout_s=2.0))
    capsys.readouterr()
    assert main(["ur", "verify", "--model", "ur5e", "--rtde", f"127.0.0.1:{port}", "--timeout", "2"]) == 3
    err = capsys.readouterr().err
    assert err.startswith("error:") and "cannot connect" in err
    assert len(err.strip().splitlines()) == 1 and "Traceback" not in err


@pytest.mark.parametrize("value", ["127.0.0.1:0", "127.0.0.1:x", ":30004", "127.0.0.1:70000"])
def test_bad_rtde_address_exits_2(value: str, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["ur", "verify", "--model", "ur5e", "--rtde", value]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: --rtde") and len(err.strip().splitlines()) == 1


def test_rtde_needs_something_to_compare(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["ur", "verify", "--rtde", "127.0.0.1"]) == 2
    assert "--rtde needs" in capsys.readouterr().err
