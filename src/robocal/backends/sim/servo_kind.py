"""How the simulated servos of one vendor differ on the wire and in their firmware: the simulator's vendor adapter.

Each servo vendor declares one :class:`SimServoKind` in its home (``backends/<vendor>/sim.py``);
:data:`robocal.backends.sim.servo_model.SIM_SERVO_KINDS` collects them.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, field

from .._servo_common import ServoModel
from .servo_firmware import ServoFirmware
from .servo_packets import Instruction

__all__ = ["SimServoKind"]


@dataclass(frozen=True)
class SimServoKind:
    """How the simulated servos of one vendor differ on the wire and in their firmware (the simulator's adapter).

    The homing rule, where ``Drive_Mode`` lives and the lock register come from the vendor's declaration
    (:mod:`robocal.core.vendors`); this holds what only the simulator needs.

    Attributes:
        vendor: The vendor's name.
        models: Model name → the backend's :class:`~robocal.backends.servo_bus.ServoModel`.
        power_on: ``(register, value)`` a new servo holds, set where its model's table has the register.
        twos_complement: Registers whose value is signed (two's complement); the others read unsigned. Unused
            where signed registers are sign-magnitude (their sign bits are the backend's ``SIGN_BITS``).
        clamps_goal: The firmware clamps ``Goal_Position`` into ``Min/Max_Position_Limit``.
        single_turn_mode: The ``Operating_Mode`` in which Present wraps to one turn (None: the homing rule says).
        address_bytes: Width of the address and length fields of READ / WRITE / SYNC packets.
        parse: Parses one instruction packet (:mod:`.servo_packets`).
        status: Builds one status packet.
        ping_reports_model: PING answers with ``Model_Number`` and ``Firmware_Version``.
        reboot: Knows REBOOT (0x08), which clears a hardware error.
        unknown_instruction_error: Status error byte for an instruction it does not know.
        eeprom_locked_by_torque: EEPROM (addresses below ``Torque_Enable``) refuses writes while the torque is on
            (Access error 7).
        firmware: The firmware class (control law, protection, status bits) a servo with physics runs.
        baud_rates: ``Baud_Rate`` register value → bit/s.
        factory_baud: ``Baud_Rate`` as shipped.
        status_level: The register gating replies (None: every instruction is answered).
        reply_levels: Instruction → the lowest ``status_level`` value at which it is still answered; an
            instruction not listed needs ``full_reply_level``.
        full_reply_level: The ``status_level`` value at which every instruction is answered.
        set_middle: The ``Torque_Enable`` value that makes the present position read half a turn (None: none).
        value_ranges: Register → the (lowest, highest) value it takes; a write outside is refused with
            ``range_error`` (none refused where empty).
        range_error: Status error byte of such a write (Dynamixel: Data Range error, 4).
    """

    vendor: str
    models: Mapping[str, ServoModel]
    power_on: tuple[tuple[str, int], ...]
    twos_complement: tuple[str, ...]
    clamps_goal: bool
    single_turn_mode: int | None
    address_bytes: int
    parse: Callable[[bytes | bytearray], tuple[int, Instruction | None]]
    status: Callable[..., bytes]
    ping_reports_model: bool
    reboot: bool
    unknown_instruction_error: int
    eeprom_locked_by_torque: bool
    firmware: type[ServoFirmware]
    baud_rates: Mapping[int, int]
    factory_baud: int
    status_level: str | None = None
    reply_levels: Mapping[int, int] = field(default_factory=dict)
    full_reply_level: int = 0
    set_middle: int | None = None
    value_ranges: Mapping[str, tuple[int, int]] = field(default_factory=dict)
    range_error: int = 0
