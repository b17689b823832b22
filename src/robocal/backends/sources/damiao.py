"""Damiao CAN source for the hand sweep: live motors (an OpenArm) read-only, the person moves the joints.

:class:`DamiaoSource` opens one :class:`~robocal.backends.damiao.bus.DamiaoBus` per channel through the backend
registry with motion not allowed (the bus refuses enable, pushing MIT frames, register writes and zeroing). It
switches every motor off once (0xFD, allowed read-only: an arm a person moves must be limp), then each
:meth:`~DamiaoSource.read` asks every motor for a state frame (0x7FF refresh), which changes nothing in the motor.
A motor reporting an error state ends the sweep with its named fault (exit 3).
"""

from __future__ import annotations

import time
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from ...core.profile import RobotProfile
from ...errors import CalibTimeoutError, UsageError
from .. import load_backend
from .live_can import LiveCanSource
from .spec import JointSpec, Sample, SourceSpec, can_bus_options

__all__ = ["SILENT_LIMIT_S", "DamiaoSource", "SimOpenArmHandSource", "open_sim_openarm_source"]

SILENT_LIMIT_S = 2.0
"""A bus with no complete refresh answered for this long, s, ends the sweep (a cable or power lost)."""
SIM_READ_PERIOD_S = 0.005
"""The in-process simulated arm is read every 5 ms (a real bus's own pace; the simulator shares the process)."""


class DamiaoSource(LiveCanSource):
    """Live joint positions from Damiao buses, read passively (refresh frames; every motor off).

    Args:
        joints: The joints, in the sweep's order.
        buses: One open :class:`~robocal.backends.damiao.bus.DamiaoBus` per channel, its motors named as the joints.
    """

    def __init__(self, joints: Sequence[JointSpec], buses: Sequence[Any]) -> None:
        super().__init__(joints, buses)
        self._answered: dict[int, float] = {}
        self.silent_limit_s = SILENT_LIMIT_S
        """A bus that has answered no refresh for this long ends the sweep (:meth:`read`)."""

    @classmethod
    def open(
        cls,
        spec: SourceSpec,
        joints: Sequence[JointSpec],
        profile: RobotProfile,
        *,
        timeout_s: float | None = None,
    ) -> DamiaoSource:
        """Open ``spec``'s channels (one per bus of the profile, in its order), read-only, and switch every motor off.

        Args:
            spec: A ``can:<interface>:<channel>[,...]`` source.
            joints: The joints to read (each in the profile, with its ``id``, ``reply_id`` and ``model``).
            profile: The robot profile (ids, reply ids, models and buses of the joints).
            timeout_s: Reply timeout per request (default: the bus's).

        Raises:
            UsageError: A joint lacks an id, reply id or model, or the channels and the buses differ in number.
            DeviceError, CalibTimeoutError: A channel cannot be opened or a motor does not answer.
        """
        from ..damiao.bus import motors_by_bus as profile_motors

        motors_by_bus = list(profile_motors(profile, (j.name for j in joints)).values())
        if len(spec.channels) != len(motors_by_bus):
            raise UsageError(
                f"--source {spec.text!r}: the robot has {len(motors_by_bus)} CAN bus(es); give one channel each"
            )
        bus_cls = load_backend("damiao")
        kw: dict[str, Any] = {} if timeout_s is None else {"timeout_s": timeout_s}
        opts = can_bus_options(spec)
        buses: list[Any] = []
        try:
            for channel, motors in zip(spec.channels, motors_by_bus, strict=True):
                buses.append(bus_cls(channel, list(motors), interface=spec.interface, bus_kwargs=opts or None, **kw))
            for bus in buses:
                bus.disable()
        except BaseException:
            for b in buses:
                b.close()
            raise
        return cls(joints, buses)

    def read(self) -> Sample:
        """Refresh every motor once; raw positions, velocities and torques (motor frame).

        A bus whose replies do not all come in time gives NaN for its joints in this sample (a reply late on a
        loaded machine or network); only a bus silent for :attr:`silent_limit_s` ends the sweep.

        Raises:
            CalibTimeoutError: A bus has not answered for :attr:`silent_limit_s`.
            DamiaoFaultError: A motor reports an error state (its subclass names the code).
        """
        n = len(self.joint_names)
        pos, vel, eff = np.full(n, np.nan), np.full(n, np.nan), np.full(n, np.nan)
        now = time.monotonic()
        for k, bus in enumerate(self.buses):
            try:
                states: Mapping[str, Any] = bus.refresh()
            except CalibTimeoutError:
                if now - self._answered.get(k, self._t0) > self.silent_limit_s:
                    raise
                continue
            self._answered[k] = now
            for name, st in states.items():
                i = self._index[name]
                pos[i], vel[i], eff[i] = st.position_rad, st.velocity_rad_s, st.torque_nm
        return Sample(self._now(), pos, vel, eff)

    def zero_sta(self) -> dict[str, int]:
        """1 for every joint: after a power cycle a Damiao motor reads within ±π of its stored zero."""
        return dict.fromkeys(self.joint_names, 1)


class SimOpenArmHandSource(DamiaoSource):
    """The simulated OpenArm (in real time, on python-can's ``virtual`` bus) with simulated hands, read as a live arm.

    :meth:`begin_sweep` has the hands sweep every joint into both stops, paced by the reads (each placement is
    read before the hand moves on); the source is exhausted a few samples after the hands are done.
    """

    def __init__(self, joints: Sequence[JointSpec], buses: Sequence[Any], arm: Any, operator: Any) -> None:
        super().__init__(joints, buses)
        self.arm = arm
        self.operator = operator
        self._begun = False
        self._idle = 0

    @property
    def exhausted(self) -> bool:
        """True a few samples after the hands finished the sweep."""
        return self._begun and self._idle > 3

    def read(self) -> Sample:
        """Read every motor, at most every :data:`SIM_READ_PERIOD_S`; count the samples since the hands stopped.

        The simulator's pacer and hands run in this process: a read loop that never lets go starves them.
        """
        time.sleep(SIM_READ_PERIOD_S)
        sample = super().read()
        if self._begun and not self.operator.busy:
            self._idle += 1
        return sample

    def begin_sweep(self) -> None:
        """The hands sweep every joint (paced)."""
        self.operator.sweep(None, seconds=3.0, dwell_s=0.3, paced=True)
        self._begun = True

    def close(self) -> None:
        """Close the bus, stop the hands and the simulated arm."""
        super().close()
        self.operator.close()
        self.arm.stop()


def open_sim_openarm_source(spec: SourceSpec, joints: Sequence[JointSpec]) -> SimOpenArmHandSource:
    """Start the simulated OpenArm arm of the joints' side (``sim:openarm?seed=N&zeroed=1``) with its hands.

    The joints are matched to the simulated motors by their CAN id (ESC_ID, the URDF's ``can_id``).

    Raises:
        UsageError: Joints of no single OpenArm side, or a CAN id the arm does not have.
    """
    from ..damiao.bus import DamiaoMotor
    from ..damiao.openarm import SimOpenArm
    from ..damiao.openarm_hands import OpenArmHands
    from ..sim.operator import HandOperator

    sides = {s for s in ("right", "left") if all(j.name.startswith(f"openarm_{s}_") for j in joints)}
    if len(sides) != 1:
        raise UsageError(f"--source {spec.text!r}: the joints are not one OpenArm arm's (openarm_right_… / openarm_left_…)")
    (side,) = sides
    arm = SimOpenArm(
        f"robocal-hand-openarm-{id(joints)}-{time.monotonic_ns()}",
        side=side,  # type: ignore[arg-type]
        seed=int(spec.options.get("seed", "0")),
        zeroed=spec.options.get("zeroed") == "1",
        realtime=True,
    ).start()
    try:
        by_id = {j.esc_id: j for j in arm.joints}
        unknown = [f"{j.name} (can_id {j.can_id})" for j in joints if j.can_id not in by_id]
        if unknown:
            raise UsageError(f"--source {spec.text!r}: the simulated OpenArm has no motor for {', '.join(unknown)}")
        motors = [DamiaoMotor(j.name, j.can_id, by_id[j.can_id].mst_id, by_id[j.can_id].model) for j in joints]
        bus = load_backend("damiao")(arm.channel, motors, interface="virtual", timeout_s=1.0)
    except BaseException:
        arm.stop()
        raise
    bus.disable()
    return SimOpenArmHandSource(joints, [bus], arm, HandOperator(OpenArmHands([arm])))
