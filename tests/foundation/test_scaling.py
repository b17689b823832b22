"""Joint-count scaling: lookups by name must be O(1), so file operations stay linear (benchmarks/bench_scaling.py
measures the time; these tests count name comparisons, which a quadratic search multiplies by N)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from counting import CountingName

from robocal.core import RobotCalibration
from robocal.core.chain import ChainJoint
from robocal.formats import CalibrationFile, read_calibration, write_calibration
from robocal.formats.urdf import UrdfModel, read_urdf
from robocal.workflows.files.job import check_calibration


def _names(n: int) -> list[str]:
    return [CountingName(f"joint_{i}") for i in range(n)]  # a new object per call: equal, not identical


def test_check_compares_each_name_a_bounded_number_of_times() -> None:
    n = 2000
    joints = tuple(ChainJoint(name, "revolute", f"l{i}", f"l{i + 1}") for i, name in enumerate(_names(n)))
    params = {name: {"direction": "-1", "can_id": str(i + 1)} for i, name in enumerate(_names(n))}
    model = UrdfModel("big", joints, params)
    cal = RobotCalibration(_names(n)[::-1], -1.0, np.full(n, 0.5))
    cf = CalibrationFile(cal, {name: n - i for i, name in enumerate(_names(n)[::-1])})
    CountingName.comparisons = 0
    report = check_calibration(cf, model)
    assert len(report.matched) == n and not report.missing and not report.extra
    assert report.ok
    assert model.joint("joint_1999").child == "l2000"
    # a list/tuple membership test per joint makes ~N²/2 = 2 million comparisons
    assert CountingName.comparisons < 20 * n


def _big_urdf(n: int) -> str:
    joints = "\n".join(
        f'  <joint name="j{i}" type="revolute"><parent link="l{i}"/><child link="l{i + 1}"/>'
        f'<limit lower="-1" upper="1"/></joint>'
        for i in range(n)
    )
    params = "\n".join(
        f'    <joint name="j{i}"><param name="can_id">{i + 1}</param><param name="direction">1</param></joint>'
        for i in range(n)
    )
    return (
        f'<robot name="big">\n{joints}\n  <ros2_control name="sys" type="system">\n{params}\n'
        "  </ros2_control>\n</robot>\n"
    )


def test_transmissions_appended_into_a_large_urdf_round_trip(tmp_path: Path) -> None:
    n = 1500
    urdf = tmp_path / "robot.urdf"
    urdf.write_text(_big_urdf(n))
    model = read_urdf(urdf)
    cal = RobotCalibration([f"j{i}" for i in range(n)], 1.0, np.linspace(-1, 1, n))
    write_calibration(urdf, cal, "ros2-transmission", urdf=model)
    back = read_calibration(urdf, "ros2-transmission").calibration
    assert back.joint_names == cal.joint_names
    np.testing.assert_allclose(back.homing_offset, cal.homing_offset, rtol=0, atol=1e-15)
    text = urdf.read_text()
    # every new transmission sits inside <ros2_control>, after its last joint, each on its own line
    assert text.index("<transmission") > text.index("<ros2_control")
    assert text.count("\n    <transmission name=") == n
    assert text.rstrip().endswith("</ros2_control>\n</robot>")


def test_check_prints_a_large_robot_as_plain_full_width_lines(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from robocal.cli.main import main

    n = 250  # above PLAIN_TABLE_ROWS: plain aligned text, no rich layout (≈ 1 ms per row), names never cut
    long = "left_shoulder_pitch_joint_with_a_rather_long_descriptive_name_"
    text = _big_urdf(n).replace('name="j', f'name="{long}j')
    urdf = tmp_path / "robot.urdf"
    urdf.write_text(text)
    cal = RobotCalibration([f"{long}j{i}" for i in range(n)], 1.0, np.linspace(-1, 1, n))
    cal_path = tmp_path / "cal.json"
    write_calibration(cal_path, cal, "lite-json", urdf=read_urdf(urdf))
    assert main(["check", "--calibration", str(cal_path), "--urdf", str(urdf)]) == 0
    out = capsys.readouterr().out.splitlines()
    assert out[0].endswith(f"{n}/{n} joints matched (lite-json)")
    header = out[1].split()
    assert header == ["joint", "id", "direction", "homing_offset", "status"]
    rows = [line.split() for line in out[2:]]
    assert len(rows) == n
    assert rows[0] == [f"{long}j0", "1", "+1", "-1.000000", "ok"]
    assert rows[-1] == [f"{long}j{n - 1}", str(n), "+1", "1.000000", "ok"]
