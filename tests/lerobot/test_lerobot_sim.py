"""Vendor SDKs against the simulated servos on a pty, and the calibration workflow with robocal's fixes."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from robocal.backends.dynamixel import DynamixelBus
from robocal.backends.feetech import FeetechBus
from robocal.backends.sim.lerobot_arms import DEFAULT_TRUTH, JointTruth, SimArm, SimArmOperator
from robocal.backends.sim.servo import SimServo, SimServoBus, dxl_crc16
from robocal.errors import CalibTimeoutError, DeviceError, ProtocolError
from robocal.lerobot import MotorCalibration, read_calibration
from robocal.workflows.lerobot import CalibrateRequest, calibrate, check, open_bus, restore, robot_spec

from .conftest import PREVIOUS

pytestmark = pytest.mark.timeout(60)


@pytest.fixture
def feetech_sim() -> Iterator[tuple[SimServoBus, FeetechBus]]:
    with SimServoBus([SimServo(1, "sts3215", 1337.0), SimServo(2, "sts3215", 3000.0)]) as sim:
        bus = FeetechBus(sim.port, {1: "sts3215", 2: "sts3215"}, retries=1)
        yield sim, bus
        bus.close()


@pytest.fixture
def dxl_sim() -> Iterator[tuple[SimServoBus, DynamixelBus]]:
    with SimServoBus([SimServo(1, "xl330-m288", 1337.0), SimServo(2, "xl430-w250", 3672.0)]) as sim:
        bus = DynamixelBus(sim.port, {1: "xl330-m288", 2: "xl430-w250"}, retries=1)
        yield sim, bus
        bus.close()


# ------------------------------------------------------------------------------------- SDK ↔ simulator
def test_feetech_sdk_registers_and_sign_magnitude(feetech_sim: tuple[SimServoBus, FeetechBus]) -> None:
    sim, bus = feetech_sim
    assert bus.ping(1) == 777
    assert bus.sync_read("Present_Position", [1, 2]) == {1: 1337, 2: 3000}
    bus.write("Homing_Offset", 1, -710)  # the half-turn homing of pose 1337
    assert bytes(sim.servos[1].regs[31:33]) == bytes([0xC6, 0x0A])  # 2758 = 0x0AC6, little-endian
    assert bus.read("Homing_Offset", 1) == -710
    assert bus.read("Present_Position", 1) == 2047  # Present = Actual − Homing_Offset
    bus.sync_write("Homing_Offset", {1: 0, 2: 1625})
    assert bus.sync_read("Homing_Offset", [1, 2]) == {1: 0, 2: 1625}
    assert bus.read("Present_Position", 2) == 3000 - 1625


def test_feetech_multi_turn_feedback_and_goal(feetech_sim: tuple[SimServoBus, FeetechBus]) -> None:
    sim, bus = feetech_sim
    sim.servos[1].move_to(4368.0)
    assert bus.read("Present_Position", 1) == 4368 - 4096  # Phase bit 4 clear: single-turn
    bus.write("Phase", 1, 0x10)
    assert bus.read("Present_Position", 1) == 4368  # multi-turn feedback (huggingface/lerobot#1296)
    bus.write("Torque_Enable", 2, 1)
    bus.write("Goal_Position", 2, 2500)
    assert bus.read("Present_Position", 2) == 2500


def test_dynamixel_sdk_twos_complement_and_drive_mode(dxl_sim: tuple[SimServoBus, DynamixelBus]) -> None:
    sim, bus = dxl_sim
    assert (bus.ping(1), bus.ping(2)) == (1200, 1060)
    bus.write("Homing_Offset", 2, 2047 - 3672)
    assert bytes(sim.servos[2].regs[20:24]) == (4294965671).to_bytes(4, "little")
    assert bus.read("Present_Position", 2) == 2047  # Present = Actual + Homing_Offset
    bus.write("Operating_Mode", 1, 4)
    bus.write("Drive_Mode", 1, 1)
    bus.write("Homing_Offset", 1, 0)
    assert bus.read("Present_Position", 1) == -1337  # reverse mode, extended position: negative
    assert bus.sync_read("Present_Position", [1, 2]) == {1: -1337, 2: 2047}


def test_dynamixel_eeprom_locked_while_torque_on(dxl_sim: tuple[SimServoBus, DynamixelBus]) -> None:
    sim, bus = dxl_sim
    bus.write("Torque_Enable", 1, 1)
    with pytest.raises(DeviceError, match=r"motor 1: write 'Homing_Offset' failed: \[RxPacketError\]") as exc:
        bus.write("Homing_Offset", 1, 5)
    assert sim.port in str(exc.value) and exc.value.exit_code == 3


def test_timeout_and_corrupt_packets_map_to_exit_3(feetech_sim: tuple[SimServoBus, FeetechBus]) -> None:
    sim, bus = feetech_sim
    sim.silent_ids.add(2)
    with pytest.raises(CalibTimeoutError) as exc:
        bus.read("Present_Position", 2)
    assert str(exc.value) == (
        f"{sim.port}: motor 2: read 'Present_Position' failed after 2 tries: [TxRxResult] There is no status packet!"
    )
    assert exc.value.exit_code == 3
    sim.silent_ids.clear()
    sim.corrupt_next = 1  # one bad checksum: the retry succeeds
    assert bus.read("Present_Position", 1) == 1337
    sim.corrupt_next = 5
    with pytest.raises(ProtocolError, match="motor 1: read 'Present_Position' failed after 2 tries"):
        bus.read("Present_Position", 1)


def test_dynamixel_crc_matches_sdk() -> None:
    from dynamixel_sdk import PacketHandler

    pkt = [0xFF, 0xFF, 0xFD, 0x00, 0x01, 0x07, 0x00, 0x02, 0x84, 0x00, 0x04, 0x00]
    assert (
        dxl_crc16(pkt) == PacketHandler(2.0).updateCRC(0, pkt, len(pkt)) == 0x151D
    )  # sent as 1D 15 (e-manual read example)


def test_scs0009_protocol_1_big_endian() -> None:
    with SimServoBus([SimServo(1, "scs0009", 700.0)]) as sim:
        bus = FeetechBus(sim.port, {1: "scs0009"}, retries=0)
        try:
            assert bus.ping(1) == 1284
            assert bus.read("Present_Position", 1) == 700
            assert bytes(sim.servos[1].regs[56:58]) == bytes([0x02, 0xBC])  # 700 = 0x02BC big-endian
        finally:
            bus.close()
        # the next Feetech bus object selects protocol 0 again
    with SimServoBus([SimServo(1, "sts3215", 700.0)]) as sim:
        bus = FeetechBus(sim.port, {1: "sts3215"})
        try:
            assert bus.read("Present_Position", 1) == 700
        finally:
            bus.close()


# --------------------------------------------------------------------------------------- calibration
def _run(robot: str, tmp_path: Path, **kw: object) -> tuple[SimArm, dict[str, MotorCalibration], object]:
    op_kw = {k: kw.pop(k) for k in ("mid_pose", "interrupt_at_step", "interrupt_at_prompt") if k in kw}
    arm = SimArm(robot_spec(robot), truth=kw.pop("truth", None), eeprom=kw.pop("eeprom", None)).start()  # type: ignore[arg-type]
    bus = open_bus(arm.spec, arm.port)
    try:
        result = calibrate(
            bus,
            CalibrateRequest(
                arm.spec,
                path=tmp_path / "cal.json",
                **kw,
            ),
            SimArmOperator(arm, **op_kw),
        )  # type: ignore[arg-type]
        return arm, result.calibration, result
    finally:
        bus.close()
        arm.stop()


def test_so101_follower_calibration_matches_truth(tmp_path: Path) -> None:
    arm, cals, result = _run("so101_follower", tmp_path)
    truth = DEFAULT_TRUTH["so101_follower"]
    for name in ("shoulder_pan", "shoulder_lift", "elbow_flex", "gripper"):
        t = truth[name]
        h = int(t.mid_ticks) - 2047
        assert cals[name].homing_offset == h
        assert (cals[name].range_min, cals[name].range_max) == (t.stop_low_ticks - h, t.stop_high_ticks - h)
    # wrist_flex's travel crosses the encoder seam physically (3100..5300): the mid-pose homing moves it out
    assert cals["wrist_flex"] == MotorCalibration(4, 0, 104 - 2047, 947, 3147)
    assert cals["wrist_roll"] == MotorCalibration(5, 0, 0, 0, 4095)  # LeRobot's forced full turn
    assert read_calibration(tmp_path / "cal.json") == cals
    assert arm.eeprom()["gripper"] == {
        "Homing_Offset": 253,
        "Min_Position_Limit": 1747,
        "Max_Position_Limit": 3147,
    }
    assert result.notes == ()  # type: ignore[attr-defined]


@pytest.mark.slow
def test_koch_follower_and_leader_match_truth(tmp_path: Path) -> None:
    _, fol, _ = _run("koch_follower", tmp_path)
    t = DEFAULT_TRUTH["koch_follower"]["elbow_flex"]
    h = 2047 - int(t.mid_ticks)
    assert fol["elbow_flex"] == MotorCalibration(
        3, 0, h, int(t.stop_low_ticks) + h, int(t.stop_high_ticks) + h
    )
    assert (fol["shoulder_pan"].range_min, fol["shoulder_pan"].range_max) == (0, 4095)
    arm, lead, _ = _run("koch_leader", tmp_path)
    t = DEFAULT_TRUTH["koch_leader"]["elbow_flex"]
    # Drive_Mode 1: Present = −Actual + offset; offset = 2047 − (−mid)
    assert lead["elbow_flex"] == MotorCalibration(3, 1, 2047 + 2100, 2047 - 3150 + 2100, 2047 - 1050 + 2100)
    assert arm.eeprom()["elbow_flex"]["Drive_Mode"] == 1
    assert lead["wrist_flex"].drive_mode == 0


def test_seam_crossing_sweep_is_rehomed(tmp_path: Path) -> None:
    # a poor mid pose (1100 instead of ~2100) puts shoulder_pan's travel 900..3300 across the seam
    arm, cals, result = _run("so101_follower", tmp_path, mid_pose={"shoulder_pan": 1100.0})
    naive = result.naive_ranges["shoulder_pan"]  # type: ignore[attr-defined]
    assert naive[0] < 400 and naive[1] > 3700  # LeRobot's wrap-blind (≈0, ≈4095) (#3586), true span 2400
    c = cals["shoulder_pan"]
    assert (c.range_min, c.range_max) == (847, 3247) and c.homing_offset == 53
    assert arm.recovered_stops(cals)["shoulder_pan"] == (900, 3300)
    assert any("shoulder_pan: the sweep crossed the 0/4095 seam" in n for n in result.notes)  # type: ignore[attr-defined]


def test_home_after_sweep_centres_every_range(tmp_path: Path) -> None:
    arm, cals, _ = _run("so101_follower", tmp_path, home_after_sweep=True, mid_pose={"elbow_flex": 900.0})
    stops = arm.recovered_stops(cals)
    for name, t in DEFAULT_TRUTH["so101_follower"].items():
        if name == "wrist_roll":
            continue
        c = cals[name]
        assert abs((c.range_min + c.range_max) // 2 - 2047) <= 1, name
        lo, hi = stops[name]
        shift = 4096 * round((t.stop_low_ticks - lo) / 4096)
        assert (lo + shift, hi + shift) == (t.stop_low_ticks, t.stop_high_ticks), name
    _, cals_k, _ = _run("koch_follower", tmp_path, home_after_sweep=True)
    assert all(
        abs((c.range_min + c.range_max) // 2 - 2047) <= 1 for n, c in cals_k.items() if n != "shoulder_pan"
    )


def test_mid_pose_at_4095_does_not_crash(tmp_path: Path) -> None:
    truth = dict(DEFAULT_TRUTH["so101_follower"])
    truth["shoulder_pan"] = JointTruth(4095, 3000, 5000)
    _, cals, result = _run("so101_follower", tmp_path, truth=truth)
    assert cals["shoulder_pan"].homing_offset == 2047  # LeRobot: 2048 -> "Magnitude 2048 exceeds 2047"
    assert (cals["shoulder_pan"].range_min, cals["shoulder_pan"].range_max) == (953, 2953)
    assert any("clamped to 2047" in n for n in result.notes)  # type: ignore[attr-defined]


@pytest.mark.slow
def test_full_turn_joints_can_be_swept(tmp_path: Path) -> None:
    _, cals, _ = _run("so101_follower", tmp_path, sweep_full_turn=True)
    assert (cals["wrist_roll"].range_min, cals["wrist_roll"].range_max) == (113 + 0, 3981)  # #4583
    _, kcal, _ = _run("koch_follower", tmp_path, sweep_full_turn=True)
    assert (kcal["shoulder_pan"].range_min, kcal["shoulder_pan"].range_max) == (500 - 1, 3600 - 1)




@pytest.mark.parametrize("robot", ["so101_follower", "koch_leader"])
@pytest.mark.parametrize("where", [{"interrupt_at_step": 5}, {"interrupt_at_prompt": "sweep"}])
def test_ctrl_c_restores_eeprom_and_leaves_file(tmp_path: Path, robot: str, where: dict[str, object]) -> None:
    path = tmp_path / "cal.json"
    path.write_text("previous file\n")
    arm = SimArm(robot_spec(robot), eeprom=PREVIOUS[robot]).start()
    bus = open_bus(arm.spec, arm.port)
    try:
        before = arm.eeprom()
        assert before["gripper"]["Homing_Offset"] == PREVIOUS[robot]["gripper"]["Homing_Offset"]
        with pytest.raises(KeyboardInterrupt):
            calibrate(bus, CalibrateRequest(arm.spec, path=path), SimArmOperator(arm, **where))  # type: ignore[arg-type]
        assert arm.eeprom() == before
        assert path.read_text() == "previous file\n"
        assert not (tmp_path / "cal.json.bak").exists()
    finally:
        bus.close()
        arm.stop()


def test_dynamixel_restore_writes_drive_mode_and_check_names_fields(tmp_path: Path) -> None:
    _, cals, _ = _run("koch_leader", tmp_path)
    arm = SimArm(robot_spec("koch_leader")).start()  # a fresh arm: Drive_Mode 0 everywhere, offsets 0
    bus = open_bus(arm.spec, arm.port)
    try:
        diffs = check(bus, arm.spec, cals)
        assert "motor 'elbow_flex' (id 3): drive_mode is 0 on the motor, 1 in the file" in [
            str(d) for d in diffs
        ]
        restore(bus, arm.spec, cals)
        assert arm.eeprom()["elbow_flex"]["Drive_Mode"] == 1
        assert check(bus, arm.spec, cals) == []
        arm.servo("wrist_flex").set_reg("Max_Position_Limit", 4000)
        (d,) = check(bus, arm.spec, cals)
        assert str(d) == (
            f"motor 'wrist_flex' (id 4): range_max is 4000 on the motor, {cals['wrist_flex'].range_max} in the file"
        )
    finally:
        bus.close()
        arm.stop()


def test_noisy_calibration_within_two_ticks(tmp_path: Path) -> None:
    arm = SimArm(robot_spec("so101_leader"), noise_ticks=1, seed=3).start()
    bus = open_bus(arm.spec, arm.port)
    try:
        cals = calibrate(bus, CalibrateRequest(arm.spec, path=None, sweep_full_turn=True), SimArmOperator(arm)).calibration
        for name, (lo, hi) in arm.recovered_stops(cals).items():
            t = arm.truth[name]
            assert abs(lo - t.stop_low_ticks) <= 2 and abs(hi - t.stop_high_ticks) <= 2, name
    finally:
        bus.close()
        arm.stop()


def test_phase_bit4_cleared_like_lerobot_fixture() -> None:
    from robocal.workflows.lerobot import clear_phase_bit4, configure

    with SimArm(robot_spec("so101_follower")) as arm:
        for name, phase in (("shoulder_pan", 0b00010000), ("shoulder_lift", 0xFF), ("elbow_flex", 0)):
            arm.servo(name).set_reg("Phase", phase)
        bus = open_bus(arm.spec, arm.port)
        try:
            assert clear_phase_bit4(bus, arm.spec) == [1, 2]  # 0 needs no write
            phases = [arm.servo(n).get_reg("Phase") for n in ("shoulder_pan", "shoulder_lift", "elbow_flex")]
            assert phases == [0, 0b11101111, 0]
            configure(bus, arm.spec)
            g = arm.servo("gripper")
            assert (
                g.get_reg("Max_Torque_Limit"),
                g.get_reg("Protection_Current"),
                g.get_reg("Overload_Torque"),
            ) == (
                500,
                250,
                25,
            )
            assert arm.servo("wrist_flex").get_reg("P_Coefficient") == 16
        finally:
            bus.close()
    with SimArm(robot_spec("koch_follower")) as arm:
        bus = open_bus(arm.spec, arm.port)
        try:
            configure(bus, arm.spec)
            assert [arm.servo(n).get_reg("Operating_Mode") for n in ("elbow_flex", "gripper")] == [4, 5]
        finally:
            bus.close()


def test_configure_writes_the_modes_and_gains_the_profile_declares() -> None:
    """The run mode and gains are the profile's (``operating_mode``, ``position_gains``), not fixed per vendor."""
    from dataclasses import replace

    from robocal.workflows.lerobot import configure

    spec = robot_spec("koch_follower")
    motors = tuple(
        replace(m, operating_mode=3, position_gains=(900, 0, 100)) if m.name == "wrist_flex" else m
        for m in spec.motors
    )
    with SimArm(replace(spec, motors=motors)) as arm:
        bus = open_bus(arm.spec, arm.port)
        try:
            written = configure(bus, arm.spec)
            modes = [arm.servo(n).get_reg("Operating_Mode") for n in arm.spec.motor_names]
            assert modes == [4, 4, 4, 3, 4, 5]
            gains = [arm.servo(n).get_reg("Position_P_Gain") for n in ("elbow_flex", "wrist_flex")]
            assert gains == [1500, 900]
            assert ("wrist_flex", "Position_D_Gain", 100) in written
        finally:
            bus.close()
    so = robot_spec("so101_leader")  # a leader: LeRobot writes no gains on it
    with SimArm(so) as arm:
        bus = open_bus(arm.spec, arm.port)
        try:
            assert not [w for w in configure(bus, arm.spec) if w[1] == "P_Coefficient"]
            assert arm.servo("wrist_flex").get_reg("P_Coefficient") == 32  # the factory's
        finally:
            bus.close()


def test_a_simulated_koch_powers_on_with_the_factory_position_gains() -> None:
    """Read over the wire before anything is written, on the arm without physics (``lerobot --port sim``) and on the
    one with (``--auto``'s): the e-Manual's RAM defaults (XL430-W250 P 640 D 4000, XL330-M288 P 400 D 0), not the
    800 every simulated Dynamixel with physics used to power on with."""
    from robocal.workflows.lerobot.auto import auto_section
    from robocal.workflows.lerobot.auto_sim import open_auto_arm

    spec = robot_spec("koch_follower")
    models = {m.name: m.model for m in spec.motors}
    factory = {"xl430-w250": (640, 4000), "xl330-m288": (400, 0)}
    assert set(models.values()) == set(factory)  # both models are on the arm

    def gains(bus: DynamixelBus) -> dict[str, tuple[int, int]]:
        return {
            m.name: (bus.read("Position_P_Gain", m.motor_id), bus.read("Position_D_Gain", m.motor_id))
            for m in spec.motors
        }

    with SimArm(spec) as arm:
        bus = open_bus(arm.spec, arm.port)
        try:
            assert isinstance(bus, DynamixelBus)
            assert gains(bus) == {n: factory[models[n]] for n in models}
        finally:
            bus.close()
    with open_auto_arm(spec, "sim?transport=inproc", auto_section("koch_follower")) as physics:
        assert isinstance(physics.bus, DynamixelBus)
        assert gains(physics.bus) == {n: factory[models[n]] for n in models}
        shutdown = {m.name: physics.bus.read("Shutdown", m.motor_id) for m in spec.motors}
        assert shutdown == {n: {"xl430-w250": 52, "xl330-m288": 53}[models[n]] for n in models}  # was 52 on all


def test_multi_turn_feedback_does_not_break_homing(tmp_path: Path) -> None:
    truth = dict(DEFAULT_TRUTH["so101_follower"])
    truth["shoulder_pan"] = JointTruth(4368, 3300, 5500)  # 4368 reads 4368 with Phase bit 4 set (#1296)
    _, cals, _ = _run("so101_follower", tmp_path, truth=truth, eeprom={"shoulder_pan": {"Phase": 0x10}})
    c = cals["shoulder_pan"]
    assert c.homing_offset == 4368 - 4096 - 2047 and (c.range_min, c.range_max) == (
        3300 - 4096 + 1775,
        5500 - 4096 + 1775,
    )


def test_feetech_check_and_restore(tmp_path: Path) -> None:
    _, cals, _ = _run("so101_follower", tmp_path)
    with SimArm(robot_spec("so101_follower")) as arm:
        bus = open_bus(arm.spec, arm.port)
        try:
            diffs = [str(d) for d in check(bus, arm.spec, cals)]
            assert "motor 'wrist_flex' (id 4): homing_offset is 0 on the motor, -1943 in the file" in diffs
            assert "motor 'gripper' (id 6): range_min is 0 on the motor, 1747 in the file" in diffs
            assert not any("drive_mode" in d for d in diffs)  # Feetech drive_mode lives in the file only
            restore(bus, arm.spec, cals)
            assert check(bus, arm.spec, cals) == []
            assert bus.read("Present_Position", 4) == 2047  # the mid pose reads the half turn again
        finally:
            bus.close()


def test_simulator_thread_stops_cleanly() -> None:
    sim = SimServoBus([SimServo(1, "sts3215")]).start()
    thread = sim._thread
    assert thread.is_alive()
    sim.stop()
    assert not thread.is_alive()
    with pytest.raises(OSError):
        import os

        os.fstat(sim._master)


ZERO = [2048, 1000, 3100, 2000, 1020, 2040]
ROTATED = [3080, 2010, 2060, 3050, 2030, 3070]


@pytest.mark.parametrize(
    ("robot", "homing", "modes"),
    [
        ("koch_follower", [-2048, -1024, 3072, -2048, -1024, -2048], ("DEGREE",) * 6),
        ("so101_follower", [-2056, -986, 3084, -2026, -1006, -2046], ("DEGREE",) * 5 + ("LINEAR",)),
    ],
)
def test_legacy_pose_calibration_through_the_sdk(
    tmp_path: Path, robot: str, homing: list[int], modes: tuple[str, ...]
) -> None:
    from robocal.lerobot.legacy import apply_calibration, read_legacy
    from robocal.workflows.lerobot import calibrate_legacy

    names = list(DEFAULT_TRUTH[robot])
    truth = {n: JointTruth(2048, 0, 4095) for n in names}
    poses = {
        "zero": dict(zip(names, map(float, ZERO), strict=True)),
        "rotated": dict(zip(names, map(float, ROTATED), strict=True)),
    }
    with SimArm(robot_spec(robot), truth=truth) as arm:
        bus = open_bus(arm.spec, arm.port)
        try:
            op = SimArmOperator(arm, poses=poses)
            cal = calibrate_legacy(bus, arm.spec, op, path=tmp_path / "main_follower.json")
            assert op.prompts == ["zero", "rotated", "rest"]
            raw_rot = [bus.read("Present_Position", i) for i in range(1, 7)]
        finally:
            bus.close()
    assert cal.drive_mode.tolist() == [0, 0, 1, 0, 0, 0]
    assert cal.homing_offset.tolist() == homing and cal.calib_mode == modes
    assert cal.start_pos.tolist() == ZERO and cal.end_pos.tolist() == [3080, 2010, -2060, 3050, 2030, 3070]
    assert read_legacy(tmp_path / "main_follower.json") == cal
    if robot == "koch_follower":  # rounded homing: the rotated pose reads close to +90° on every joint
        deg = apply_calibration(raw_rot, cal)
        assert all(abs(d - 90) < 6 for d in deg)


def test_legacy_calibration_requires_torque_off() -> None:
    from robocal.errors import UsageError
    from robocal.workflows.lerobot import calibrate_legacy

    with SimArm(robot_spec("koch_follower")) as arm:
        arm.servo("elbow_flex").set_reg("Torque_Enable", 1)
        bus = open_bus(arm.spec, arm.port)
        try:
            with pytest.raises(
                UsageError, match=r"torque must be disabled on all motors \(enabled on elbow_flex\)"
            ):
                calibrate_legacy(bus, arm.spec, SimArmOperator(arm))
        finally:
            bus.close()


@pytest.mark.slow
@settings(max_examples=40)
@given(
    offset=st.integers(-2047, 2047),
    actual=st.integers(0, 4095),
    dxl_offset=st.one_of(st.integers(-1_044_479, 1_044_479), st.integers(-(2**31), 2**31 - 1)),
)
def test_registers_round_trip_through_sdk(offset: int, actual: int, dxl_offset: int) -> None:
    with SimServoBus([SimServo(1, "sts3215", float(actual))]) as sim:
        bus = FeetechBus(sim.port, {1: "sts3215"})
        try:
            bus.write("Homing_Offset", 1, offset)
            assert bus.read("Homing_Offset", 1) == offset
            assert bus.read("Present_Position", 1) == (actual - offset) % 4096
        finally:
            bus.close()
    with SimServoBus([SimServo(1, "xl330-m077", float(actual))]) as sim:
        dbus = DynamixelBus(sim.port, {1: "xl330-m077"})
        try:
            if abs(dxl_offset) <= 1_044_479:  # the e-Manual's range
                dbus.write("Homing_Offset", 1, dxl_offset)
                assert dbus.read("Homing_Offset", 1) == dxl_offset
                assert dbus.sync_read("Homing_Offset", [1]) == {1: dxl_offset}
            else:  # refused with the Data Range error, as the servo does
                with pytest.raises(DeviceError, match="out of range"):
                    dbus.write("Homing_Offset", 1, dxl_offset)
                assert dbus.read("Homing_Offset", 1) == 0
        finally:
            dbus.close()


def test_home_after_sweep_offset_at_the_sign_magnitude_edge(tmp_path: Path) -> None:
    truth = dict(DEFAULT_TRUTH["so101_follower"])
    truth["elbow_flex"] = JointTruth(4095, 3095, 5095)  # travel centred on the seam: offset would be ±2048
    arm, cals, _ = _run("so101_follower", tmp_path, truth=truth, home_after_sweep=True)
    assert cals["elbow_flex"] == MotorCalibration(3, 0, -2047, 1046, 3046)
    assert arm.eeprom()["elbow_flex"]["Homing_Offset"] == -2047
