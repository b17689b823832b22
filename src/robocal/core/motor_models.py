"""robocal's motor model table: each motor's rated and stall torque, with the document the numbers come from.

Every torque an automatic calibration asks a motor for is a fraction of a rating in this table: a robot profile may
name the model (``model: rs-05`` on the joint, or ``motor: sts3215-12v`` in its ``auto_calibration`` row) and may
lower the rating (``rated_nm``), never raise it (:mod:`robocal.formats._profile_auto` refuses that when the profile
is read). The drivers clamp every torque they send to :func:`ceiling_nm` of the model, whatever they are asked for
(:mod:`robocal.backends.robstride.joint_driver`, :mod:`robocal.backends.servo_joint_driver`).

Torques are at the output shaft, N·m. The Robstride manuals give a rated (continuous) and a peak torque. The
Feetech and ROBOTIS datasheets give only the stall torque at a supply voltage; robocal rates a servo at that stall
torque (its ``Torque_Limit`` 1000 / ``Goal_Current`` at the stall current / ``Goal_PWM`` 885 are that torque), so
for the servos ``rated_nm == stall_nm``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from ..errors import UsageError

__all__ = [
    "HARD_MAX_TORQUE_FRACTION",
    "MOTOR_MODELS",
    "MotorModel",
    "ceiling_nm",
    "find_motor_model",
    "motor_key",
    "rated_motor_model",
]

HARD_MAX_TORQUE_FRACTION = 0.5
"""No search pushes harder than this fraction of the motor model's rated torque (no flag, file or variable lifts it)."""

_KG_CM = 9.80665 / 100.0  # 1 kg·cm in N·m


@dataclass(frozen=True)
class MotorModel:
    """One motor model's torque ratings.

    Attributes:
        name: The model as robocal names it (``RS05``, ``STS3215-12V``, ``XL330-M288``).
        family: ``robstride``, ``feetech``, ``dynamixel`` or ``damiao``.
        rated_nm: The rating torque caps are fractions of (Robstride: rated; servos: stall), N·m at the output.
        stall_nm: Peak (Robstride) or stall torque (servos), N·m at the output.
        source: The document the numbers come from.
        bus_model: The model name the vendor bus reports for it (a 12 V STS3215 answers as ``sts3215``).
    """

    name: str
    family: str
    rated_nm: float
    stall_nm: float
    source: str
    bus_model: str

    @property
    def ceiling_nm(self) -> float:
        """The hard ceiling of every search torque on this model: :data:`HARD_MAX_TORQUE_FRACTION` of its rating."""
        return HARD_MAX_TORQUE_FRACTION * self.rated_nm


_RS_MANUAL = "Robstride RS0x user manual rev. 260428, ch. 4 model #define block (rated / peak torque)"


def _rs(name: str, rated: float, peak: float) -> MotorModel:
    return MotorModel(name, "robstride", rated, peak, _RS_MANUAL, name.lower()[:2] + "-" + name[2:])


_DM_DATASHEET = (
    "OpenArm docs, hardware/openarm-2.0/motor.mdx (enactic/openarm@1080ae9), Damiao datasheet table: {model} "
    "rated {rated:g} / peak {peak:g} N·m at 24 V"
)


def _dm(name: str, datasheet_model: str, rated: float, peak: float) -> MotorModel:
    source = _DM_DATASHEET.format(model=datasheet_model, rated=rated, peak=peak)
    return MotorModel(name, "damiao", rated, peak, source, name)


def _servo(name: str, family: str, stall: float, source: str, bus_model: str | None = None) -> MotorModel:
    return MotorModel(name, family, stall, stall, source, bus_model or name.lower())


MOTOR_MODELS: tuple[MotorModel, ...] = (
    _rs("RS00", 5.0, 14.0),
    _rs("RS01", 6.0, 17.0),
    _rs("RS02", 6.0, 17.0),
    _rs("RS03", 20.0, 60.0),
    _rs("RS04", 40.0, 120.0),
    _rs("RS05", 1.6, 5.5),
    _rs("RS06", 11.0, 36.0),
    _rs("EL05", 1.8, 6.0),
    _servo(
        "STS3215",
        "feetech",
        1.91,
        "Feetech ST/STS3215 (C001, 1/345) datasheet: 19.5 kg·cm stall at 7.4 V; SO-ARM100 bill of materials",
        "sts3215",
    ),
    _servo(
        "STS3215-12V",
        "feetech",
        round(30.0 * _KG_CM, 3),
        "Feetech STS3215 12 V (C018, 1/345) datasheet: 30 kg·cm stall at 12 V (the SO-ARM100 BOM's 12 V option)",
        "sts3215",
    ),
    _servo("STS3250", "feetech", 4.9, "Feetech STS3250 specification sheet: 50 kg·cm stall at 12 V"),
    _servo("SCS0009", "feetech", 0.23, "Feetech SCS0009 datasheet: 2.3 kg·cm stall at 6 V"),
    _servo("SM8512BL", "feetech", 11.8, "Feetech SM8512BL datasheet: 120 kg·cm stall at 12 V"),
    _servo("XL330-M077", "dynamixel", 0.228, "ROBOTIS e-Manual XL330-M077-T: stall 0.228 N·m at 6.0 V, 1.74 A"),
    _servo("XL330-M288", "dynamixel", 0.52, "ROBOTIS e-Manual XL330-M288-T: stall 0.52 N·m at 5.0 V, 1.47 A"),
    _servo("XL430-W250", "dynamixel", 1.5, "ROBOTIS e-Manual XL430-W250-T: stall 1.5 N·m at 12 V, 1.4 A"),
    _servo("XC430-W150", "dynamixel", 1.4, "ROBOTIS e-Manual XC430-W150-T: stall 1.4 N·m at 12 V, 1.4 A"),
    _servo("XM430-W350", "dynamixel", 4.1, "ROBOTIS e-Manual XM430-W350: stall 4.1 N·m at 12 V, 2.3 A"),
    _servo("XM540-W270", "dynamixel", 10.6, "ROBOTIS e-Manual XM540-W270: stall 10.6 N·m at 12 V, 4.4 A"),
    _dm("DM4310", "DM-J4310-2EC V1.1", 3.0, 7.0),
    _dm("DM4340", "DM4340 series (DM-J4340-2EC, DM-J4340P-2EC)", 9.0, 27.0),
    _dm("DM8009", "DM-J8009P-2EC", 20.0, 40.0),
)
"""Every motor model robocal knows (a test pins the numbers)."""


def motor_key(name: str) -> str:
    """The lookup key of a model name: upper case without ``-``, ``_`` or spaces (``rs-05`` → ``RS05``)."""
    return "".join(c for c in name.strip().upper() if c not in "-_ ")


_BY_KEY = {motor_key(m.name): m for m in MOTOR_MODELS}
_BY_KEY.update({motor_key("STS3215-C001"): _BY_KEY["STS3215"], motor_key("STS3215-C018"): _BY_KEY["STS321512V"]})


def find_motor_model(name: str | None) -> MotorModel | None:
    """The model named ``name`` (``rs-05``, ``RS05``, ``sts3215-12v``, ``STS3215-C018``), or None when unknown."""
    if name is None:
        return None
    return _BY_KEY.get(motor_key(name))


def rated_motor_model(joint: str, name: str | None) -> MotorModel:
    """The model table entry a joint's motor must have before anything pushes it.

    Raises:
        UsageError: ``name`` is not in the table (no rating, so no torque ceiling).
    """
    found = find_motor_model(name)
    if found is None:
        raise UsageError(f"joint {joint}: motor model {name!r} has no rating in robocal's model table")
    return found


def ceiling_nm(name: str | None) -> float:
    """The hard ceiling (N·m) of any search torque on model ``name``; 0 for an unknown model (it never pushes)."""
    model = find_motor_model(name)
    if model is None or not math.isfinite(model.rated_nm):
        return 0.0
    return model.ceiling_nm
