"""Robstride CAN sources: live motors on python-can buses, and the simulated Lite on python-can's ``virtual`` bus.

Both open :class:`~robocal.backends.robstride.RobstrideBus` through the backend registry
(:func:`robocal.backends.load_backend`), so the simulated robot runs the same bus code as the real one.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np

from ...errors import CalibTimeoutError, JointMismatchError, UsageError
from .. import load_backend
from .live_can import LiveCanSource
from .spec import JointSpec, Sample, SourceSpec, can_bus_options

__all__ = ["RobstrideSource", "SimLiteSource", "open_can", "open_sim_lite_source"]


class RobstrideSource(LiveCanSource):
    """Live joint positions from Robstride buses, read passively (MIT zero-torque polls).

    Args:
        joints: The joints (with CAN id and model).
        buses: One :class:`~robocal.backends.robstride.RobstrideBus` per channel, each listing its joints.
    """

    def read(self) -> Sample:
        """Poll every joint once (zero torque) and return raw positions, velocities and torques."""
        n = len(self.joint_names)
        pos = np.full(n, np.nan)
        vel = np.full(n, np.nan)
        eff = np.full(n, np.nan)
        for bus in self.buses:
            for name, fb in bus.zero_torque().items():
                i = self._index[name]
                pos[i], vel[i], eff[i] = fb.position_rad, fb.velocity_rad_s, fb.torque_nm
        return Sample(self._now(), pos, vel, eff)

    def zero_sta(self) -> dict[str, int]:
        """Read ``zero_sta`` (0x7029) of every motor."""
        from ..robstride.protocol import Param

        out: dict[str, int] = {}
        for bus in self.buses:
            out.update({k: int(v) for k, v in bus.read_param_many(list(bus.motors), Param.ZERO_STA).items()})
        return out


class SimLiteSource(RobstrideSource):
    """The simulated Lite robot read through the real :class:`RobstrideBus` code path.

    Each :meth:`read` first advances simulated time by one tick (the simulated operator moves), then polls the
    motors over the ``virtual`` bus. The source is exhausted a few ticks after the operator's sweep ends.
    """

    def __init__(self, joints: Sequence[JointSpec], sim: Any, *, timeout_s: float = 5.0) -> None:
        # the simulated motors answer at once; a long reply timeout only matters on a heavily loaded machine,
        # where a thread may wait for the GIL longer than a real bus's 0.5 s
        from ..robstride import MotorSpec
        from ..sim.lite import LITE_JOINTS

        bus_class = load_backend("robstride")

        table = {j.name: j for j in LITE_JOINTS}
        unknown = [j.name for j in joints if j.name not in table]
        if unknown:
            raise JointMismatchError(
                f"sim:lite has no joint(s) {', '.join(unknown)}; it simulates {', '.join(table)}"
            )
        self.sim = sim
        buses = []
        for bus_name, channel in sim.channels.items():
            specs = [MotorSpec(j.name, table[j.name].can_id, table[j.name].model) for j in joints]
            specs = [s for s in specs if table[s.name].bus == bus_name]
            if specs:
                buses.append(bus_class(channel, specs, interface="virtual", timeout_s=timeout_s))
        super().__init__(joints, buses)
        self._idle = 0

    @property
    def exhausted(self) -> bool:
        """True a few ticks after the simulated operator finished the sweep."""
        return bool(self.sim.operator.sweep_started and self._idle > 3)

    def read(self) -> Sample:
        """Advance the simulation one tick, then poll the motors."""
        self.sim.step()
        if self.sim.operator.sweep_started and not self.sim.operator.busy:
            self._idle += 1
        s = super().read()
        return Sample(self.sim.t_s, s.position_rad, s.velocity_rad_s, s.effort_nm)

    def begin_sweep(self) -> None:
        """The simulated operator starts sweeping."""
        self.sim.operator.begin_sweep()

    def prompt_positive(self, joint: str) -> None:
        """The simulated operator moves ``joint`` toward its + limit."""
        self.sim.operator.move_toward_plus(joint)

    def close(self) -> None:
        """Close the buses and stop the simulated robot."""
        super().close()
        self.sim.stop()


def open_sim_lite_source(spec: SourceSpec, joints: Sequence[JointSpec]) -> SimLiteSource:
    """Start the simulated Lite with the ``sim:lite?...`` options and read ``joints`` from it."""
    from ..sim.lite import SimLite

    o = spec.options
    names = {j.name for j in joints}

    def names_of(key: str) -> list[str]:
        items = [x for x in o.get(key, "").split(",") if x]
        bad = [x for x in items if x not in names]
        if bad:
            raise UsageError(f"--source {spec.text!r}: {key}: unknown joint(s) {', '.join(bad)}")
        return items

    short: dict[str, float] = {}
    for item in [x for x in o.get("short", "").split(",") if x]:
        joint, _, amount = item.partition(":")
        try:
            value = float(amount or "0.4")
        except ValueError:
            value = math.nan
        if joint not in names or not (math.isfinite(value) and value >= 0):
            raise UsageError(f"--source {spec.text!r}: short: expected joint[:rad], got {item!r}")
        short[joint] = value
    sim = SimLite(
        int(o.get("seed", "0")),
        noise_rad=float(o.get("noise", "3e-4")),
        flip=names_of("flip"),
        zero_sta=int(o.get("zero_sta", "1")),
        single_turn=o.get("single_turn", "0") == "1",
        skip=names_of("skip"),
        short_rad=short,
    )
    sim.start()
    try:
        return SimLiteSource(joints, sim)
    except BaseException:
        sim.stop()
        raise


def open_can(spec: SourceSpec, joints: Sequence[JointSpec], timeout_s: float) -> RobstrideSource:
    """Open the ``can:`` buses; with several channels each joint is placed where its CAN id answers."""
    from ..robstride import MotorSpec
    from ..robstride.protocol import model_limits

    bus_class = load_backend("robstride")
    opts = can_bus_options(spec)

    missing_ids = [j.name for j in joints if j.can_id <= 0]
    if missing_ids:
        raise UsageError(f"joints without a can_id param in the URDF: {', '.join(missing_ids)}")
    for j in joints:
        try:
            model_limits(j.model)
        except UsageError as exc:
            raise UsageError(f"joint {j.name!r}: {exc}") from None
    if len(spec.channels) == 1:
        specs = [MotorSpec(j.name, j.can_id, j.model) for j in joints]
        bus = bus_class(spec.channels[0], specs, interface=spec.interface, timeout_s=timeout_s, bus_options=opts)
        return RobstrideSource(joints, [bus])
    # several channels: find each joint where its CAN id answers a (harmless) type-0 device-id request
    probes = [
        bus_class(ch, [], interface=spec.interface, timeout_s=timeout_s, bus_options=opts) for ch in spec.channels
    ]
    try:
        found = [p.probe([j.can_id for j in joints]) for p in probes]
    finally:
        for p in probes:
            p.close()
    buses = []
    placed: set[str] = set()
    for ch, ids in zip(spec.channels, found, strict=True):
        specs = [
            MotorSpec(j.name, j.can_id, j.model) for j in joints if j.can_id in ids and j.name not in placed
        ]
        placed.update(s.name for s in specs)
        if specs:
            buses.append(bus_class(ch, specs, interface=spec.interface, timeout_s=timeout_s, bus_options=opts))
    lost = [f"{j.name!r} (CAN id {j.can_id})" for j in joints if j.name not in placed]
    if lost:
        for b in buses:
            b.close()
        raise CalibTimeoutError(f"no reply on {', '.join(spec.channels)} from {', '.join(lost)}")
    return RobstrideSource(joints, buses)
