"""Joints searched at the same time: several joints' steps carried out in lockstep, one control period each.

A profile may put a joint ``alongside`` an earlier one (:class:`~robocal.core.profile_auto.AutoJoint`): the two
are independent (neither holds a pose for the other, their holds agree), so their searches run together and the
run takes the longer of the two instead of their sum. Each joint's moves are the same steps as alone
(:func:`robocal.workflows.autocal.joint.calibrate_joint_steps`, with the same bounds, detector and back-off); per
control period every active joint gets its command and its reading, then the clock lets the rest of the period
pass once. A driver with a ``send`` method (the servo drivers: :meth:`execute` without the wait) shares one
period; a driver without it is carried out by its own :meth:`execute` (its period then includes the other
joints' bus time).

Any exception (a device fault, Ctrl-C) from one joint ends every joint's steps and propagates; the caller makes
every motor limp (:func:`robocal.workflows.autocal.model.limp_on_error`).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import TypeVar

from ...core.stop_search import Command, StopSample
from .joint import JointSteps
from .model import Clock, JointDriver

__all__ = ["run_lockstep"]

_T = TypeVar("_T")


def run_lockstep(
    drivers: Mapping[str, JointDriver],
    steps: Mapping[str, JointSteps[_T]],
    clock: Clock | None,
    period_s: float = 0.01,
) -> dict[str, _T]:
    """Carry out every joint's ``steps`` at once on its driver; each joint's result.

    Args:
        drivers: Joint → driver (one per entry of ``steps``).
        steps: Joint → its steps (started here, in the mapping's order each period).
        clock: The run's clock; with it, drivers that have ``send`` share one control period.
        period_s: The control period (the longest ``period_s`` of the drivers is used when they have one).

    Returns:
        Joint → the value its steps returned.
    """
    results: dict[str, _T] = {}
    pending: dict[str, Command] = {}
    senders: dict[str, Callable[[Command], StopSample]] = {}
    for name in steps:
        send = getattr(drivers[name], "send", None)
        if clock is not None and callable(send):
            senders[name] = send
            period_s = max(period_s, float(getattr(drivers[name], "period_s", period_s)))
    try:
        for name, st in steps.items():
            try:
                pending[name] = next(st)
            except StopIteration as stop:
                results[name] = stop.value
        while pending:
            t0 = clock.now() if clock is not None else 0.0
            readings: dict[str, StopSample] = {}
            for name, cmd in pending.items():
                send = senders.get(name)
                readings[name] = send(cmd) if send is not None else drivers[name].execute(cmd)
            if clock is not None and senders:
                clock.sleep(max(0.0, period_s - (clock.now() - t0)))
            for name, reading in readings.items():
                try:
                    pending[name] = steps[name].send(reading)
                except StopIteration as stop:
                    results[name] = stop.value
                    del pending[name]
    finally:
        for st in steps.values():
            st.close()
    return results
