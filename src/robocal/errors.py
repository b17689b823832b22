"""The robocal exception hierarchy.

Every error robocal raises on purpose derives from :class:`CalibError`. Subclasses also derive from the
matching builtin (``ValueError``, ``LookupError``, ``OSError``, ``TimeoutError``, ``ImportError``) so code
that already catches those keeps working. Each class carries the CLI exit code it maps to:

* 2 — bad input or usage (a malformed file, a NaN, a missing joint, a wrong type). Nothing was written.
* 3 — device or communication failure (no reply, a truncated or garbage packet, a timeout).

Messages name the file, joint or field and say what was expected, so the CLI can print them as one
``error:`` line.
"""

from __future__ import annotations

from collections.abc import Sequence

__all__ = [
    "BackendNotAvailableError",
    "CalibError",
    "CalibTimeoutError",
    "DeviceError",
    "DeviceGoneError",
    "FileFormatError",
    "FileWriteError",
    "InvalidCalibrationError",
    "JointMismatchError",
    "JointOutOfRangeError",
    "ProtocolError",
    "ShapeMismatchError",
    "SignalInterrupt",
    "UsageError",
    "check_choice",
]


class CalibError(Exception):
    """Root of every robocal error. ``exit_code`` is what the CLI exits with."""

    exit_code: int = 2


class UsageError(CalibError, ValueError):
    """A command, flag or argument combination that cannot work; fix the invocation."""


def check_choice(flag: str, value: str, valid: Sequence[str]) -> str:
    """``value`` if it is one of ``valid``; else the :class:`UsageError` ``<flag> '<value>'; valid: a, b``.

    Raises:
        UsageError: ``value`` is not in ``valid``.
    """
    if value not in valid:
        raise UsageError(f"{flag} {value!r}; valid: {', '.join(valid)}")
    return value


class InvalidCalibrationError(CalibError, ValueError):
    """A calibration value is impossible (direction not ±1, NaN or inf, scale 0); fix the value."""


class ShapeMismatchError(InvalidCalibrationError):
    """An array does not have the shape the calibration expects (e.g. ``(N,)`` or ``(T, N)``)."""


class JointMismatchError(CalibError, LookupError):
    """Joint names do not line up: a joint is missing, unknown or duplicated. The message lists them."""

    def __str__(self) -> str:  # LookupError would otherwise quote the message like KeyError does
        return str(self.args[0]) if self.args else ""


class JointOutOfRangeError(CalibError, ValueError):
    """A joint value is outside the range the calibration allows (e.g. LeRobot legacy ±270°)."""


class FileFormatError(CalibError, ValueError):
    """A file cannot be parsed or does not follow its format; the message names the file and field."""


class FileWriteError(UsageError):
    """An output file cannot be written; the message names the path and why, and nothing was changed.

    For example its folder is missing or read-only, the disk is full, a name is too long, or the destination
    is a directory.
    """


class BackendNotAvailableError(CalibError, ImportError):
    """An optional dependency is missing; the message names the extra to install."""


class DeviceError(CalibError, OSError):
    """A device or bus failed: no reply, an error status, a port that cannot be opened."""

    exit_code = 3


class ProtocolError(DeviceError):
    """A packet on the wire is truncated, garbled, oversized or of an unexpected type."""


class CalibTimeoutError(DeviceError, TimeoutError):
    """A device did not answer within the timeout; the message names the device."""


class DeviceGoneError(DeviceError):
    """The port itself failed (an unplugged cable, a reset USB adapter): nothing on that bus can be reached."""


class SignalInterrupt(KeyboardInterrupt):
    """SIGTERM or SIGHUP arrived while a command ran (``robocal.cli.entry`` raises it in the main thread).

    It is a ``KeyboardInterrupt``, so every path that makes motors limp and restores registers on Ctrl-C runs
    for ``kill`` and a closed terminal too. ``exit_code`` is the shell's ``128 + signum`` (143, 129).

    The motion guard (``robocal.workflows.motion.guard``) raises it for SIGINT and SIGQUIT too. ``args`` hold only
    what a clean-up added (the motors or registers it could not restore), as for a plain ``KeyboardInterrupt``
    re-raised by a rollback: empty means everything was restored.

    Attributes:
        signum: The signal number.
    """

    def __init__(self, signum: int, *note: object) -> None:
        super().__init__(*note)
        self.signum = int(signum)

    @property
    def exit_code(self) -> int:
        """``128 + signum``."""
        return 128 + self.signum
