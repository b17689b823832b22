"""Primary-interface client against the simulated controller on loopback TCP, and the byte layout."""

from __future__ import annotations

import socket
import struct
import threading
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from tests.net import free_port

from robocal.backends import load_backend
from robocal.backends.sim.ur_controller import ROBOT_STATE_LAYOUT, SimUrController, build_robot_state
from robocal.backends.ur_primary import (
    KINEMATICS_INFO_SIZE,
    PrimaryClient,
    encode_kinematics_info,
    iter_subpackages,
    parse_kinematics_info,
    resolve_host,
)
from robocal.cli.main import main
from robocal.core.dh import DHParameters
from robocal.core.ur import nominal_dh
from robocal.core.urhash import calib_hash
from robocal.errors import (
    CalibTimeoutError,
    DeviceError,
    ProtocolError,
    UsageError,
)

SHORT = 0.6  # seconds; every network wait in these tests is bounded by this


def ursim_fixture_bytes(dh: DHParameters, status: int) -> bytes:
    """A RobotState like the client library's 1386-byte URSim 5.8 UR5e fixture, built independently."""
    subs = b""
    for sub_type, size in [(0, 47), (1, 251), (4, 101)]:
        subs += struct.pack(">IB", size, sub_type) + bytes([0xAB]) * (size - 5)
    body = struct.pack(
        ">6I6d6d6d6dI", *[0xFFFFFFFF] * 6, *dh.theta_rad, *dh.a_m, *dh.d_m, *dh.alpha_rad, status
    )
    subs += struct.pack(">IB", 225, 5) + body
    for sub_type, size in [(9, 53), (3, 75), (2, 37), (6, 445), (7, 61), (8, 9), (10, 43), (11, 26), (12, 8)]:
        # other sub-packages may contain anything, even a byte pattern that looks like a KinematicsInfo header
        subs += struct.pack(">IB", size, sub_type) + (struct.pack(">IB", 225, 5) * 200)[: size - 5]
    return struct.pack(">iB", len(subs) + 5, 16) + subs


def test_fixture_layout_and_decode() -> None:
    dh = nominal_dh("ur5e")
    msg = ursim_fixture_bytes(dh, 0)
    assert len(msg) == 1386
    assert msg.index(struct.pack(">IB", 225, 5)) == 404  # KinematicsInfo is the 4th sub-package at offset 404
    subs = list(iter_subpackages(msg[5:]))
    assert [(t, len(s)) for t, s in subs] == list(ROBOT_STATE_LAYOUT)
    info, longer = parse_kinematics_info(subs[3][1])
    assert not longer
    assert info.dh == dh
    assert info.calibration_status == 0 and not info.linearised
    assert info.checksum == (0xFFFFFFFF,) * 6
    assert (
        calib_hash(info.dh.theta_rad, info.dh.d_m, info.dh.a_m, info.dh.alpha_rad)
        == "calib_12788084448423163542"
    )
    # the simulator produces the same layout
    assert [(t, len(s)) for t, s in iter_subpackages(build_robot_state(dh)[5:])] == list(ROBOT_STATE_LAYOUT)


def test_kinematics_info_encode_decode_and_longer_tolerated() -> None:
    dh = nominal_dh("ur10e")
    sub = encode_kinematics_info(dh, 2)
    assert len(sub) == KINEMATICS_INFO_SIZE
    info, longer = parse_kinematics_info(sub[:4] + sub[4:] + bytes(20))
    assert info.dh == dh and longer
    with pytest.raises(ProtocolError, match=r"KinematicsInfo: 100 bytes, expected 225"):
        parse_kinematics_info(sub[:100])
    nan_sub = bytearray(sub)
    struct.pack_into(">d", nan_sub, 125, float("nan"))  # dh_d[0]
    with pytest.raises(ProtocolError, match=r"dh_d\[0\] is nan"):
        parse_kinematics_info(bytes(nan_sub))


def test_subpackage_walk_rejects_bad_lengths() -> None:
    with pytest.raises(ProtocolError, match="claims 4 bytes"):
        list(iter_subpackages(struct.pack(">IB", 4, 0)))
    with pytest.raises(ProtocolError, match="too short for a header"):
        list(iter_subpackages(struct.pack(">IB", 5, 0) + b"\x00\x01"))


def test_registry_names_primary_client() -> None:
    assert load_backend("ur_primary") is PrimaryClient


def test_client_reads_simulated_controller(dh_sets: dict[int, DHParameters]) -> None:
    with SimUrController(dh_sets[3]) as sim, PrimaryClient(*sim.address, timeout_s=5.0) as client:
        info = client.read_kinematics()
    assert info.dh == dh_sets[3]
    assert info.linearised
    assert client.warnings == []


def test_status_not_linearised_warns() -> None:
    sim = SimUrController(nominal_dh("ur5e"), calibration_status=1)
    with sim, PrimaryClient(*sim.address, timeout_s=5.0) as client:
        client.read_kinematics()
    assert len(client.warnings) == 1
    assert "calibration_status is 1, not 2 (linearised)" in client.warnings[0]


@pytest.mark.parametrize(
    ("mode", "error", "message"),
    [
        ("truncated", ProtocolError, r"connection closed in the middle of a 1386-byte message of type 16"),
        ("garbage", ProtocolError, r"has size 1213486160; expected 5\.\.65536 bytes"),
        ("oversized", ProtocolError, r"has size 2147483647"),
        ("bad_subpackage", ProtocolError, r"sub-package type 0 at offset 0 claims 5000 bytes"),
        ("short_kinematics", ProtocolError, r"KinematicsInfo: 100 bytes, expected 225"),
        ("silent", CalibTimeoutError, r"no KinematicsInfo within 0\.6 s"),
        ("no_kinematics", CalibTimeoutError, r"no KinematicsInfo within 0\.6 s"),
        ("close", DeviceError, r"connection closed before a KinematicsInfo arrived"),
    ],
)
def test_faults_give_clear_errors_within_timeout(mode: str, error: type[Exception], message: str) -> None:
    with SimUrController(nominal_dh("ur10e"), mode=mode) as sim:
        host, port = sim.address
        with PrimaryClient(host, port, timeout_s=SHORT) as client, pytest.raises(error, match=message) as exc:
            client.read_kinematics()
    assert f"UR controller {host}:{port}" in str(exc.value)
    assert getattr(exc.value, "exit_code", None) == 3


def test_connection_refused_is_device_error() -> None:
    port = free_port()
    with pytest.raises(DeviceError, match="cannot connect"):
        PrimaryClient("127.0.0.1", port, timeout_s=SHORT).read_kinematics()


# --- CLI -----------------------------------------------------------------------------------------------------


@pytest.mark.slow
def test_extract_gives_the_same_file_as_correct(
    tmp_path: Path, dh_sets: dict[int, DHParameters], capsys: pytest.CaptureFixture[str]
) -> None:
    dh = dh_sets[2]
    dh_file = tmp_path / "dh.yaml"
    dh_file.write_text(
        f"dh_theta: {list(dh.theta_rad)}\ndh_a: {list(dh.a_m)}\ndh_d: {list(dh.d_m)}\ndh_alpha: {list(dh.alpha_rad)}\n"
    )
    for rpy in ("urdf", "upstream"):
        extracted, corrected = tmp_path / f"extracted_{rpy}.yaml", tmp_path / f"corrected_{rpy}.yaml"
        with SimUrController(dh) as sim:
            host, port = sim.address
            code = main(
                [
                    "ur",
                    "extract",
                    "--host",
                    host,
                    "--port",
                    str(port),
                    "--out",
                    str(extracted),
                    "--timeout",
                    "5",
                    "--rpy",
                    rpy,
                ]
            )
        assert code == 0
        assert main(["ur", "correct", "--dh", str(dh_file), "--out", str(corrected), "--rpy", rpy]) == 0
        assert extracted.read_bytes() == corrected.read_bytes()
    assert "hash: calib_12699676364380556618" in capsys.readouterr().out


def test_extract_status_warning_exit_1(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "k.yaml"
    with SimUrController(nominal_dh("ur5e"), calibration_status=0) as sim:
        host, port = sim.address
        assert (
            main(["ur", "extract", "--host", host, "--port", str(port), "--out", str(out), "--timeout", "5"])
            == 1
        )
    assert out.exists()
    assert "warning: " in capsys.readouterr().err


@pytest.mark.slow
@pytest.mark.parametrize("mode", ["silent", "garbage", "truncated"])
def test_extract_failures_exit_3_nothing_written(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], mode: str
) -> None:
    out = tmp_path / "k.yaml"
    with SimUrController(nominal_dh("ur5e"), mode=mode) as sim:
        host, port = sim.address
        code = main(
            ["ur", "extract", "--host", host, "--port", str(port), "--out", str(out), "--timeout", "0.5"]
        )
    assert code == 3
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(f"error: UR controller {host}:{port}")
    assert not out.exists()


def test_extract_checks_out_dir_before_connecting(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    with SimUrController(nominal_dh("ur5e")) as sim:
        host, port = sim.address
        out = tmp_path / "missing" / "k.yaml"
        assert main(["ur", "extract", "--host", host, "--port", str(port), "--out", str(out)]) == 2
        assert sim.connections == 0
    assert "does not exist" in capsys.readouterr().err


@pytest.mark.slow
def test_verify_against_controller_pose(
    tmp_path: Path, dh_sets: dict[int, DHParameters], capsys: pytest.CaptureFixture[str]
) -> None:
    from robocal.core.ur import correct_kinematics
    from robocal.formats.ur_kinematics import write_kinematics

    good, upstream = tmp_path / "good.yaml", tmp_path / "upstream.yaml"
    write_kinematics(good, correct_kinematics(dh_sets[3], "urdf"))
    write_kinematics(upstream, correct_kinematics(dh_sets[3], "upstream"))
    with SimUrController(dh_sets[3], rate_hz=100) as sim:
        host, port = sim.address
        base = ["--host", host, "--port", str(port), "--timeout", "5", "--controller-samples", "10"]
        assert main(["ur", "verify", str(good), *base]) == 0
        assert "controller" in capsys.readouterr().out
        assert main(["ur", "verify", str(upstream), *base]) == 1
    err = capsys.readouterr().err
    assert f"warning: controller {host}:{port} vs {upstream}: FK differs" in err


def test_pose_samples_decode() -> None:
    from robocal.backends.ur_primary import parse_pose_sample
    from robocal.core.dh import fk_dh
    from robocal.core.se3 import matrix_from_rotvec, rotation_angle_between

    dh = nominal_dh("ur5e")
    q = (0.1, -1.2, 1.3, -0.4, 0.5, 2.9)
    sample = parse_pose_sample(build_robot_state(dh, q_rad=q)[5:])
    assert sample is not None and sample.q_rad == q
    T = fk_dh(dh, list(q))
    assert np.max(np.abs(np.array(sample.tcp_xyz_m) - T[:3, 3])) == 0.0
    assert rotation_angle_between(matrix_from_rotvec(sample.tcp_rotvec_rad), T[:3, :3]) < 1e-15
    assert sample.tcp_offset == (0.0,) * 6
    assert parse_pose_sample(build_robot_state(dh)[5:]) is not None  # zero-filled joints still decode


@pytest.mark.slow
def test_verify_timeout_is_per_read_at_the_real_10_hz_rate(
    tmp_path: Path, dh_sets: dict[int, DHParameters], capsys: pytest.CaptureFixture[str]
) -> None:
    """A healthy 10 Hz controller: 25 samples take ~2.5 s, yet --timeout 1 is enough (1 s per read)."""
    import time

    from robocal.core.ur import correct_kinematics
    from robocal.formats.ur_kinematics import write_kinematics

    good = tmp_path / "good.yaml"
    write_kinematics(good, correct_kinematics(dh_sets[3], "urdf"))
    with SimUrController(dh_sets[3], rate_hz=10) as sim:
        host, port = sim.address
        t0 = time.monotonic()
        args = ["--host", host, "--port", str(port), "--timeout", "1", "--controller-samples", "25"]
        code = main(["ur", "verify", str(good), *args])
        elapsed = time.monotonic() - t0
    captured = capsys.readouterr()
    assert code == 0, captured.err
    assert "error" not in captured.err
    assert elapsed > 2.0  # the samples really took longer than --timeout all together


def test_pose_sample_timeout_names_what_was_missing() -> None:
    """RobotStates (with KinematicsInfo) keep arriving but lack CartesianInfo: the error says so."""
    with SimUrController(nominal_dh("ur5e"), mode="no_cartesian", rate_hz=20) as sim:
        host, port = sim.address
        with PrimaryClient(host, port, timeout_s=SHORT) as client:
            info = client.read_kinematics()  # the KinematicsInfo did arrive
            assert info.linearised
            with pytest.raises(CalibTimeoutError) as exc:
                client.read_pose_samples(3)
    msg = str(exc.value)
    assert (
        f"UR controller {host}:{port}: no RobotState with Joint data and CartesianInfo within {SHORT:g} s"
        in msg
    )
    assert "sample 1 of 3; the RobotStates that arrived lack CartesianInfo" in msg
    assert "KinematicsInfo" not in msg


def test_pose_sample_timeout_on_a_silent_stream_names_the_sample() -> None:
    """The controller stops after the KinematicsInfo: the timeout names the sample, not the KinematicsInfo."""

    class _StopAfterFirst(SimUrController):
        def _send(self, conn: socket.socket, data: bytes) -> bool:
            self._sent = getattr(self, "_sent", 0) + 1
            if self._sent > 3:  # version message, then two RobotState rounds; then silence
                self._stop.wait()
                return False
            return super()._send(conn, data)

    with _StopAfterFirst(nominal_dh("ur5e"), rate_hz=20) as sim:
        host, port = sim.address
        with PrimaryClient(host, port, timeout_s=SHORT) as client:
            client.read_kinematics()
            with pytest.raises(CalibTimeoutError) as exc:
                client.read_pose_samples(5)
    msg = str(exc.value)
    assert "no RobotState with Joint data and CartesianInfo within" in msg
    assert "of 5" in msg and "KinematicsInfo" not in msg


@pytest.mark.parametrize("port", [0, -1, 70000])
def test_client_refuses_port_out_of_range(port: int) -> None:
    # 70000 used to be wrapped by getaddrinfo to port 4464 and connected there
    with pytest.raises(UsageError, match=rf"--port {port}: expected 1\.\.65535"):
        PrimaryClient("127.0.0.1", port, 0.5).read_kinematics()


@pytest.mark.parametrize("host", ["", "  "])
def test_client_refuses_empty_host(host: str) -> None:
    with pytest.raises(UsageError, match="--host: expected a controller address"):
        PrimaryClient(host, 30001, 0.5).read_kinematics()


def test_sub_package_size_field_is_unsigned() -> None:
    from robocal.backends.ur_primary import iter_subpackages
    from robocal.errors import ProtocolError

    with pytest.raises(ProtocolError, match="claims 4294967295 bytes"):
        list(iter_subpackages(struct.pack(">IB", 0xFFFFFFFF, 5) + bytes(10)))


def test_simulator_serves_after_a_client_left() -> None:
    with SimUrController(nominal_dh("ur3e")) as sim:
        for _ in range(2):
            with PrimaryClient(*sim.address, timeout_s=5.0) as client:
                assert client.read_kinematics().dh == nominal_dh("ur3e")
        assert sim.connections == 2


def _one_error_line(err: str) -> str:
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: "), lines
    return lines[0]


def test_unresolvable_host_is_one_error_exit_3(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "k.yaml"
    assert main(["ur", "extract", "--host", "nonexistent.invalid", "--out", str(out), "--timeout", "3"]) == 3
    line = _one_error_line(capsys.readouterr().err)
    assert "UR controller nonexistent.invalid:30001: cannot resolve host name 'nonexistent.invalid'" in line
    assert not out.exists()


def test_resolution_that_never_answers_hits_the_timeout(monkeypatch: pytest.MonkeyPatch) -> None:
    release = threading.Event()
    real = socket.getaddrinfo

    def stuck(host: str, *args: Any, **kw: Any) -> Any:
        if kw.get("flags", 0) & socket.AI_NUMERICHOST:
            return real(host, *args, **kw)
        release.wait(30)  # a dead DNS server
        raise socket.gaierror(socket.EAI_AGAIN, "Temporary failure in name resolution")

    monkeypatch.setattr(socket, "getaddrinfo", stuck)
    try:
        with pytest.raises(
            CalibTimeoutError, match=r"cannot resolve host name 'robot\.example' within 0\.2 s"
        ):
            PrimaryClient("robot.example", 30001, 0.2).read_kinematics()
        # numeric addresses never wait for the resolver
        assert resolve_host("127.0.0.1", 30001, 0.2)[0][4] == ("127.0.0.1", 30001)
    finally:
        release.set()


def test_resolver_error_is_a_device_error(monkeypatch: pytest.MonkeyPatch) -> None:
    real = socket.getaddrinfo

    def fails(host: str, *args: Any, **kw: Any) -> Any:
        if kw.get("flags", 0) & socket.AI_NUMERICHOST:
            return real(host, *args, **kw)
        raise socket.gaierror(socket.EAI_NONAME, "Name or service not known")

    monkeypatch.setattr(socket, "getaddrinfo", fails)
    with pytest.raises(
        DeviceError, match=r"cannot resolve host name 'robot\.example' \(Name or service not known\)"
    ):
        resolve_host("robot.example", 30001, 5.0)
