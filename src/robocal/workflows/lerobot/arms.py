"""The LeRobot arms robocal knows (their robot profiles), their buses (real or simulated) and norm modes."""

from __future__ import annotations

import contextlib
import os
from collections.abc import Iterator, Mapping
from pathlib import Path
from typing import Any

from ...backends import load_backend
from ...backends.servo_bus import ServoBus
from ...core.lerobot import (
    RobotSpec,
)
from ...errors import UsageError

__all__ = [
    "check_simulated",
    "norm_modes",
    "open_arm",
    "open_bus",
    "open_sim_bus",
    "robot_names",
    "robot_spec",
    "sim_operator",
]


def robot_names() -> tuple[str, ...]:
    """Names of the built-in LeRobot arm profiles (``koch_follower``, ..., ``so101_leader``), sorted."""
    from ...formats.profiles import builtin_lerobot_profiles

    return tuple(p.name for p in builtin_lerobot_profiles())

def robot_spec(robot: str | os.PathLike[str]) -> RobotSpec:
    """The :class:`RobotSpec` of a built-in LeRobot arm (``so101_follower``, ...) or of a profile file.

    Raises:
        UsageError: Neither a built-in LeRobot arm nor a profile file of one.
        FileFormatError: The profile file is malformed.
    """
    from ...formats.profiles import load_profile

    text = os.fspath(robot)
    names = robot_names()
    if text not in names and not (text.endswith((".yaml", ".yml")) and Path(text).is_file()):
        raise UsageError(f"unknown robot {text!r}; valid: {', '.join(names)} (or a robot profile file)")
    return RobotSpec.from_profile(load_profile(text))


def check_simulated(spec: RobotSpec, port: str, flag: str = "--port") -> None:
    """Refuse a simulated port (``sim``, ``sim?...``) for an arm the simulator does not have.

    The simulator's physics are the built-in arms' (their stops and middles, by name); a robot profile file names
    another arm, which works on a real port only.

    Raises:
        UsageError: ``spec`` is not a built-in arm; the message names the ones the simulator has.
    """
    from ...backends.sim.lerobot_arms import DEFAULT_TRUTH

    if spec.name not in DEFAULT_TRUTH:
        raise UsageError(
            f"{flag} {port!r}: the simulator has the built-in arms only ({', '.join(sorted(DEFAULT_TRUTH))}); "
            f"robot {spec.name!r} (a profile file) is not one of them: give one of those to --robot, or the real "
            "arm's port"
        )


def open_bus(
    spec: RobotSpec,
    port: str,
    *,
    retries: int = 3,
    packet_timeout_ms: float | None = 100.0,
    label: str | None = None,
) -> ServoBus:
    """Open the vendor-SDK bus of an arm on ``port`` (a serial port, a simulator's pty or ``inproc://`` port).

    ``label``: how the bus's messages name the port (default ``port``; ``sim`` for a simulated arm).
    """
    motors = {m.motor_id: m.model for m in spec.motors}
    bus: ServoBus = load_backend(spec.vendor_spec.backend)(
        port, motors, retries=retries, packet_timeout_ms=packet_timeout_ms, label=label
    )
    return bus


SIM_PACKET_TIMEOUT_MS = 1000.0
"""The least wait for a status packet from a simulated arm running in this process on a pseudo-terminal
(``--port sim``): not a wire, its reply waits for the simulator's thread, which a starved process may not run for
hundreds of ms (a loaded machine). A real port keeps :func:`open_bus`'s 100 ms; an in-process port
(``inproc://``) answers within the call and keeps it too (its time is the simulated clock's)."""


def open_sim_bus(spec: RobotSpec, arm: Any, label: str = "sim") -> ServoBus:
    """:func:`open_bus` on a simulated arm of this process (a ``SimArm``), with :data:`SIM_PACKET_TIMEOUT_MS`.

    Its messages name the port ``label`` (the port as the user gave it, ``sim``), not the arm's pseudo-terminal or
    in-process name, which the user never gave and which is gone when the command ends.
    """
    pty = getattr(arm.bus, "transport", "pty") == "pty"
    return open_bus(spec, arm.port, packet_timeout_ms=SIM_PACKET_TIMEOUT_MS if pty else 100.0, label=label)


def norm_modes(
    spec: RobotSpec, *, use_degrees: bool | None = None, overrides: Mapping[str, str] | None = None
) -> tuple[str, ...]:
    """LeRobot's norm mode per motor (bus order) for a ``use_degrees`` setting, with per-joint overrides.

    ``use_degrees=None`` keeps LeRobot's default for the robot (SO arms DEGREES since v0.4.4, Koch
    RANGE_M100_100). True: every motor but the gripper in DEGREES; False: RANGE_M100_100. The gripper stays
    RANGE_0_100 (LeRobot refuses DEGREES there). ``overrides`` (motor → mode) win over all of that.

    Raises:
        UsageError: An override names an unknown motor or mode.
    """
    from ...core.lerobot.normalisation import NormMode

    valid = {v.value for v in NormMode}
    over = dict(overrides or {})
    unknown = sorted(set(over) - set(spec.motor_names))
    if unknown:
        raise UsageError(
            f"--modes: unknown motor(s) {', '.join(unknown)} on a {spec.name}; valid: {', '.join(spec.motor_names)}"
        )
    out = []
    for m in spec.motors:
        if m.name in over:
            mode = over[m.name].strip().lower()
            if mode not in valid:
                raise UsageError(
                    f"--modes {m.name}={over[m.name]}: expected one of {', '.join(sorted(valid))}"
                )
        elif use_degrees is None or m.name == "gripper":
            mode = m.norm_mode
        else:
            mode = "degrees" if use_degrees else "range_m100_100"
        out.append(mode)
    return tuple(out)


@contextlib.contextmanager
def open_arm(spec: RobotSpec, port: str, flag: str = "--port") -> Iterator[tuple[ServoBus, Any]]:
    """Open the arm's bus on ``port``; ``sim`` starts a simulated arm first and yields it too.

    ``flag``: the option that gave ``port`` (for the message refusing ``sim`` for an arm the simulator lacks).

    Yields:
        ``(bus, sim_arm)``: the open bus and the :class:`~robocal.backends.sim.lerobot_arms.SimArm` (None on a
        real port). The bus is closed (and the simulated arm stopped) on exit.
    """
    if port == "sim":
        from ...backends.sim.lerobot_arms import SimArm

        check_simulated(spec, port, flag)
        with SimArm(spec) as arm:
            bus = open_sim_bus(spec, arm)
            try:
                yield bus, arm
            finally:
                bus.close()
        return
    bus = open_bus(spec, port)
    try:
        yield bus, None
    finally:
        bus.close()


def sim_operator(arm: Any) -> Any:
    """The simulated operator of a simulated arm (mid pose on request, stop-to-stop sweeps)."""
    from ...backends.sim.lerobot_arms import SimArmOperator

    return SimArmOperator(arm)
