"""A person's hands on simulated OpenArm arms (``robocal sim openarm``'s control socket and live view).

:class:`OpenArmHands` is the :class:`~robocal.backends.sim.operator.HandDevice` of one or two
:class:`~.openarm.SimOpenArm` arms: joints named as the OpenArm profiles and robocal's URDF name them
(``openarm_right_joint1`` … ``openarm_right_gripper_motor``), positions in rad in the joint frame. Placing a joint
sets its plant's state (the velocity follows from the previous placement; a joint pushed past a stop is put at
the stop); the plant then goes on under gravity and its motor's command, as a joint a hand lets go of. A joint whose motor is enabled with a command that
pushes (any gain or feed-forward torque) is held by the motor, and the hand cannot move it.

For fault injection each joint's view also carries the motor's state as a test judges it (``extra``): ``enabled``
(state 0x1, torque on), ``ram`` and ``flash`` (every register by name), ``zero_abs_rad`` (the zero in flash),
``flash_writes``, ``lost_comm_at_s`` (when its TIMEOUT tripped, simulated time), ``last_rx_s`` and
``torque_off_at`` (``[motor time, host monotonic time]`` of each frame or event that took its torque away, to time
a limp against the signal that asked for it);
:meth:`OpenArmHands.attach` is the control socket's ``attach`` command (the motors not named stop hearing and
answering: power or cable lost).
"""

from __future__ import annotations

import threading
import time
from collections.abc import Iterable, Sequence
from typing import Any

from ...errors import UsageError
from ..sim.operator import JointView
from .openarm import SimOpenArm
from .openarm_urdf import openarm_urdf_joint

__all__ = ["OpenArmHands"]

_ANSWERED = ("mit", "refresh", "enable", "disable", "set zero", "clear error")
"""Frames a motor answers with its position (a state frame)."""


class OpenArmHands:
    """The hand-movable view of simulated OpenArm arms (a ``HandDevice``; rad, joint frame)."""

    unit = "rad"
    step = 0.02

    def __init__(self, arms: Iterable[SimOpenArm]) -> None:
        self.lock = threading.RLock()
        self._joints: dict[str, tuple[SimOpenArm, str]] = {}
        for arm in arms:
            for j in arm.joints:
                self._joints[openarm_urdf_joint(arm.side, j.name)] = (arm, j.name)
        self._last: dict[str, tuple[float, float]] = {}

    def joint_names(self) -> Sequence[str]:
        """Every joint, arm by arm, J1 … J7 then the gripper."""
        return list(self._joints)

    def view(self, name: str) -> JointView:
        """One joint: position, stops, whether its motor holds it, the motor's reading, its last command."""
        arm, joint = self._joints[name]
        m, plant = arm.motors[joint], arm.plants[joint]
        spec = next(j for j in arm.joints if j.name == joint)
        with arm.bus.lock:
            cmd = m.last_command
            held = m.enabled and cmd is not None and any(abs(x) > 0 for x in (cmd.kp, cmd.kd, cmd.torque_nm))
            last = ""
            if cmd is not None:
                last = (
                    f"MIT q={cmd.position_rad:+.3f} dq={cmd.velocity_rad_s:+.2f} kp={cmd.kp:g} kd={cmd.kd:g} "
                    f"tau={cmd.torque_nm:+.2f}"
                )
            low = plant.params.stop_lower_rad
            high = plant.params.stop_upper_rad
            return JointView(
                name=name,
                position=plant.link_rad,
                low=spec.stop_lower_rad if low is None else low,
                high=spec.stop_upper_rad if high is None else high,
                mid=0.5 * (spec.stop_lower_rad + spec.stop_upper_rad),
                torque=held,
                reading=m.reading_rad(m.joint_rad()),
                last_write=last,
                last_write_age_s=None,
                extra={
                    "esc_id": m.esc_id,
                    "mst_id": m.mst_id,
                    "side": arm.side,
                    "motor": joint,
                    "state": int(m.state),
                    "enabled": m.enabled,
                    "flash_writes": m.flash_writes,
                    "zero_abs_rad": m.zero_abs_rad,
                    "ram": {r.name: v for r, v in m.ram.items()},
                    "flash": {r.name: v for r, v in m.flash.items()},
                    "lost_comm_at_s": list(m.lost_comm_at_s),
                    "last_rx_s": m.last_rx_s,
                    "torque_off_at": [list(t) for t in m.torque_off_at],
                },
            )

    def reads(self, name: str) -> int:
        """Frames the motor answered with its position so far (state frames)."""
        arm, joint = self._joints[name]
        requests = arm.motors[joint].requests
        return sum(requests.get(kind, 0) for kind in _ANSWERED)

    def place(self, name: str, position: float) -> None:
        """Put the joint at ``position``, or at the stop it would pass (a hard stop holds a joint pushed into it)."""
        arm, joint = self._joints[name]
        now = time.monotonic()
        with arm.bus.lock:
            plant = arm.plants[joint]
            low, high = plant.params.stop_lower_rad, plant.params.stop_upper_rad
            wanted = position
            if low is not None:
                position = max(position, low)
            if high is not None:
                position = min(position, high)
            t0, placed = self._last.get(name, (now, plant.link_rad))
            dt = now - t0
            # the hand's own speed, from its previous placement: not from where the limp link drifted meanwhile
            # (gravity between two placements; that drift over a short dt gave the link a speed that carried it
            # further by the next placement: the joint flew stop to stop when the reads came a few ms apart).
            # A hand pressing a joint into its stop holds it there, still: a speed would carry the link into the
            # soft stop's spring (past the stop by an amount that depends on how late the simulator's next step is)
            at_stop = position != wanted
            velocity = (position - placed) / dt if 0 < dt < 0.5 and not at_stop else 0.0
            arm.motors[joint].set_position(position, velocity)
        self._last[name] = (now, position)

    def attach(self, req: dict[str, Any]) -> dict[str, Any]:
        """The control socket's ``attach``: only the named joints' motors hear and answer (``"all"``: every one).

        A motor left out neither hears nor answers (:meth:`SimOpenArm.silence`): its power or cable lost, while
        its state and registers stay as they were (an enabled motor's TIMEOUT, if armed, then makes it limp).

        Raises:
            UsageError: ``joints`` is neither ``"all"`` nor a list of this device's joint names.
        """
        joints = req.get("joints", "all")
        if isinstance(joints, str):
            joints = list(self._joints) if joints == "all" else [joints]
        if not isinstance(joints, list) or any(j not in self._joints for j in joints):
            raise UsageError(f"attach: joints must be 'all' or names among {', '.join(self._joints)}")
        for name, (arm, joint) in self._joints.items():
            arm.silence(joint, name not in joints)
        return {"attached": [n for n in self._joints if n in joints]}
