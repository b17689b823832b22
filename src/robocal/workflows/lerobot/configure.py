"""LeRobot's ``configure()`` motor presets (return delay, acceleration, PID, operating modes, gripper)."""

from __future__ import annotations

from collections.abc import Callable, Mapping

from ...backends.servo_bus import ServoBus
from ...core.lerobot import LeRobotMotor, MotorCalibration, RobotSpec
from ...errors import InvalidCalibrationError, UsageError

__all__ = [
    "clear_phase_bit4",
    "configure",
]


def clear_phase_bit4(bus: ServoBus, spec: RobotSpec) -> list[int]:
    """Clear bit 4 of Phase on sts3215 motors (single-turn angle feedback; huggingface/lerobot#3373).

    Writes only where the bit is set (0b00010000 → 0, 0xFF → 0b11101111, 0 → no write).

    Returns:
        Ids of the motors written.
    """
    written = []
    for m in spec.motors:
        if m.model != "sts3215":
            continue
        phase = bus.read("Phase", m.motor_id)
        if phase & 0x10:
            bus.write("Phase", m.motor_id, phase & ~0x10 & 0xFF)
            written.append(m.motor_id)
    return written

def configure(
    bus: ServoBus,
    spec: RobotSpec,
    *,
    calibration: Mapping[str, MotorCalibration] | None = None,
    gripper_open_pos: float = 50.0,
    on_status: Callable[[str], None] | None = None,
    snapshot_port: str | None = None,
) -> list[tuple[str, str, int]]:
    """LeRobot's ``configure()`` presets (torque stays off, except the Koch leader's gripper trigger).

    Every arm: torque off (Feetech also Lock 0), Return_Delay_Time 0. Feetech (SO): Maximum_Acceleration and
    Acceleration 254, Phase bit 4 cleared on sts3215, Operating_Mode 0; the follower also P/I/D 16/0/32 and
    gripper Max_Torque_Limit 500, Protection_Current 250, Overload_Torque 25. Dynamixel (Koch): extended position
    (4) except the gripper current-based position (5); the follower's elbow_flex Position P/I/D 1500/0/600.

    Koch leader gripper trigger (LeRobot's order): with ``calibration`` given, the gripper's torque is enabled
    and ``Goal_Position = gripper_open_pos`` written (RANGE_0_100, unnormalised like LeRobot), so the gripper
    springs back open when squeezed. LeRobot also enables the torque without a calibration (holding whatever
    goal the motor has); robocal then skips the trigger. LeRobot's followers re-enable torque afterwards;
    robocal leaves it off.

    Runs under the arm's :class:`~robocal.workflows.motion.guard.MotionGuard`: each register's value is read
    before its first write (the snapshot, kept in robocal's state folder under ``snapshot_port``); a signal or a
    fault midway makes every motor limp and writes the snapshot back (the presets are all or nothing).
    ``Torque_Enable`` and ``Goal_Position`` are never restored (a restore leaves the motors limp).

    Returns:
        ``(motor, register, value)`` for every register written, in order (Phase only where changed).

    Raises:
        UsageError: The arm's vendor has no presets here (nothing written).
    """
    from .guard import arm_guard

    presets = _PRESETS.get(spec.vendor)
    if presets is None:
        raise UsageError(f"no LeRobot configure presets for vendor {spec.vendor!r}; valid: {', '.join(_PRESETS)}")
    written: list[tuple[str, str, int]] = []
    before: dict[str, dict[str, int]] = {}
    guard = arm_guard(bus, spec, command="lerobot configure", on_status=on_status, snapshot_port=snapshot_port)

    def put(name: str, motor_id: int, register: str, value: int) -> None:
        regs = before.setdefault(name, {})
        if register not in ("Torque_Enable", "Goal_Position") and register not in regs:
            regs[register] = bus.read(register, motor_id)  # the snapshot: each register before its first write
            guard.snapshot(before, robot=spec.name)
        bus.write(register, motor_id, value)
        written.append((name, register, value))

    with guard:  # a signal or fault midway: every motor limp, the snapshot written back (motion_guard.py)
        for m in spec.motors:  # Phase (clear_phase_bit4 writes it without put): its old value first
            if bus.has_register(m.motor_id, "Phase"):
                before.setdefault(m.name, {})["Phase"] = bus.read("Phase", m.motor_id)
        for m in spec.motors:  # torque off first (EEPROM writes)
            put(m.name, m.motor_id, "Torque_Enable", 0)
            if bus.has_register(m.motor_id, "Lock"):
                put(m.name, m.motor_id, "Lock", 0)
        for m in spec.motors:
            put(m.name, m.motor_id, "Return_Delay_Time", 0)
        presets(bus, spec, put, written, calibration, gripper_open_pos)
    return written


_Put = Callable[[str, int, str, int], None]


def _gain_presets(spec: RobotSpec, motor: LeRobotMotor) -> list[tuple[str, int]]:
    """The position gains LeRobot writes on ``motor`` (its profile's ``position_gains``), as register writes."""
    registers = spec.vendor_spec.position_gain_registers
    if motor.position_gains is None or registers is None:
        return []
    return list(zip(registers, motor.position_gains, strict=True))


def _feetech_presets(
    bus: ServoBus,
    spec: RobotSpec,
    put: _Put,
    written: list[tuple[str, str, int]],
    calibration: Mapping[str, MotorCalibration] | None,
    gripper_open_pos: float,
) -> None:
    """LeRobot's SO arms (Feetech): Phase bit 4, accelerations, position mode; the follower's P/I/D and gripper."""
    follower = spec.kind == "robots"
    by_id = {m.motor_id: m.name for m in spec.motors}
    for i in clear_phase_bit4(bus, spec):
        written.append((by_id[i], "Phase", bus.read("Phase", i)))
    for m in spec.motors:
        presets = [("Maximum_Acceleration", 254), ("Acceleration", 254), ("Operating_Mode", spec.run_mode(m))]
        presets += _gain_presets(spec, m)
        if follower and m.name == "gripper":
            presets += [("Max_Torque_Limit", 500), ("Protection_Current", 250), ("Overload_Torque", 25)]
        for reg, value in presets:
            put(m.name, m.motor_id, reg, value)


def _dynamixel_presets(
    bus: ServoBus,
    spec: RobotSpec,
    put: _Put,
    written: list[tuple[str, str, int]],
    calibration: Mapping[str, MotorCalibration] | None,
    gripper_open_pos: float,
) -> None:
    """LeRobot's Koch arms (Dynamixel): operating modes, the follower's elbow gains, the leader's gripper trigger."""
    follower = spec.kind == "robots"
    for m in spec.motors:
        put(m.name, m.motor_id, "Operating_Mode", spec.run_mode(m))
    for m in spec.motors:
        for reg, value in _gain_presets(spec, m):
            put(m.name, m.motor_id, reg, value)
    if not follower and calibration is not None:
        gripper = next(m for m in spec.motors if m.name == "gripper")
        if gripper.name not in calibration:
            raise InvalidCalibrationError("calibration has no entry for motor 'gripper'")
        from ...core.lerobot.normalisation import unnormalize

        goal = int(
            unnormalize(
                float(gripper_open_pos), calibration[gripper.name], "range_0_100", apply_drive_mode=False
            )
        )
        put(gripper.name, gripper.motor_id, "Torque_Enable", 1)
        put(gripper.name, gripper.motor_id, "Goal_Position", goal)


_PRESETS: dict[
    str,
    Callable[
        [ServoBus, RobotSpec, _Put, list[tuple[str, str, int]], Mapping[str, MotorCalibration] | None, float],
        None,
    ],
] = {"feetech": _feetech_presets, "dynamixel": _dynamixel_presets}
"""LeRobot's ``configure()`` of each vendor's arms (the adapter; everything else reads the vendor declaration)."""
