"""The manual sweep of an OpenArm: a person moves each joint into both stops while robocal's read-only Damiao bus
records the motors' readings (LeRobot's motor names as columns), then ``robocal sweep --source replay:`` computes
the zeros from the recording. Judged by the simulator's truth."""

from __future__ import annotations

import math
from importlib import resources
from pathlib import Path

import pytest

pytest.importorskip("can")

from robocal.backends.damiao.bus import DamiaoBus
from robocal.backends.damiao.openarm import SimOpenArm
from robocal.cli.main import main
from robocal.formats import read_calibration

URDF = Path(str(resources.files("robocal").joinpath("data", "openarm_v10_right.urdf")))


def _steps(a: float, b: float) -> list[float]:
    n = max(1, math.ceil(abs(b - a) / math.radians(30)))
    return [a + (b - a) * k / n for k in range(1, n + 1)]


def _record(arm: SimOpenArm, path: Path) -> None:
    """The person's sweep: every joint to its lower stop, its upper stop and back to 0 in 30° steps, read at each."""
    names = [j.name for j in arm.joints]
    rows = ["t," + ",".join(names)]
    with DamiaoBus(arm.channel, arm.motor_specs(), interface="virtual", timeout_s=1.0) as bus:  # read-only
        t = 0.0
        for j in arm.joints:
            moves = [*_steps(0.0, j.stop_lower_rad), *_steps(j.stop_lower_rad, j.stop_upper_rad),
                    *_steps(j.stop_upper_rad, 0.0)]
            for q in moves:
                arm.set_joint(j.name, q)
                states = bus.refresh()
                t += 0.5
                rows.append(f"{t:.3f}," + ",".join(repr(states[n].position_rad) for n in names))
        assert not any(m.enabled for m in arm.motors.values())  # nothing was switched on
    path.write_text("\n".join(rows) + "\n")


def test_live_hand_sweep_on_a_damiao_bus_is_refused_with_the_way_that_works(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    code = main(["sweep", "--robot", "openarm_follower_right", "--urdf", str(URDF), "--source", "can:virtual:x",
                 "--out", str(tmp_path / "c.yaml")])
    err = capsys.readouterr().err
    assert code == 2 and err.count("error:") == 1 and "use replay:FILE" in err
    assert not (tmp_path / "c.yaml").exists()


@pytest.mark.slow
def test_hand_sweep_from_a_recording_in_lerobots_motor_names(tmp_path: Path) -> None:
    arm = SimOpenArm(f"oa-hand-{id(tmp_path)}", seed=9).start()
    try:
        rec = tmp_path / "rec.csv"
        _record(arm, rec)
        out = tmp_path / "cal.yaml"
        code = main(["sweep", "--robot", "openarm_follower_right", "--urdf", str(URDF), "--source", f"replay:{rec}",
                     "--out", str(out)])
        assert code in (0, 1)  # 1: the sweep's hints about an arbitrary factory zero (wrap_in_travel, ...)
        cal = read_calibration(out).calibration
        for j in arm.joints:
            name = f"openarm_right_joint{j.name[-1]}" if j.name != "gripper" else "openarm_right_gripper_motor"
            got = cal.homing_offset[cal.index(name)]
            # the hand put each joint exactly on its stops: the zero is exact to the 16-bit field's step
            assert abs(math.degrees(got - arm.zero_error_rad(j.name))) < 0.05, name
    finally:
        arm.stop()
