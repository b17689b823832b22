"""The values and interfaces of the automatic hard-stop calibration: errors, clocks, drivers, views, outcomes.

Shared by :mod:`robocal.workflows.autocal.joint` (one joint), :mod:`robocal.workflows.autocal.job` (a robot) and
:mod:`robocal.workflows.autocal.group` (joints searched at the same time); see docs/auto_calibration.md.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterator, Mapping, Sequence
from contextlib import contextmanager, suppress
from dataclasses import dataclass
from typing import Any, Protocol

from ...backends import load_backend
from ...backends.bus_transaction import signals_held
from ...backends.clock import Clock, MonotonicClock
from ...core.named import get_named
from ...core.profile_auto import NOT_SEARCHED, AutoJoint
from ...core.stop_search import Command, JointStops, StopSample
from ...core.vendors import vendor_spec
from ...errors import CalibError, UsageError

__all__ = [
    "AutoCalAbortedError",
    "AutoCalFailedError",
    "AutoCalResult",
    "AutoView",
    "Clock",
    "ConfirmStart",
    "JointCaps",
    "JointDriver",
    "JointOutcome",
    "MonotonicClock",
    "joint_driver_class",
    "limp_all",
    "limp_on_error",
]

ConfirmStart = Callable[[Sequence[str], Mapping[str, float]], bool]
"""The clear-workspace question, asked before anything moves: the joints that will move (in order) and their
torque caps (N·m; a :class:`JointCaps`, which also knows each motor's model and rating); False: nothing moves."""


class JointCaps(dict[str, float]):
    """The torque cap (N·m) of each searched joint, with its motor model and that model's rating (for the prompt).

    Attributes:
        models: Joint → (motor model name, the model's rated torque in N·m).
        host_loss: What stops the motors if robocal is killed or the bus is lost (their watchdog, or none).
    """

    def __init__(self, joints: Sequence[AutoJoint], host_loss: str = "") -> None:
        super().__init__((j.name, j.torque_cap_nm) for j in joints if j.searched)
        self.host_loss = host_loss
        self.models: dict[str, tuple[str, float]] = {
            j.name: (j.motor or "?", j.model_rated_nm) for j in joints if j.searched
        }


class AutoCalAbortedError(CalibError):
    """The auto-calibration was interrupted or hit a fault: every motor was made limp, nothing was written."""

    exit_code = 3


class AutoCalFailedError(CalibError):
    """One or more joints failed (missing stop, snag, span mismatch, ...); nothing was written.

    Attributes:
        result: The run's result (the passing joints' zeros are in it).
    """

    exit_code = 3

    def __init__(self, message: str, result: AutoCalResult) -> None:
        super().__init__(message)
        self.result = result




class JointDriver(Protocol):
    """One joint as the stop search sees it (joint frame ``s = direction·raw``, rad; N·m)."""

    name: str

    def read(self) -> StopSample:
        """Read the joint without changing what the motor does."""
        ...

    def execute(self, cmd: Command) -> StopSample:
        """Carry out ``cmd`` for one control period; return the reading at its end."""
        ...

    def limp(self) -> None:
        """Torque off now (must not raise)."""
        ...

    def position_count_rad(self) -> float:
        """One count of the joint's position reading, rad (``--verify``'s resolution term; the vendor's)."""
        ...


class AutoView(Protocol):
    """A live view of the run."""

    def joint_start(self, name: str, cap_nm: float, speed_rad_s: float) -> None:
        """A joint's search begins."""
        ...

    def sample(self, name: str, phase: str, side: str, sample: StopSample) -> None:
        """One reading of the joint being searched."""
        ...

    def joint_done(self, outcome: JointOutcome) -> None:
        """A joint finished (passed or failed)."""
        ...


@dataclass(frozen=True)
class JointOutcome:
    """One joint's auto-calibration.

    Attributes:
        stops: The combined stops, zero and verdict (:class:`JointStops`).
        cap_nm: Torque cap used.
        speed_rad_s: Approach speed used.
        time_s: Time the joint took (search, back-off, parking).
    """

    stops: JointStops
    cap_nm: float
    speed_rad_s: float
    time_s: float

    @property
    def name(self) -> str:
        """Joint name."""
        return self.stops.name

    @property
    def ok(self) -> bool:
        """Whether the joint passed."""
        return self.stops.ok

    def to_report(self) -> dict[str, Any]:
        """The joint's report entry."""
        d = self.stops.to_report()
        d.update(cap_nm=round(self.cap_nm, 4), speed_deg_s=round(math.degrees(self.speed_rad_s), 3))
        d["time_s"] = round(self.time_s, 3)
        return d


@dataclass(frozen=True)
class AutoCalResult:
    """A whole run: the outcome of every searched joint in search order.

    Attributes:
        joints: Outcomes in order.
        total_time_s: Time of the whole run (driver clock).
        interrupted: The run was interrupted (the joints after the interruption are missing).
    """

    joints: tuple[JointOutcome, ...]
    total_time_s: float
    interrupted: bool = False

    def __getitem__(self, name: str) -> JointOutcome:
        return get_named(self.joints, name)

    @property
    def failed(self) -> tuple[JointOutcome, ...]:
        """Joints that failed (a joint without stops, ``not_searched``, did not fail)."""
        return tuple(j for j in self.joints if not j.ok and j.stops.code != NOT_SEARCHED)

    @property
    def not_searched(self) -> tuple[JointOutcome, ...]:
        """Joints the profile gives no stop (``stops: none``): never moved, nothing measured."""
        return tuple(j for j in self.joints if j.stops.code == NOT_SEARCHED)

    @property
    def offsets_rad(self) -> dict[str, float]:
        """Joint-frame position offsets (``q_joint = s − offset``) of the passing joints."""
        return {j.name: j.stops.offset_rad for j in self.joints if j.ok}

    def failure_summary(self) -> str:
        """One line naming each failed joint with its code and reason."""
        return "; ".join(f"{j.name}: {j.stops.code} ({j.stops.reason})" for j in self.failed)

    def to_report(self) -> dict[str, Any]:
        """The ``auto`` part of a sweep report."""
        return {
            "total_time_s": round(self.total_time_s, 3),
            "interrupted": self.interrupted,
            "joints": {j.name: j.to_report() for j in self.joints},
        }


# ------------------------------------------------------------------------------------------------ limp
def limp_all(drivers: Mapping[str, JointDriver] | Sequence[JointDriver]) -> list[str]:
    """Torque off every driver (errors ignored: each motor gets its chance); returns the joints whose limp failed.

    First every enabled driver (a driver without ``enabled`` counts as enabled) that can send its torque-off
    without awaiting a reply (``torque_off_nowait``, the MIT-mode CAN motors) does so, all before any reply is
    waited for; then each driver's confirmed ``limp``, the enabled ones first. So no motor that can push waits
    behind another motor's exchanges, lost replies or watchdog bookkeeping (issue 26: every motor limp within
    100 ms). Signals are held off meanwhile (:func:`~robocal.backends.bus_transaction.signals_held`): one that
    comes during a limp (Ctrl-C just after the file was written) no longer skips the watchdogs put back after it.
    """
    items = list(drivers.values() if isinstance(drivers, Mapping) else drivers)
    ordered = sorted(items, key=lambda d: not getattr(d, "enabled", True))
    failed: list[str] = []
    with signals_held():  # a signal meanwhile comes out once every motor is limp and its watchdog put back
        for d in ordered:
            quick = getattr(d, "torque_off_nowait", None)
            if quick is not None and getattr(d, "enabled", True):
                with suppress(Exception):  # never raises by contract; a limp must reach every motor all the same
                    quick()
        for d in ordered:
            try:  # a limp must reach every motor
                d.limp()
            except Exception:
                failed.append(d.name)
    return failed


@contextmanager
def limp_on_error(drivers: Mapping[str, JointDriver]) -> Iterator[None]:
    """Any exception inside (Ctrl-C too): every driver goes limp, then the exception propagates."""
    try:
        yield
    except BaseException:
        limp_all(drivers)
        raise


def joint_driver_class(vendor: str) -> Any:
    """The stop-search joint driver class of ``vendor``, from its home through ``load_backend``.

    E.g. ``joint_driver_class("feetech")(bus, "wrist_roll", 5, rated_nm=1.91, cap_nm=0.48, clock=clock)``.

    Raises:
        UsageError: Unknown vendor, or a vendor without a stop search.
    """
    spec = vendor_spec(vendor)
    if spec.joint_driver is None:
        raise UsageError(f"no stop-search driver for vendor {vendor!r}")
    return load_backend(spec.joint_driver)
