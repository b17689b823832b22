"""What differs between motor vendors, declared once per vendor and looked up by name.

Every rule that depends on the vendor (the homing offset's sign and register encoding, whether ``Drive_Mode``
lives in the motor, which lock, torque-cap and operating-mode registers exist, how a motor is made limp, ...)
is a field of that vendor's :class:`VendorSpec`; code elsewhere reads the fields and never compares vendor
names (``tests/foundation/test_vendor_seam.py`` enforces it). :func:`vendor_spec` is the one lookup: a name
with no declaration raises :class:`~robocal.errors.UsageError` naming the valid ones, so a new vendor never
quietly inherits another vendor's signs. Adding a vendor is one :class:`VendorSpec` in :data:`VENDORS` (and its
bus in ``robocal.backends.BACKENDS``); see CONTRIBUTING.md.

Pure data and integer arithmetic (no numpy needed), so core, the workflows, the dataset code and the
simulators can all read it.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

from ..errors import UsageError

__all__ = [
    "VENDORS",
    "HomingRule",
    "VendorSpec",
    "drives_sweep_auto",
    "expected_homing_vendors",
    "hand_sweep_source",
    "homing_vendor",
    "homing_vendors",
    "speaks_live_can_sweep",
    "vendor_spec",
]


@dataclass(frozen=True)
class HomingRule:
    """How a servo's ``Homing_Offset`` register moves its ``Present_Position`` reading.

    Attributes:
        offset_sign: ``Present = Actual + offset_sign · Homing_Offset`` (Feetech −1, Dynamixel +1).
        encoding: The register's encoding of a negative offset: ``"sign-magnitude"`` (sign bit
            :attr:`sign_bit`) or ``"twos-complement"``.
        sign_bit: Index of the sign bit of a sign-magnitude register (Feetech 11); unused otherwise.
        wraps_per_turn: Present is reported modulo one turn, so the offset is kept within a half turn
            (±(res/2 − 1), the sign-magnitude register's reach) and readings are known modulo a turn.
    """

    offset_sign: Literal[1, -1]
    encoding: Literal["sign-magnitude", "twos-complement"]
    sign_bit: int
    wraps_per_turn: bool

    def offset_for_shift(self, base: int, shift_ticks: int) -> int:
        """The offset that lowers every reading by ``shift_ticks`` from one of ``base``.

        Feetech adds the shift, Dynamixel subtracts it.
        """
        return int(base) - self.offset_sign * int(shift_ticks)

    def present(self, actual_ticks: float, offset: int) -> float:
        """The reading of a shaft at ``actual_ticks`` under ``offset`` (before any wrap to a turn)."""
        return actual_ticks + self.offset_sign * offset

    def offset_reading(self, actual_ticks: int, present_ticks: int) -> int:
        """The offset that makes a shaft at ``actual_ticks`` read ``present_ticks``."""
        return self.offset_sign * (int(present_ticks) - int(actual_ticks))

    def turn_shift(self, true_ticks: float, recovered_ticks: float, resolution: int) -> int:
        """Whole turns (in ticks) to add to a recovered reading to compare it with the true one.

        Readings that wrap per turn are known only modulo a turn; others are absolute (0).
        """
        if not self.wraps_per_turn:
            return 0
        return resolution * round((true_ticks - recovered_ticks) / resolution)


@dataclass(frozen=True)
class VendorSpec:
    """Everything robocal needs to know that differs between motor vendors (one frozen value per vendor).

    Attributes:
        name: The vendor's name as profiles and options spell it (``"feetech"``).
        title: The name in messages (``"Feetech"``).
        backend: Name of its bus in ``robocal.backends.BACKENDS`` (reached through ``load_backend``).
        resolution_ticks: Encoder ticks per turn of its usual models (a model's table may say otherwise).
        homing: How its ``Homing_Offset`` moves the reading; None: no such register (Robstride: the zero is
            set by a command).
        drive_mode_in_hardware: ``Drive_Mode`` bit 0 is a motor register that inverts the reading (Dynamixel);
            False: LeRobot applies ``drive_mode`` in software when normalising (Feetech).
        lock_register: The EEPROM write-lock register cleared before EEPROM writes, or None.
        operating_mode_register: The register selecting position / current / ... control, or None.
        torque_cap_registers: The RAM registers the stop search changes to cap torque and shape goals (saved and
            restored around it).
        latched_error_register: A hardware-error register whose error only a REBOOT clears (the motor switches
            its torque off), or None.
        multi_turn_phase_bit: Bit 4 of its ``Phase`` register turns on multi-turn feedback, which must be off
            for the half-turn homing (Feetech).
        limp: How a motor is made limp (for people): the write that removes its torque.
        max_lag_deg: How far the stop search's position goal may lead the joint (above the firmware's lag at the
            torque cap), degrees; None where no servo stop search exists.
        legacy_quarter_turn: LeRobot's 2024 calibration rounds the rotated pose to a quarter turn (Dynamixel);
            False: uses it exactly (Feetech).
        legacy_linear_gripper: LeRobot's 2024 calibration makes the ``gripper`` LINEAR by default (Feetech).
        torque_off_to_calibrate: LeRobot refuses to calibrate while a motor's torque is on (Dynamixel).
        live_can_sweep: The live CAN sweep (``--source can:``) and ``sweep --auto`` speak its protocol
            (Robstride).
        hand_sweep_source: Name in ``robocal.backends.BACKENDS`` of the source class a live hand sweep
            (``--source can:`` without ``--auto``) reads its motors with, where that is not Robstride's
            (``damiao.source``: ``open(spec, joints, profile)``), or None.
        joint_driver: Name in ``robocal.backends.BACKENDS`` of its stop-search joint driver (in the vendor's home,
            reached through ``load_backend``), or None where no stop search exists.
        sweep_auto: ``robocal sweep --auto`` drives its motors over CAN (Robstride, Damiao); the servo vendors are
            auto-calibrated by ``robocal lerobot calibrate --auto``.
        host_loss: What stops a moving motor when robocal is killed or the bus is lost (the clear-workspace
            prompt says it), or "" where :attr:`sweep_auto` is False.
        sim_auto_robot: The simulated robot ``sweep --auto --source sim:NAME`` offers for its motors (``lite``,
            ``openarm``), or None.
        position_gain_registers: Its position loop's ``(P, I, D)`` gain registers, or None.
        position_loop: Name in ``robocal.backends.BACKENDS`` of its position loop's model
            (:class:`robocal.backends.servo_ratings.PositionLoop`, in the vendor's home: the stiffness and damping of
            a P and D gain, the factory gains per model), or None.
        goal_limit_modes: The operating modes in which the servo clamps its goal to its position limits (Feetech
            position mode 0, Dynamixel position mode 3; not extended or current-based position).
        power_on_half_turn: After a power cycle the reading restarts within ±π of the stored zero (Damiao: the
            multi-turn count is in RAM), so a joint whose travel crosses zero ± π reads a turn off (the sweep's
            ``wrap_in_travel`` with ``zero_sta`` 1).
    """

    name: str
    title: str
    backend: str
    resolution_ticks: int | None
    homing: HomingRule | None
    drive_mode_in_hardware: bool
    lock_register: str | None
    operating_mode_register: str | None
    torque_cap_registers: tuple[str, ...]
    latched_error_register: str | None
    multi_turn_phase_bit: bool
    limp: str
    max_lag_deg: float | None
    legacy_quarter_turn: bool = False
    legacy_linear_gripper: bool = False
    torque_off_to_calibrate: bool = False
    live_can_sweep: bool = False
    hand_sweep_source: str | None = None
    joint_driver: str | None = None
    sweep_auto: bool = False
    host_loss: str = ""
    power_on_half_turn: bool = False
    sim_auto_robot: str | None = None
    position_gain_registers: tuple[str, str, str] | None = None
    position_loop: str | None = None
    goal_limit_modes: tuple[int, ...] = ()

    @property
    def applies_drive_mode_in_software(self) -> bool:
        """LeRobot's normalisation applies ``drive_mode`` itself (it is not a motor register)."""
        return not self.drive_mode_in_hardware

    def homing_rule(self) -> HomingRule:
        """Its homing rule.

        Raises:
            UsageError: The vendor has no ``Homing_Offset`` register.
        """
        if self.homing is None:
            raise UsageError(f"vendor {self.name!r} has no Homing_Offset register")
        return self.homing


FEETECH = VendorSpec(
    name="feetech",
    title="Feetech",
    backend="feetech",
    resolution_ticks=4096,
    homing=HomingRule(offset_sign=-1, encoding="sign-magnitude", sign_bit=11, wraps_per_turn=True),
    drive_mode_in_hardware=False,
    lock_register="Lock",
    operating_mode_register="Operating_Mode",
    torque_cap_registers=("Torque_Limit", "Goal_Velocity", "Acceleration"),
    latched_error_register=None,
    multi_turn_phase_bit=True,
    limp="Torque_Enable 0",
    max_lag_deg=3.0,
    legacy_linear_gripper=True,
    joint_driver="feetech.joint_driver",
    position_gain_registers=("P_Coefficient", "I_Coefficient", "D_Coefficient"),
    position_loop="feetech.position_loop",
    goal_limit_modes=(0,),
)
"""Feetech STS/SCS servos (SO-100/SO-101): ``Present = (Actual − Homing_Offset) mod 4096``, offset in
sign-magnitude (bit 11); drive mode in software; ``Lock`` guards the EEPROM; the P gain reaches the torque cap
within ~1–2°."""

DYNAMIXEL = VendorSpec(
    name="dynamixel",
    title="Dynamixel",
    backend="dynamixel",
    resolution_ticks=4096,
    homing=HomingRule(offset_sign=1, encoding="twos-complement", sign_bit=31, wraps_per_turn=False),
    drive_mode_in_hardware=True,
    lock_register=None,
    operating_mode_register="Operating_Mode",
    torque_cap_registers=("Bus_Watchdog", "Goal_Current", "Goal_PWM", "Profile_Velocity", "Profile_Acceleration"),
    latched_error_register="Hardware_Error_Status",
    multi_turn_phase_bit=False,
    limp="Torque_Enable 0",
    max_lag_deg=10.0,
    legacy_quarter_turn=True,
    torque_off_to_calibrate=True,
    joint_driver="dynamixel.joint_driver",
    position_gain_registers=("Position_P_Gain", "Position_I_Gain", "Position_D_Gain"),
    position_loop="dynamixel.position_loop",
    goal_limit_modes=(3,),
)
"""Dynamixel X servos (Koch): ``Present = (±Actual) + Homing_Offset`` (``−`` with ``Drive_Mode`` bit 0), two's
complement; a hardware error latches until REBOOT; the current-based position gain reaches the cap within
~2–6°."""

ROBSTRIDE = VendorSpec(
    name="robstride",
    title="Robstride",
    backend="robstride",
    resolution_ticks=None,
    homing=None,
    drive_mode_in_hardware=False,
    lock_register=None,
    operating_mode_register=None,
    torque_cap_registers=(),
    latched_error_register=None,
    multi_turn_phase_bit=False,
    limp="a zero-torque MIT frame",
    max_lag_deg=None,
    live_can_sweep=True,
    joint_driver="robstride.joint_driver",
    sweep_auto=True,
    sim_auto_robot="lite",
    host_loss="If robocal is killed or the CAN bus is lost, each moving motor's CAN timeout puts it in reset mode "
    "within 0.5 s.",
)
"""Robstride CAN actuators (MIT frames, radians; the zero is set by a command, no homing register)."""

DAMIAO = VendorSpec(
    name="damiao",
    title="Damiao",
    backend="damiao",
    resolution_ticks=None,
    homing=None,
    drive_mode_in_hardware=False,
    lock_register=None,
    operating_mode_register="CTRL_MODE",
    torque_cap_registers=(),
    latched_error_register=None,
    multi_turn_phase_bit=False,
    limp="disable (0xFD), or the zero-torque MIT frame",
    max_lag_deg=None,
    hand_sweep_source="damiao.source",
    joint_driver="damiao.joint_driver",
    sweep_auto=True,
    host_loss="If robocal is killed or the CAN bus is lost, each moving motor's TIMEOUT (register 9) makes it limp "
    "(state 0xD) within 0.5 s.",
    power_on_half_turn=True,
    sim_auto_robot="openarm",
)
"""Damiao CAN motors (the OpenArm's DM4310 / DM4340 / DM8009): MIT frames in radians scaled by the motor's PMAX /
VMAX / TMAX registers; the zero is set by a command (0xFE) into the motor's flash, no homing register; register
CTRL_MODE (10) selects MIT / position-velocity / velocity / position-force; an error state latches until the
clear-error command (0xFB), not a reboot; torque is capped per command (no cap register). The live hand sweep
(``--source can:``) reads them through ``damiao.source`` (every motor off, refresh frames only); ``sweep --auto``
drives them through ``damiao.joint_driver`` (issue 31)."""

VENDORS: dict[str, VendorSpec] = {v.name: v for v in (FEETECH, DYNAMIXEL, ROBSTRIDE, DAMIAO)}
"""Vendor name → its declaration: the one registry (a new vendor is one line here)."""


def vendor_spec(name: str) -> VendorSpec:
    """The declaration of vendor ``name``.

    Raises:
        UsageError: No vendor has that name (the message lists the valid ones).
    """
    spec = VENDORS.get(name)
    if spec is None:
        raise UsageError(f"unknown vendor {name!r}; valid: {', '.join(sorted(VENDORS))}")
    return spec


def homing_vendors() -> tuple[str, ...]:
    """Names of the vendors whose servos have a ``Homing_Offset`` register (LeRobot's), in declaration order."""
    return tuple(n for n, v in VENDORS.items() if v.homing is not None)


def speaks_live_can_sweep(actuator: str | None) -> bool:
    """Whether a profile's ``actuator`` (None: not stated) is driven by the live CAN sweep."""
    spec = VENDORS.get(actuator) if actuator is not None else None
    return actuator is None or (spec is not None and (spec.live_can_sweep or spec.hand_sweep_source is not None))


def hand_sweep_source(actuator: str | None) -> str | None:
    """The backend name of the live hand-sweep source of a profile's ``actuator`` (None: Robstride's ``can:``)."""
    spec = VENDORS.get(actuator) if actuator is not None else None
    return spec.hand_sweep_source if spec is not None else None


def drives_sweep_auto(actuator: str | None) -> VendorSpec | None:
    """The declaration of a profile's ``actuator`` when ``sweep --auto`` drives it (None: not stated → Robstride)."""
    spec = VENDORS.get(actuator if actuator is not None else "robstride")
    return spec if spec is not None and spec.sweep_auto else None


def homing_vendor(name: str) -> VendorSpec | None:
    """The declaration of a vendor with a ``Homing_Offset`` register, or None.

    The caller words the refusal with :func:`expected_homing_vendors`.
    """
    spec = VENDORS.get(name)
    return spec if spec is not None and spec.homing is not None else None


def expected_homing_vendors(*, quoted: bool = True) -> str:
    """``"'feetech' or 'dynamixel'"`` (or unquoted): the valid vendors for a refusal message."""
    names = [f"{n!r}" if quoted else n for n in homing_vendors()]
    return " or ".join(names)
