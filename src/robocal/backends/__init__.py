"""Hardware, recordings and simulators, behind small protocols.

Backends are looked up by name through :data:`BACKENDS`, a registry of lazy imports (module path, attribute),
extended by the ``robocal.backends`` entry-point group, so an optional dependency that is not installed gives a
clear :class:`~robocal.errors.BackendNotAvailableError` naming the extra to install instead of an ImportError at
start-up. :func:`load_backend` is the one way robocal picks a bus or client class: the ``--source`` sources
(Robstride, live and simulated), the LeRobot workflow (Feetech or Dynamixel by the robot's vendor) and the UR
workflows (primary interface, RTDE) all go through it.
"""

from __future__ import annotations

import importlib
import math
import os
from importlib.metadata import entry_points
from typing import TYPE_CHECKING, Any, Literal, overload

if TYPE_CHECKING:
    from .damiao.bus import DamiaoBus
    from .dynamixel import DynamixelBus
    from .feetech import FeetechBus
    from .robstride import RobstrideBus
    from .ur_primary import PrimaryClient
    from .ur_rtde_client import RtdeReceiveClient

from ..errors import BackendNotAvailableError, UsageError

__all__ = [
    "BACKENDS",
    "EXTRAS",
    "REPLY_TIMEOUT_ENV",
    "list_backends",
    "load_backend",
    "reply_timeout_floor_s",
    "require",
]

BACKENDS: dict[str, tuple[str, str]] = {
    "robstride": ("robocal.backends.robstride", "RobstrideBus"),
    "feetech": ("robocal.backends.feetech", "FeetechBus"),
    "dynamixel": ("robocal.backends.dynamixel", "DynamixelBus"),
    "ur_primary": ("robocal.backends.ur_primary", "PrimaryClient"),
    "ur_rtde": ("robocal.backends.ur_rtde_client", "RtdeReceiveClient"),
    "damiao": ("robocal.backends.damiao.bus", "DamiaoBus"),
    "robstride.joint_driver": ("robocal.backends.robstride.joint_driver", "RobstrideJointDriver"),
    "feetech.joint_driver": ("robocal.backends.feetech.joint_driver", "FeetechJointDriver"),
    "dynamixel.joint_driver": ("robocal.backends.dynamixel.joint_driver", "DynamixelJointDriver"),
    "damiao.joint_driver": ("robocal.backends.damiao.joint_driver", "DamiaoJointDriver"),
    "damiao.source": ("robocal.backends.sources.damiao", "DamiaoSource"),
    "feetech.position_loop": ("robocal.backends.feetech.gains", "POSITION_LOOP"),
    "dynamixel.position_loop": ("robocal.backends.dynamixel.gains", "POSITION_LOOP"),
}
"""Backend name → (module, attribute). Extended by the ``robocal.backends`` entry points."""

EXTRAS: dict[str, str] = {
    "can": "robstride",
    "scservo_sdk": "feetech",
    "dynamixel_sdk": "dynamixel",
    "serial": "feetech",
    "rosbags": "ros",
    "matplotlib": "plot",
    "pyarrow": "dataset",
}
"""Top-level module of an optional dependency → the robocal extra that installs it."""

REPLY_TIMEOUT_ENV = "ROBOCAL_REPLY_TIMEOUT_MS"
"""Environment variable: the least time, ms, to wait for a device's reply (see :func:`reply_timeout_floor_s`)."""


def reply_timeout_floor_s() -> float:
    """The least time to wait for each reply of a device, s: ``$ROBOCAL_REPLY_TIMEOUT_MS`` / 1000 (0 when unset).

    Servo status packets (Feetech, Dynamixel) and Robstride CAN replies are waited for at least this long, and
    each bus's own timeout still applies when it is longer. For a slow USB adapter, or a simulator running as
    another process on a loaded machine (``robocal sim``), whose answers can come later than a motor's.

    Raises:
        UsageError: The variable is set to something other than a number of milliseconds in 0..600000.
    """
    text = os.environ.get(REPLY_TIMEOUT_ENV, "").strip()
    if not text:
        return 0.0
    try:
        ms = float(text)
    except ValueError:
        ms = math.nan
    if not 0 <= ms <= 600_000:
        raise UsageError(f"{REPLY_TIMEOUT_ENV}={text!r}: expected a number of ms from 0 to 600000")
    return ms / 1000.0


def require(module: str, purpose: str, *, message: str | None = None) -> Any:
    """Import an optional dependency or raise :class:`BackendNotAvailableError` naming the extra.

    Args:
        module: Module to import, e.g. ``"can"``.
        purpose: What it is needed for, used in the message (e.g. ``"the Robstride CAN backend"``).
        message: The whole error message instead of the one built from ``purpose`` (for a package whose
            pip name differs from its module's).

    Returns:
        The imported module.
    """
    try:
        return importlib.import_module(module)
    except ImportError:
        extra = EXTRAS.get(module.split(".")[0], "all")
        raise BackendNotAvailableError(
            message or f"{purpose} needs the Python package {module!r}: pip install 'robocal[{extra}]'"
        ) from None


def _registry() -> dict[str, tuple[str, str]]:
    reg = dict(BACKENDS)
    for ep in entry_points(group="robocal.backends"):
        module, _, attr = ep.value.partition(":")
        reg.setdefault(ep.name, (module, attr))
    return reg


def list_backends() -> list[str]:
    """Names of every registered backend (built-in and entry points), sorted."""
    return sorted(_registry())


@overload
def load_backend(name: Literal["robstride"]) -> type[RobstrideBus]: ...
@overload
def load_backend(name: Literal["feetech"]) -> type[FeetechBus]: ...
@overload
def load_backend(name: Literal["dynamixel"]) -> type[DynamixelBus]: ...
@overload
def load_backend(name: Literal["ur_primary"]) -> type[PrimaryClient]: ...
@overload
def load_backend(name: Literal["ur_rtde"]) -> type[RtdeReceiveClient]: ...
@overload
def load_backend(name: Literal["damiao"]) -> type[DamiaoBus]: ...
@overload
def load_backend(name: str) -> Any: ...


def load_backend(name: str) -> Any:
    """Import and return the backend class registered as ``name``.

    Raises:
        UsageError: No backend has that name (the message lists the valid names).
        BackendNotAvailableError: The backend's optional dependency is missing.
    """
    reg = _registry()
    if name not in reg:
        raise UsageError(f"unknown backend {name!r}; valid: {', '.join(sorted(reg))}")
    module, attr = reg[name]
    try:
        mod = importlib.import_module(module)
    except ImportError as exc:
        missing = (exc.name or "").split(".")[0]
        if missing.startswith("robocal"):
            raise
        extra = EXTRAS.get(missing, "all")
        raise BackendNotAvailableError(
            f"backend {name!r} needs the Python package {missing!r}: pip install 'robocal[{extra}]'"
        ) from None
    return getattr(mod, attr)
