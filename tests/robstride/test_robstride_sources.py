"""Source strings, the can: source on virtual channels (discovery, silent motors), replay errors."""

from __future__ import annotations

import itertools
from pathlib import Path

import numpy as np
import pytest

from robocal.backends.robstride.sim import SimMotor, SimMotorBus
from robocal.backends.sim.lite import LITE_JOINTS, SimLite, lite_urdf_text
from robocal.backends.sources import JointSpec, open_source, parse_source
from robocal.cli.main import main
from robocal.errors import CalibTimeoutError, FileFormatError, JointMismatchError, UsageError

_n = itertools.count()
JOINTS = [JointSpec(j.name, j.can_id, j.model, j.direction, j.lower, j.upper) for j in LITE_JOINTS]


def test_parse_source_forms() -> None:
    s = parse_source("sim:lite?seed=4&noise=0.001&skip=a,b")
    assert (s.kind, s.robot, dict(s.options)) == (
        "sim",
        "lite",
        {"seed": "4", "noise": "0.001", "skip": "a,b"},
    )
    assert parse_source("sim:lite?skip=a&skip=b,c").options["skip"] == "a,b,c"
    c = parse_source("can:socketcan:can0,can1")
    assert (c.kind, c.interface, c.channels) == ("can", "socketcan", ("can0", "can1"))
    r = parse_source("replay:/tmp/x.mcap")
    assert (r.kind, r.path) == ("replay", "/tmp/x.mcap")
    for bad, msg in [
        ("sim", "expected sim:lite"),
        ("usb:x", "unknown kind 'usb'"),
        ("can:socketcan:can0,can0", "listed twice"),
        ("can:socketcan:can0,", "expected can:<interface>"),
        ("sim:lite?noise=-1", "noise must be a number >= 0"),
        ("sim:lite?seed", "malformed options"),
        ("sim:lite?seed=\u00b2", "seed must be a non-negative integer"),  # str.isdigit() is True for '²'
        ("sim:lite?zero_sta=2", "zero_sta must be 0 or 1, got '2'"),
        ("sim:lite?seed=1&seed=2", "option 'seed' is given 2 times"),
        ("sim:lite?single_turn=7", "single_turn must be 0 or 1"),
    ]:
        with pytest.raises(UsageError, match=msg):
            parse_source(bad)


@pytest.mark.slow
def test_can_source_finds_joints_on_two_channels() -> None:
    sim = SimLite(3, noise_rad=0.0, channel_prefix=f"src-test-{next(_n)}")
    with sim:
        # the probe waits this long on each channel (half the ids are elsewhere); every motor must answer within
        # it, however loaded the machine is
        src = open_source(f"can:virtual:{sim.channels['can0']},{sim.channels['can1']}", JOINTS, timeout_s=1.0)
        try:
            assert [sorted(b.motors) for b in src.buses] == [
                sorted(j.name for j in LITE_JOINTS if j.bus == "can0"),
                sorted(j.name for j in LITE_JOINTS if j.bus == "can1"),
            ]
            s = src.read()
            assert s is not None and src.frame == "motor"
            expected = [sim.motors[j.name].reading_rad(noisy=False) for j in LITE_JOINTS]
            np.testing.assert_allclose(s.position_rad, expected, atol=4e-4)
            assert src.zero_sta() == {j.name: 1 for j in LITE_JOINTS}
            assert all(m.requests.get(6, 0) == 0 and m.mode == 0 for m in sim.motors.values())
        finally:
            src.close()


@pytest.mark.slow
def test_can_source_names_a_motor_that_never_answers() -> None:
    sim = SimLite(3, channel_prefix=f"src-test-{next(_n)}", silent=["right_elbow_pitch"])
    with sim:
        text = f"can:virtual:{sim.channels['can0']},{sim.channels['can1']}"
        with pytest.raises(CalibTimeoutError, match=r"'right_elbow_pitch' \(CAN id 24\)"):
            open_source(text, JOINTS, timeout_s=1.0)  # the other 13 must answer within it, however loaded


def test_sweep_cli_device_failure_exit_3(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    urdf = tmp_path / "lite.urdf"
    urdf.write_text(lite_urdf_text())
    ch = f"src-test-{next(_n)}"
    # one channel, only the left arm answers: the right arm's first poll times out
    motors = [SimMotor(can_id=j.can_id, model=j.model) for j in LITE_JOINTS if j.bus == "can0"]
    with SimMotorBus(ch, motors):
        rc = main(
            ["sweep", "--urdf", str(urdf), "--source", f"can:virtual:{ch}", "--out", str(tmp_path / "c.yaml")]
        )
    err = capsys.readouterr().err
    assert rc == 3 and not (tmp_path / "c.yaml").exists()
    lines = [ln for ln in err.splitlines() if ln.startswith("error:")]
    assert len(lines) == 1 and "right_shoulder_pitch" in lines[0] and "CAN id 21" in lines[0]


def test_sim_source_rejects_unknown_joint() -> None:
    with pytest.raises(JointMismatchError, match="sim:lite has no joint"):
        open_source("sim:lite", [JointSpec("neck_yaw", 31)])


def test_replay_errors(tmp_path: Path) -> None:
    names = ["a", "b"]
    cases = {
        "x,a\n0,1\n": "first column is 'x'",
        "t,a\n": "no samples after the header",
        "t,a\n0,1,2\n": "line 2 has 3 cells",
        "t,a\n0,inf\n": "a is not finite",
        "t,a\n1,0\n0,0\n": "not in time order",
        "t,a,a\n0,1,1\n": "appears twice",
    }
    for i, (text, msg) in enumerate(cases.items()):
        p = tmp_path / f"r{i}.csv"
        p.write_text(text)
        with pytest.raises(FileFormatError, match=msg):
            open_source(f"replay:{p}", [JointSpec(n) for n in names])
    none = tmp_path / "none.csv"
    none.write_text("t,c\n0,1\n")
    with pytest.raises(JointMismatchError, match="0/2 joints matched; it has c"):
        open_source(f"replay:{none}", [JointSpec(n) for n in names])
    ok = tmp_path / "ok.csv"
    ok.write_text("t,b,zzz\n0,1.5,9\n0.1,2.5,9\n")
    src = open_source(f"replay:{ok}", [JointSpec(n) for n in names])
    s = src.read()
    assert s is not None and np.isnan(s.position_rad[0]) and s.position_rad[1] == 1.5
    with pytest.raises(FileFormatError, match="cannot read rosbag2"):
        (tmp_path / "notabag").mkdir()
        open_source(f"replay:{tmp_path / 'notabag'}", [JointSpec(n) for n in names])


def test_rosbag_wrong_topic_lists_topics(tmp_path: Path) -> None:
    from rosbags.rosbag2 import StoragePlugin, Writer
    from rosbags.typesys import Stores, get_typestore

    ts = get_typestore(Stores.ROS2_HUMBLE)
    JS = ts.types["sensor_msgs/msg/JointState"]
    H = ts.types["std_msgs/msg/Header"]
    T = ts.types["builtin_interfaces/msg/Time"]
    bag = tmp_path / "bag"
    with Writer(bag, version=8, storage_plugin=StoragePlugin.MCAP) as w:
        c = w.add_connection("/other", JS.__msgtype__, typestore=ts)
        m = JS(H(T(1, 0), ""), ["a"], np.array([0.5]), np.zeros(0), np.zeros(0))
        w.write(c, 1_000_000_000, ts.serialize_cdr(m, JS.__msgtype__))
    with pytest.raises(FileFormatError, match=r"no topic '/lite/joint_states'; has /other \(pass --topic\)"):
        open_source(f"replay:{bag}", [JointSpec("a")])
    src = open_source(f"replay:{bag}", [JointSpec("a")], topic="/other")
    s = src.read()
    assert s is not None and s.position_rad[0] == 0.5 and s.t_s == 1.0


def test_check_cli_with_source(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    urdf = tmp_path / "lite.urdf"
    urdf.write_text(lite_urdf_text())
    cal = tmp_path / "cal.yaml"
    assert main(["sweep", "--urdf", str(urdf), "--source", "sim:lite?seed=9", "--out", str(cal)]) in (0, 1)
    capsys.readouterr()
    rc = main(["check", "--urdf", str(urdf), "--calibration", str(cal), "--source", "sim:lite?seed=9"])
    out = capsys.readouterr().out
    assert rc in (0, 1)
    assert "left_elbow_pitch: q = " in out and out.count(": q = ") == 14


def test_can_source_unknown_interface_is_bad_input() -> None:
    with pytest.raises(
        UsageError, match=r"CAN interface 'bogus' is unknown to python-can; expected one of .*virtual"
    ):
        open_source("can:bogus:can0", JOINTS)


def test_can_source_single_channel_uses_the_timeout_and_names_a_bad_model() -> None:
    ch = f"src-test-{next(_n)}"
    src = open_source(f"can:virtual:{ch}", JOINTS[:2], timeout_s=0.37)
    try:
        assert [b.timeout_s for b in src.buses] == [0.37]
    finally:
        src.close()
    bad = [JointSpec("left_elbow_pitch", 14, "rs-99")]
    with pytest.raises(UsageError, match=r"joint 'left_elbow_pitch': unknown Robstride model 'rs-99'"):
        open_source(f"can:virtual:{ch}", bad)


def test_csv_with_a_byte_order_mark(tmp_path: Path) -> None:
    p = tmp_path / "excel.csv"
    p.write_bytes("\ufefft,a\r\n0,0.5\r\n".encode())
    s = open_source(f"replay:{p}", [JointSpec("a")]).read()
    assert s is not None and s.position_rad[0] == 0.5
