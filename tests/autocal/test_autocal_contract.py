"""Issue 11's CLI contract for ``--joints`` and for Ctrl-C while the files are written (both stacks).

``--joints`` with an empty list, an empty entry, an unknown joint or a joint the profile gives no hard stop is one
``error:`` line, exit 2, before anything moves (the drivers are never opened, the clear-workspace question is
never asked) and nothing written. Ctrl-C (or any error) between the report and the calibration of ``sweep --auto``
puts both files, and their backups, back as they were.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest

pytest.importorskip("can")

from robocal.backends.sim.lite import lite_urdf_text
from robocal.cli.main import main
from robocal.core.profile_auto import AutoSection
from robocal.errors import UsageError
from robocal.fileio import backup_paths
from robocal.formats.profiles import load_profile
from robocal.lerobot import read_calibration
from robocal.workflows.autocal.job import select_joints
from robocal.workflows.autocal.sim import SimAutoLite, sim_opener
from robocal.workflows.autocal.sweep import SweepAutoRequest, run_sweep_auto
from robocal.workflows.lerobot import robot_spec
from robocal.workflows.lerobot.auto import AutoCalibrationRequest, auto_calibrate, auto_section

pytestmark = pytest.mark.timeout(600)

JOINTS = ["left_wrist_roll", "left_wrist_pitch"]


def calibrate_args(folder: Path, *extra: str, robot: str, robot_id: str) -> list[str]:
    """``lerobot calibrate`` of the simulated ``robot`` into ``folder``."""
    return ["lerobot", "calibrate", "--robot", robot, "--port", "sim", "--id", robot_id,
            "--calibration-dir", str(folder), *extra]  # fmt: skip


@pytest.fixture
def urdf(tmp_path: Path) -> Path:
    p = tmp_path / "lite.urdf"
    p.write_text(lite_urdf_text())
    return p


def _files(folder: Path) -> dict[str, bytes]:
    return {str(p.relative_to(folder)): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()}


@pytest.mark.parametrize(
    ("joints", "message"),
    [
        ("", "--joints '': expected comma-separated names with no empty entries"),
        (",", "--joints ',': expected comma-separated names with no empty entries"),
        ("left_wrist_roll,,left_wrist_pitch", "no empty entries"),
        ("left_wrist_roll,nope", "--joints: no auto-calibration entry for nope"),
    ],
)
def test_sweep_auto_bad_joints_exit_2_nothing_moved_or_written(
    urdf: Path, tmp_path: Path, joints: str, message: str, capsys: pytest.CaptureFixture[str]
) -> None:
    out, report = tmp_path / "out" / "c.yaml", tmp_path / "out" / "r.json"
    out.parent.mkdir()
    args = ["sweep", "--auto", "--urdf", str(urdf), "--robot", "bhl_arms", "--source", "sim:lite"]
    rc = main([*args, "--out", str(out), "--report", str(report), "--joints", joints, "--yes"])
    err = capsys.readouterr().err
    assert rc == 2
    assert err.count("error:") == 1 and message in err and "Traceback" not in err
    assert "searching its stops" not in err  # no joint started
    assert list(out.parent.iterdir()) == []


def test_sweep_auto_refuses_an_empty_subset_before_the_drivers_open(urdf: Path, tmp_path: Path) -> None:
    opened: list[Any] = []

    def opener(*args: Any) -> Any:
        opened.append(args)
        raise AssertionError("the drivers must not be opened")

    with pytest.raises(UsageError, match="--joints: give at least one joint name"):
        run_sweep_auto(
            SweepAutoRequest(
                urdf,
                "sim:lite",
                tmp_path / "c.yaml",
                robot="bhl_arms",
                joints=[],
            ),
            open_drivers_fn=opener,
        )
    assert opened == [] and not (tmp_path / "c.yaml").exists()


def test_select_joints_refuses_stopless_joints_only_when_named() -> None:
    section = load_profile("koch_follower").auto
    assert isinstance(section, AutoSection)
    everything = select_joints(section, None, movable_only=True)  # no --joints: the whole profile
    assert [j.name for j in everything if not j.searched] == ["shoulder_pan", "wrist_roll"]
    with pytest.raises(
        UsageError, match=r"--joints: shoulder_pan cannot be auto-calibrated.*full-turn motor"
    ):
        select_joints(section, ["gripper", "shoulder_pan"], movable_only=True)
    with pytest.raises(UsageError, match="give at least one joint name"):
        select_joints(section, [])
    # run_autocal's own call (the whole section, not a user's choice) still takes them
    assert [j.name for j in select_joints(section, ["gripper", "wrist_roll"])] == ["gripper", "wrist_roll"]


@pytest.mark.parametrize(
    ("joints", "message"),
    [
        (
            "shoulder_pan",
            "--joints: shoulder_pan cannot be auto-calibrated, the profile gives it no hard stop",
        ),
        ("gripper,wrist_roll", "--joints: wrist_roll cannot be auto-calibrated"),
        ("", "no empty entries"),
        ("gripper,", "no empty entries"),
        ("gripper,nope", "--joints: no auto-calibration entry for nope"),
    ],
)
def test_lerobot_auto_bad_joints_exit_2_nothing_moved_or_written(
    tmp_path: Path, joints: str, message: str, capsys: pytest.CaptureFixture[str]
) -> None:
    args = calibrate_args(
        tmp_path, "--auto", "--yes", "--joints", joints, robot="koch_follower", robot_id="k"
    )
    rc = main(args)
    err = capsys.readouterr().err
    assert rc == 2
    assert err.count("error:") == 1 and message in err and "Traceback" not in err
    assert "searching its stops" not in err
    assert _files(tmp_path) == {}


def test_lerobot_auto_stopless_joint_is_refused_before_the_question() -> None:
    from robocal.workflows.lerobot.auto_sim import open_auto_arm

    spec = robot_spec("koch_follower")
    section = auto_section("koch_follower")
    asked: list[Any] = []
    with open_auto_arm(spec, "sim", section) as arm:
        before = arm.sim.eeprom()
        with pytest.raises(UsageError, match="wrist_roll cannot be auto-calibrated"):
            auto_calibrate(
                arm.bus,
                AutoCalibrationRequest(
                    spec,
                    section,
                    joints=["gripper", "wrist_roll"],
                ),
                clock=arm.clock,
                confirm_start=lambda *a: bool(asked.append(a)) or True,
            )
        assert arm.sim.eeprom() == before
    assert asked == []


@pytest.mark.slow
@pytest.mark.parametrize("report_exists", [True, False])
def test_ctrl_c_between_the_report_and_the_calibration_leaves_both_unchanged(
    urdf: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch, report_exists: bool
) -> None:
    import robocal.workflows.sweep.job as sweep_module

    out, report = tmp_path / "cal.yaml", tmp_path / "report.json"
    out.write_text("left_wrist_roll:\n  id: 16\n  direction: -1\n  homing_offset: 0.25\n")
    backup_paths(out)[0].write_text("an older calibration\n")
    if report_exists:
        report.write_text('{"joints": {}}\n')
    before = _files(tmp_path)
    calls: list[Path] = []

    def interrupted(path: Any, *args: Any, **kwargs: Any) -> None:
        calls.append(Path(path))
        raise KeyboardInterrupt

    monkeypatch.setattr(sweep_module, "write_calibration", interrupted)
    holder: list[SimAutoLite] = []
    with pytest.raises(KeyboardInterrupt):
        run_sweep_auto(
            SweepAutoRequest(
                urdf,
                "sim:lite?seed=2",
                out,
                robot="bhl_arms",
                joints=JOINTS,
                report=report,
            ),
            open_drivers_fn=sim_opener(holder),
        )
    assert calls == [out]  # the report was written, then Ctrl-C came
    assert _files(tmp_path) == before  # the report (and its backup) as before, or gone if it was new
    assert all(m.mode == 0 for m in holder[0].motors.values())  # every motor limp
    assert all(m.drive().tau_max_nm == 0.0 for m in holder[0].motors.values())


@pytest.mark.slow
def test_disk_error_on_the_calibration_takes_the_report_back(
    urdf: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    import robocal.workflows.sweep.job as sweep_module

    out, report = tmp_path / "cal.yaml", tmp_path / "report.json"

    def full(path: Any, *args: Any, **kwargs: Any) -> None:
        raise OSError(28, "No space left on device", str(path))

    monkeypatch.setattr(sweep_module, "write_calibration", full)
    rc = main(
        [
            "sweep", "--auto", "--urdf", str(urdf), "--robot", "bhl_arms", "--source", "sim:lite?seed=2",
            "--out", str(out), "--report", str(report), "--joints", "left_wrist_roll", "--yes",
        ]
    )  # fmt: skip
    err = capsys.readouterr().err
    assert rc != 0 and err.count("error:") == 1 and "No space left on device" in err
    assert _files(tmp_path) == {"lite.urdf": urdf.read_bytes()}


def test_lerobot_json_unchanged_when_the_auto_run_is_refused(tmp_path: Path) -> None:
    """A refused subset leaves an existing LeRobot file as it was (byte for byte)."""
    assert main(calibrate_args(tmp_path, robot="koch_follower", robot_id="k")) == 0  # the hand procedure
    folder = tmp_path / "robots" / "koch_follower"
    before = _files(folder)
    assert read_calibration(folder / "k.json")
    assert (
        main(
            calibrate_args(
                tmp_path, "--auto", "--yes", "--joints", "shoulder_pan", robot="koch_follower", robot_id="k"
            )
        )
        == 2
    )
    assert _files(folder) == before


def test_the_question_names_every_joint_that_moves_and_its_cap(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    import sys

    import typer

    from robocal.cli._autocal import make_confirm_start

    asked: list[str] = []
    monkeypatch.setattr(sys.stdin, "isatty", lambda: True)
    monkeypatch.setattr(typer, "confirm", lambda text, default=False: bool(asked.append(text)))
    confirm = make_confirm_start(False, what="so101_follower")
    assert make_confirm_start(True) is None  # --yes: no question
    caps = {"shoulder_lift": 0.859, "gripper": 0.477}
    assert confirm(tuple(caps), caps) is False  # the default answer is no
    out = capsys.readouterr().out
    assert asked == ["Start?"]
    assert "these 2 joints of the so101_follower will move on their own" in out
    assert "pushing with at most 0.86 N·m" in out
    assert "  shoulder_lift  (cap 0.86 N·m)" in out and "  gripper  (cap 0.48 N·m)" in out
    assert "Ctrl-C at any time makes every motor limp at once." in out


def test_the_question_states_each_cap_as_a_share_of_the_motors_rating_and_what_a_lost_host_leaves(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    import sys

    import typer

    from robocal.cli._autocal import make_confirm_start
    from robocal.formats.profiles import load_profile
    from robocal.workflows.autocal.model import JointCaps
    from robocal.workflows.lerobot.auto import HOST_LOSS

    monkeypatch.setattr(sys.stdin, "isatty", lambda: True)
    monkeypatch.setattr(typer, "confirm", lambda text, default=False: False)
    section = load_profile("so101_follower").auto
    assert section is not None
    caps = JointCaps(section.searched_joints[:2], HOST_LOSS["feetech"])
    assert make_confirm_start(False, what="so101_follower")(tuple(caps), caps) is False
    out = capsys.readouterr().out
    assert "  shoulder_lift  (cap 0.86 N·m = 45 % of the STS3215's 1.91 N·m rating)" in out
    assert "  elbow_flex  (cap 0.76 N·m = 40 % of the STS3215's 1.91 N·m rating)" in out
    assert "Feetech STS servos have no host-loss watchdog: if robocal is killed or the cable is pulled" in out
