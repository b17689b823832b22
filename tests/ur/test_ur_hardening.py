"""Regression tests from the UR review (each failed before its fix), plus a few extra wire and simulator edge cases."""

from __future__ import annotations

import math
import socket
import struct
from pathlib import Path

import numpy as np
import pytest

from robocal.backends.sim.ur_controller import SimUrController
from robocal.backends.ur_primary import PrimaryClient, encode_kinematics_info, parse_kinematics_info
from robocal.cli.main import main
from robocal.core.dh import DHParameters
from robocal.core.ur import correct_kinematics, default_kinematics, nominal_dh
from robocal.core.urhash import calib_hash, kinematics_hash_string
from robocal.errors import FileFormatError, JointMismatchError, UsageError
from robocal.formats.ur_kinematics import kinematics_to_text, read_dh, read_kinematics, write_kinematics
from robocal.workflows.ur_verify import urdf_fk

from .test_ur_urdf import pytransform3d_fk, ur_urdf_text


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def _one_error_line(err: str) -> str:
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: "), lines
    return lines[0]


# --- hash of a raw DH with a negative zero ---------------------------------------------------------------------


def test_negative_zero_in_raw_dh_is_hashed_like_the_driver() -> None:
    # the driver prints the controller's raw doubles with ostream <<, so -0.0 hashes as "-0"
    nom = nominal_dh("ur5e")
    a_raw = (*nom.a_m[:5], -0.0)
    dh = DHParameters(nom.theta_rad, a_raw, nom.d_m, nom.alpha_rad)
    assert math.copysign(1.0, dh.a_m[5]) == -1.0
    assert kinematics_hash_string(dh.theta_rad, dh.d_m, dh.a_m, dh.alpha_rad).endswith("0.0996-00")
    expected = calib_hash(nom.theta_rad, nom.d_m, a_raw, nom.alpha_rad)
    assert expected != "calib_12788084448423163542"
    assert correct_kinematics(dh).hash == expected
    # the same through the wire format
    info, _ = parse_kinematics_info(encode_kinematics_info(dh))
    assert correct_kinematics(info.dh).hash == expected
    # the written file still never contains -0
    assert ": -0.0\n" not in kinematics_to_text(correct_kinematics(dh))


# --- primary interface: port range ------------------------------------------------------------------------------


@pytest.mark.parametrize("port", [0, -1, 70000])
def test_client_refuses_port_out_of_range(port: int) -> None:
    # 70000 used to be wrapped by getaddrinfo to port 4464 and connected there
    with pytest.raises(UsageError, match=rf"--port {port}: expected 1\.\.65535"):
        PrimaryClient("127.0.0.1", port, 0.5).read_kinematics()


@pytest.mark.parametrize("host", ["", "  "])
def test_client_refuses_empty_host(host: str) -> None:
    with pytest.raises(UsageError, match="--host: expected a controller address"):
        PrimaryClient(host, 30001, 0.5).read_kinematics()


def test_verify_host_validates_port_and_counts(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    f = tmp_path / "k.yaml"
    write_kinematics(f, default_kinematics("ur5e", "urdf"))
    assert main(["ur", "verify", str(f), "--host", "127.0.0.1", "--port", "70000", "--timeout", "0.5"]) == 2
    assert "--port 70000: expected 1..65535" in _one_error_line(capsys.readouterr().err)
    port = str(_free_port())
    assert (
        main(["ur", "verify", str(f), "--host", "127.0.0.1", "--port", port, "--controller-samples", "0"])
        == 2
    )
    assert "--controller-samples 0: expected at least 1" in _one_error_line(capsys.readouterr().err)


# --- CLI: nothing said about replacing a file that is not replaced ----------------------------------------------


def test_failed_extract_leaves_existing_file_alone_one_error_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "k.yaml"
    out.write_text("keep me\n")
    port = str(_free_port())
    assert (
        main(["ur", "extract", "--host", "127.0.0.1", "--port", port, "--out", str(out), "--timeout", "0.5"])
        == 3
    )
    assert "cannot connect" in _one_error_line(capsys.readouterr().err)
    assert out.read_text() == "keep me\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["k.yaml"]
    assert main(["ur", "defaults", "--model", "ur99", "--out", str(out)]) == 2
    assert "unknown UR model 'ur99'" in _one_error_line(capsys.readouterr().err)


def test_overwrite_note_after_success(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "k.yaml"
    out.write_text("old\n")
    assert main(["ur", "defaults", "--model", "ur5e", "--out", str(out)]) == 0
    assert "previous file kept as k.yaml.bak" in capsys.readouterr().err
    assert (tmp_path / "k.yaml.bak").read_text() == "old\n"


def test_urdf_out_must_differ_from_out(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    urdf = tmp_path / "ur.urdf"
    urdf.write_text(ur_urdf_text(default_kinematics("ur5e", "urdf")))
    out = tmp_path / "k.yaml"
    code = main(
        [
            "ur",
            "correct",
            "--model",
            "ur5e",
            "--out",
            str(out),
            "--urdf-in",
            str(urdf),
            "--urdf-out",
            str(tmp_path / "." / "k.yaml"),
        ]
    )
    assert code == 2
    assert "--urdf-out" in _one_error_line(capsys.readouterr().err)
    assert not out.exists()


# --- plot ---------------------------------------------------------------------------------------------------------


def test_plot_unknown_format_exit_2_nothing_written(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    fig = tmp_path / "fig.xyz"
    assert main(["ur", "plot", "--model", "ur10e", "--out", str(fig)]) == 2
    assert "fig.xyz: unsupported figure format 'xyz'" in _one_error_line(capsys.readouterr().err)
    assert list(tmp_path.iterdir()) == []


# --- files ----------------------------------------------------------------------------------------------------------


def test_hash_beyond_uint64_refused(tmp_path: Path) -> None:
    text = kinematics_to_text(default_kinematics("ur5e"))
    p = tmp_path / "k.yaml"
    p.write_text(text.replace("calib_12788084448423163542", "calib_18446744073709551616"))
    with pytest.raises(FileFormatError, match=r"kinematics\.hash is 'calib_18446744073709551616'"):
        read_kinematics(p)
    p.write_text(text.replace("calib_12788084448423163542", "calib_18446744073709551615"))
    assert read_kinematics(p).hash == "calib_18446744073709551615"


def test_kinematics_file_passed_as_dh_says_so(tmp_path: Path) -> None:
    p = tmp_path / "cal.yaml"
    write_kinematics(p, default_kinematics("ur5e"))
    with pytest.raises(FileFormatError, match=r"is a kinematics YAML \(robocal ur correct output\)"):
        read_dh(p)


# --- verify --urdf: the chain as ur_description builds it -----------------------------------------------------------


def _urdf_with(kin_text: str, old: str, new: str) -> str:
    assert old in kin_text
    return kin_text.replace(old, new)


def test_urdf_fk_runs_to_tool0_through_fixed_frames(tmp_path: Path, dh_sets: dict[int, DHParameters]) -> None:
    kin = correct_kinematics(dh_sets[3])
    good = tmp_path / "good.urdf"
    good.write_text(ur_urdf_text(kin))
    q = np.random.default_rng(8).uniform(-2 * math.pi, 2 * math.pi, (20, 6))
    # an independent reader (pytransform3d, base_link_inertia → tool0) agrees with urdf_fk
    np.testing.assert_allclose(urdf_fk(good, q), pytransform3d_fk(kin, q), rtol=0, atol=1e-12)
    # a tool0 that is not the flange is caught
    bad = tmp_path / "bad.urdf"
    bad.write_text(
        _urdf_with(
            ur_urdf_text(kin), 'rpy="1.5707963267948966 0 1.5707963267948966"', 'rpy="1.5707963267948966 0 0"'
        )
    )
    dh_file = tmp_path / "dh.yaml"
    dh = dh_sets[3]
    dh_file.write_text(
        f"dh_theta: {list(dh.theta_rad)}\ndh_a: {list(dh.a_m)}\n"
        f"dh_d: {list(dh.d_m)}\ndh_alpha: {list(dh.alpha_rad)}\n"
    )
    assert main(["ur", "verify", "--dh", str(dh_file), "--urdf", str(good), "--samples", "50"]) == 0
    assert main(["ur", "verify", "--dh", str(dh_file), "--urdf", str(bad), "--samples", "50"]) == 1


def test_urdf_fk_refuses_a_broken_chain(tmp_path: Path) -> None:
    text = ur_urdf_text(default_kinematics("ur5e", "urdf"))
    p = tmp_path / "ur.urdf"
    p.write_text(
        _urdf_with(
            text,
            '<joint name="wrist_1_joint" type="revolute"><parent link="forearm_link"/>',
            '<joint name="wrist_1_joint" type="revolute"><parent link="upper_arm_link"/>',
        )
    )
    with pytest.raises(
        JointMismatchError, match=r"wrist_1_joint's parent is upper_arm_link; expected forearm_link"
    ):
        urdf_fk(p, np.zeros((1, 6)))


def test_urdf_fk_refuses_moving_joint_after_wrist_3(tmp_path: Path) -> None:
    text = ur_urdf_text(default_kinematics("ur5e", "urdf"))
    p = tmp_path / "ur.urdf"
    p.write_text(
        _urdf_with(
            text,
            '<joint name="flange-tool0" type="fixed">',
            '<joint name="flange-tool0" '
            'type="revolute"><axis xyz="0 0 1"/><limit lower="-1" upper="1" effort="1" velocity="1"/>',
        )
    )
    with pytest.raises(JointMismatchError, match=r"flange-tool0 .* is revolute; expected fixed"):
        urdf_fk(p, np.zeros((1, 6)))


# --- simulator: a KinematicsInfo in a message sent in pieces ----------------------------------------------------------


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


def test_rotations_are_exactly_the_textbook_matrices() -> None:
    from robocal.core.se3 import rot_x, rot_y, rot_z

    a = 0.3
    c, s = math.cos(a), math.sin(a)
    assert rot_x(a).tolist() == [[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]]
    assert rot_y(a).tolist() == [[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]]
    assert rot_z(a).tolist() == [[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]]
    assert rot_z(np.zeros((2, 5))).shape == (2, 5, 3, 3)


def test_conf_with_a_key_twice_is_refused(tmp_path: Path) -> None:
    from robocal.formats.ur_kinematics import read_deltas

    conf = tmp_path / "calibration.conf"
    zeros = "[0, 0, 0, 0, 0, 0]"
    conf.write_text(
        f"[mounting]\ndelta_theta = {zeros}\ndelta_a = {zeros}\ndelta_d = {zeros}\n"
        f"delta_alpha = {zeros}\ndelta_d = [0, 1, 0, 0, 0, 0]\n"
    )
    with pytest.raises(
        FileFormatError, match=rf"deltas file {conf} line 6: delta_d appears twice \(first on line 4\)"
    ):
        read_deltas(conf)


def test_huge_next_d_is_corrected_not_a_zero_division() -> None:
    # d3 = 1e300: |d3·u|² overflowed, the normalised axis became 0 and the division raised ZeroDivisionError
    n = nominal_dh("ur10e")
    dh = DHParameters(
        n.theta_rad,
        n.a_m,
        (0.1807, 1.0, 1e300, 0.17415, 0.11985, 0.11655),
        (1.570796327, 0.01, 0.0, 1.570796327, -1.570796327, 0.0),
    )
    kin = correct_kinematics(dh)
    forearm = kin.links[2]
    assert forearm.xyz_m[0] == pytest.approx(-math.hypot(-0.6127, math.tan(0.01)), abs=1e-15)
    assert kin.links[3].xyz_m[2] == 1e300


def test_deviation_of_absurd_lengths_does_not_overflow() -> None:
    import warnings

    from robocal.core.ur import deviation_from_nominal

    n = nominal_dh("ur10e")
    kin = correct_kinematics(
        DHParameters(n.theta_rad, (0.0, -1e300, -0.5, 0.0, 0.0, 0.0), n.d_m, n.alpha_rad)
    )
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # numpy's overflow RuntimeWarning would print on the CLI's stderr
        dev = deviation_from_nominal(kin)
    assert dev.length_m == 1e300 and dev.length_field == "a2"
