"""Runtime joint-frame read/write over the virtual CAN bus (CalibratedRobot)."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from robocal.backends.sim.lite import SimLite
from robocal.backends.sources import SimLiteSource
from robocal.core import RobotCalibration
from robocal.errors import ShapeMismatchError, UsageError
from robocal.formats import read_calibration
from robocal.formats.urdf import read_urdf
from robocal.workflows.sweep.job import SweepRequest, run_sweep
from robocal.workflows.sweep.joint_specs import joints_from_urdf
from robocal.workflows.sweep.robot import CalibratedRobot, open_robot


def _robot(urdf: Path, cal_path: Path, sim: SimLite) -> CalibratedRobot:
    joints = joints_from_urdf(read_urdf(urdf))
    names = [j.name for j in joints]
    cal = read_calibration(cal_path).calibration.select(names)
    sim.start()
    src = SimLiteSource(joints, sim)
    return CalibratedRobot(cal, np.array([j.lower for j in joints]), np.array([j.upper for j in joints]), src)


@pytest.mark.slow
def test_read_after_power_cycle_and_write_mapping(urdf: Path, tmp_path: Path, h: Any) -> None:
    # elbow travel crosses the power-on wrap point (zero_sta 0): after a power cycle at q = -2.2 the raw
    # reading jumps a turn; the first read picks the branch inside the limits
    sim = SimLite(21, noise_rad=0.0, zero_sta=0, factory_zero_rad={"left_elbow_pitch": -0.6})
    cal_path = tmp_path / "cal.yaml"
    run_sweep(SweepRequest(urdf, "sim:lite", cal_path), open_source_fn=h.sim_opener(sim))
    sim.motors["left_elbow_pitch"].set_position(-0.2)  # raw = 0.2 - 0.6 = -0.4 -> 2π - 0.4 after power-on
    sim.power_cycle()
    truth_q = sim.joint_positions()
    with _robot(urdf, cal_path, sim) as robot:
        state = robot.read()
        for i, name in enumerate(robot.joint_names):
            assert state.position_rad[i] == pytest.approx(truth_q[name], abs=1e-3), name
        shift = robot.branch_shift_rad
        assert shift is not None
        i_el = robot.joint_names.index("left_elbow_pitch")
        assert abs(shift[i_el]) == pytest.approx(2 * math.pi)
        turns = shift / (2 * math.pi)
        assert np.allclose(turns, np.round(turns))  # only whole turns are ever added

        n = len(robot.joint_names)
        q_cmd = np.linspace(-0.3, 0.2, n)
        v_cmd = np.full(n, 0.5)
        tau = np.full(n, 1.0)
        robot.write(q_cmd, v_cmd, kp=20.0, kd=1.0, torque_nm=tau)
        cal: RobotCalibration = robot.calibration
        for i, name in enumerate(robot.joint_names):
            motor = sim.motors[name]
            assert motor.last_command is not None
            p, v, kp, kd, t = motor.last_command
            d = cal.direction[i]
            expected_raw = d * q_cmd[i] + cal.homing_offset[i] - shift[i]
            assert p == pytest.approx(expected_raw, abs=5e-4), name  # full map
            assert v == pytest.approx(d * 0.5, abs=5e-3)  # direction only
            assert t == pytest.approx(d * 1.0, abs=5e-3)  # direction only
            assert kp == pytest.approx(20.0, abs=0.01) and kd == pytest.approx(1.0, abs=0.01)  # unchanged


@pytest.mark.slow
def test_write_errors(urdf: Path, tmp_path: Path, h: Any) -> None:
    sim = SimLite(22, noise_rad=0.0)
    cal_path = tmp_path / "cal.yaml"
    run_sweep(SweepRequest(urdf, "sim:lite", cal_path), open_source_fn=h.sim_opener(sim))
    with _robot(urdf, cal_path, sim) as robot:
        with pytest.raises(UsageError, match=r"before the first robot\.read"):
            robot.write(np.zeros(14))
        robot.read()
        with pytest.raises(ShapeMismatchError, match="position must be 14 finite numbers"):
            robot.write(np.zeros(3))
        with pytest.raises(ShapeMismatchError, match="kp"):
            robot.write(np.zeros(14), kp=[math.nan] * 14)


@pytest.mark.slow
def test_open_robot_from_source_string(urdf: Path, tmp_path: Path) -> None:
    cal_path = tmp_path / "cal.yaml"
    run_sweep(SweepRequest(urdf, "sim:lite?seed=3", cal_path))
    with open_robot(urdf, cal_path, "sim:lite?seed=3&noise=0") as robot:
        state = robot.read()
        assert state.position_rad.shape == (14,) and np.all(np.isfinite(state.position_rad))
        lo = np.array([j.lower for j in joints_from_urdf(read_urdf(urdf))])
        assert np.all(state.position_rad >= lo - 0.05)
    with pytest.raises(UsageError, match="not a replay"):
        open_robot(urdf, cal_path, "replay:x.csv")


@pytest.mark.slow
def test_read_after_write_holds_the_targets(urdf: Path, tmp_path: Path, h: Any) -> None:
    # a read between two writes must not replace the running targets with the zero-torque frame
    sim = SimLite(23, noise_rad=0.0)
    cal_path = tmp_path / "cal.yaml"
    run_sweep(SweepRequest(urdf, "sim:lite", cal_path), open_source_fn=h.sim_opener(sim))
    with _robot(urdf, cal_path, sim) as robot:
        assert robot.read().position_rad.shape == (14,)
        first = {n: m.last_command for n, m in sim.motors.items()}
        assert all(c is not None and c[2] == 0.0 and c[3] == 0.0 for c in first.values())  # passive poll
        q = np.linspace(-0.2, 0.1, 14)
        robot.write(q, kp=20.0, kd=1.0, torque_nm=0.5)
        written = {n: m.last_command for n, m in sim.motors.items()}
        state = robot.read()
        for name, motor in sim.motors.items():
            assert motor.last_command == written[name], name
            assert motor.last_command is not None and motor.last_command[2] == pytest.approx(20.0, abs=0.01)
        assert np.all(np.isfinite(state.position_rad))


@pytest.mark.slow
def test_write_rejects_bad_gains_and_types(urdf: Path, tmp_path: Path, h: Any) -> None:
    sim = SimLite(24, noise_rad=0.0)
    cal_path = tmp_path / "cal.yaml"
    run_sweep(SweepRequest(urdf, "sim:lite", cal_path), open_source_fn=h.sim_opener(sim))
    with _robot(urdf, cal_path, sim) as robot:
        q = robot.read().position_rad
        with pytest.raises(UsageError, match=r"joint 'left_shoulder_pitch' \(RS02\): kp -1 / kd 0 outside"):
            robot.write(q, kp=-1.0)
        with pytest.raises(UsageError, match=r"kp 600 / kd 1 outside 0\.\.500 / 0\.\.5"):
            robot.write(q, kp=600.0, kd=1.0)
        with pytest.raises(ShapeMismatchError, match="velocity must be 14 finite numbers, got 'fast'"):
            robot.write(q, velocity_rad_s="fast")  # type: ignore[arg-type]
        assert all(m.last_command is None or m.last_command[2] == 0.0 for m in sim.motors.values())


@pytest.mark.slow
def test_enable_disable_and_close_stops_enabled_motors(urdf: Path, tmp_path: Path, h: Any) -> None:
    sim = SimLite(29, noise_rad=0.0)
    cal_path = tmp_path / "cal.yaml"
    run_sweep(SweepRequest(urdf, "sim:lite", cal_path), open_source_fn=h.sim_opener(sim))
    with _robot(urdf, cal_path, sim) as robot:
        robot.read()
        assert {m.mode for m in sim.motors.values()} == {0}  # never enabled by reading
        state = robot.enable()
        assert state.position_rad.shape == (14,)
        assert {m.mode for m in sim.motors.values()} == {2}
        robot.disable()
        assert {m.mode for m in sim.motors.values()} == {0}
        robot.enable()
    assert {m.mode for m in sim.motors.values()} == {0}  # close() stopped what it had enabled


def test_read_follows_the_four_pi_feedback_wrap(urdf: Path, tmp_path: Path) -> None:
    # a joint turned far past ±4π of raw travel (a continuous joint, stops removed in the simulator): the
    # type-2 position loops within ±4π, and the runtime robot must keep the joint position continuous
    sim = SimLite(25, noise_rad=0.0)
    name = "left_shoulder_yaw"  # direction +1
    motor = sim.motors[name]
    motor.stop_lower_rad, motor.stop_upper_rad = -40.0, 40.0
    truth = sim.true_offsets()
    cal_path = tmp_path / "cal.yaml"
    cal_path.write_text(
        "".join(
            f"{j.name}:\n  id: {j.can_id}\n  direction: {j.direction}\n  homing_offset: {truth[j.name]!r}\n"
            for j in sim.joints
        )
    )
    with _robot(urdf, cal_path, sim) as robot:
        i = robot.joint_names.index(name)
        path = [*np.arange(0.0, 30.0, 0.5), *np.arange(30.0, -30.0, -0.5), -30.0]  # past +4π twice, then −4π
        seen = []
        for q in path:
            motor.set_position(float(q))
            state = robot.read()
            seen.append(state.position_rad[i])
            assert state.position_rad[i] == pytest.approx(q, abs=1e-3), q
            assert abs(motor.reading_rad(noisy=False)) <= 4 * math.pi  # the motor itself did wrap
        assert np.max(np.abs(np.diff(seen))) == pytest.approx(0.5, abs=1e-3)  # no 8π jump anywhere
        wraps = robot.wrap_shift_rad[i] / (8 * math.pi)
        assert wraps == round(wraps) and wraps != 0  # whole 8π loops only
        # a write at the current joint position targets the motor's own (wrapped) reading: it holds still
        robot.write(state.position_rad, kp=20.0, kd=1.0)
        assert motor.last_command is not None
        assert motor.last_command[0] == pytest.approx(motor.reading_rad(noisy=False), abs=1e-3)  # 2 LSB


@pytest.mark.slow
def test_tick_frames_and_states_are_the_reference_formula_bit_for_bit(
    urdf: Path, tmp_path: Path, h: Any, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The per-tick fast path (fused map, precomputed limits) sends and returns exactly the reference numbers,
    and looks nothing up per tick (model limits are resolved once, when the robot is built)."""
    import robocal.workflows.sweep.robot as robot_mod

    sim = SimLite(23, noise_rad=0.0)
    cal_path = tmp_path / "cal.yaml"
    run_sweep(SweepRequest(urdf, "sim:lite", cal_path), open_source_fn=h.sim_opener(sim))
    with _robot(urdf, cal_path, sim) as robot:
        calls = {"model_limits": 0}
        real = robot_mod.model_limits

        def counting(model: str) -> Any:
            calls["model_limits"] += 1
            return real(model)

        monkeypatch.setattr(robot_mod, "model_limits", counting)
        cal: RobotCalibration = robot.calibration
        robot.read()
        sent: list[dict[str, tuple[float, ...]]] = []
        replies: list[dict[str, Any]] = []
        for bus in robot.source.buses:
            orig = bus.mit_many

            def spy(cmds: Any, orig: Any = orig) -> Any:
                sent.append(dict(cmds))
                out = orig(cmds)
                replies.append(out)
                return out

            monkeypatch.setattr(bus, "mit_many", spy)
        n = len(robot.joint_names)
        q = np.linspace(-0.4, 0.3, n)
        v = np.linspace(0.5, -0.5, n)
        tau = np.linspace(-1.0, 1.0, n)
        state = robot.write(q, v, kp=15.0, kd=0.5, torque_nm=tau)
        shift, wrap = robot.branch_shift_rad, robot.wrap_shift_rad
        assert shift is not None
        p_ref = cal.to_raw(q) - shift - wrap
        v_ref, t_ref = cal.velocity_to_raw(v), cal.effort_to_raw(tau)
        frames = {name: cmd for bus_cmds in sent for name, cmd in bus_cmds.items()}
        for i, name in enumerate(robot.joint_names):
            assert frames[name] == (p_ref[i], v_ref[i], 15.0, 0.5, t_ref[i]), name
        fb = {name: f for r in replies for name, f in r.items()}
        raw = np.array([fb[name].position_rad for name in robot.joint_names])
        vel = np.array([fb[name].velocity_rad_s for name in robot.joint_names])
        eff = np.array([fb[name].torque_nm for name in robot.joint_names])
        assert np.array_equal(state.position_rad, cal.to_joint(raw + shift + wrap))
        assert np.array_equal(state.velocity_rad_s, cal.velocity_to_joint(vel))
        assert np.array_equal(state.effort_nm, cal.effort_to_joint(eff))
        for _ in range(3):
            robot.read()
            robot.write(q, v, kp=15.0, kd=0.5, torque_nm=tau)
        assert calls["model_limits"] == 0
