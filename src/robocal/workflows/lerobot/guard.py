"""The motion guard of a LeRobot arm's bus: limp every motor, write a register snapshot back (issue 26).

:func:`arm_guard` builds the :class:`~robocal.workflows.motion_guard.MotionGuard` every LeRobot command that writes
to the motors runs under (``calibrate``, ``calibrate --auto``, ``calibrate --use-file``, ``configure``): limp is
``Torque_Enable`` 0 in one SYNC_WRITE and then once per motor, read back; restore writes the snapshot back motor
by motor (:func:`robocal.workflows.lerobot.eeprom._rollback`, which reads it back), after rebooting Dynamixels
whose protection latched.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from contextlib import suppress

from ...backends.servo_bus import ServoBus
from ...core.lerobot import RobotSpec
from ...errors import DeviceError
from ..motion_guard import MotionGuard
from ..motion_snapshot import SnapshotStore
from .eeprom import RollbackReport, _rollback

__all__ = ["arm_guard", "limp_arm", "restore_registers"]


def limp_arm(bus: ServoBus, spec: RobotSpec) -> list[str]:
    """Torque off on every motor in one SYNC_WRITE, then once more per motor, then read back; never raises.

    Returns:
        ``"name (id N)"`` of the motors whose ``Torque_Enable`` did not read back 0 (or could not be read: the
        read-back is one SYNC_READ of every motor).
    """
    with suppress(Exception):
        bus.sync_write("Torque_Enable", {m.motor_id: 0 for m in spec.motors})
    for m in spec.motors:
        with suppress(Exception):
            bus.sync_write("Torque_Enable", {m.motor_id: 0})
    now: dict[int, int] = {}
    try:  # one SYNC_READ: a bus that does not answer costs one timeout, not one per motor
        now = bus.sync_read("Torque_Enable", [m.motor_id for m in spec.motors])
    except DeviceError:
        pass
    except Exception:  # a bus without SYNC_READ (Feetech SCS): one read per motor
        for m in spec.motors:
            with suppress(Exception):
                now[m.motor_id] = bus.read("Torque_Enable", m.motor_id)
    return [f"{m.name} (id {m.motor_id})" for m in spec.motors if now.get(m.motor_id, 1) != 0]


def restore_registers(
    bus: ServoBus,
    spec: RobotSpec,
    before: Mapping[str, Mapping[str, int]],
    on_status: Callable[[str], None] | None,
) -> RollbackReport:
    """Every motor limp, the watchdogs disarmed, latched Dynamixels rebooted, the snapshot written back (checked)."""
    limp_arm(bus, spec)
    disarm = getattr(bus, "disarm_watchdog", None)  # Dynamixel Bus_Watchdog; Feetech has none
    if disarm is not None:  # first: a tripped Bus_Watchdog refuses the goal registers the snapshot restores
        with suppress(Exception):
            disarm([m.motor_id for m in spec.motors])
    latched = spec.vendor_spec.latched_error_register
    if latched is not None:
        reboot = getattr(bus, "reboot", None)
        for m in spec.motors:
            with suppress(Exception):
                if reboot is not None and bus.sync_read(latched, [m.motor_id])[m.motor_id]:
                    reboot(m.motor_id)
    return _rollback(bus, spec, before, on_status)


def arm_guard(
    bus: ServoBus,
    spec: RobotSpec,
    *,
    command: str,
    on_status: Callable[[str], None] | None = None,
    snapshot_port: str | None = None,
) -> MotionGuard:
    """The guard of ``bus`` (``snapshot_port``: keep the snapshot in the state folder under that port's name)."""
    return MotionGuard(
        limp=lambda: limp_arm(bus, spec),
        restore=lambda snap: restore_registers(bus, spec, snap, on_status),
        on_status=on_status,
        store=SnapshotStore(snapshot_port, command) if snapshot_port is not None else None,
    )
