"""Number parsing and formatting shared by the file formats."""

from __future__ import annotations

import math
from typing import Any

from ..errors import FileFormatError

__all__ = [
    "MAX_MOTOR_ID",
    "format_float",
    "parse_direction",
    "parse_finite",
    "parse_int",
    "parse_motor_id",
    "shown",
]

MAX_MOTOR_ID = (1 << 29) - 1
"""Largest motor id any supported bus can address (a 29-bit extended CAN identifier); servo ids are far smaller."""


def format_float(x: float) -> str:
    """Shortest string that reads back as the same float; never ``-0`` (written as ``0.0``)."""
    v = float(x)
    if v == 0.0:
        return "0.0"
    return repr(v)


def _digits(value: int) -> int:
    """Decimal digits of ``value`` (without converting it to a string, which Python limits to 4300 digits)."""
    try:
        return len(str(abs(value)))
    except ValueError:
        return int(abs(value).bit_length() * math.log10(2)) + 1


def shown(value: Any, limit: int = 40) -> str:
    """``repr(value)`` cut to ``limit`` characters, for error messages about values a file may make huge."""
    if isinstance(value, int) and not isinstance(value, bool) and value.bit_length() > 128:
        return f"<an integer of {_digits(value)} digits>"
    text = repr(value)
    return text if len(text) <= limit else f"{text[: limit - 1]}…"


def parse_finite(value: Any, where: str, field: str) -> float:
    """A finite float from a number or numeric string, else :class:`FileFormatError` naming ``where.field``."""
    if isinstance(value, bool) or value is None:
        raise FileFormatError(f"{where}: {field} is {value!r}; expected a number")
    if isinstance(value, str):
        try:
            v = float(value.strip())
        except ValueError:
            raise FileFormatError(f"{where}: {field} {shown(value)} is not a number") from None
    elif isinstance(value, int):
        try:
            v = float(value)
        except OverflowError:
            raise FileFormatError(
                f"{where}: {field} is an integer of {_digits(value)} digits; expected a finite number"
            ) from None
    elif isinstance(value, float):
        v = float(value)
    else:
        raise FileFormatError(f"{where}: {field} has type {type(value).__name__}; expected a number")
    if not math.isfinite(v):
        raise FileFormatError(f"{where}: {field} is {v}; expected a finite number")
    return v


def parse_int(value: Any, where: str, field: str) -> int:
    """An integer from an int, an integral float or an integer string."""
    if isinstance(value, bool) or value is None:
        raise FileFormatError(f"{where}: {field} is {value!r}; expected an integer")
    if isinstance(value, int):
        return int(value)
    if isinstance(value, float):
        if value.is_integer():
            return int(value)
        raise FileFormatError(f"{where}: {field} {shown(value)} is not an integer")
    if isinstance(value, str):
        text = value.strip()
        try:
            return int(text, 10) if text.lstrip("+-").isdigit() else int(text, 0)  # "011" is 11; "0x1B" hex
        except ValueError:
            raise FileFormatError(f"{where}: {field} {shown(value)} is not an integer") from None
    raise FileFormatError(f"{where}: {field} has type {type(value).__name__}; expected an integer")


def parse_motor_id(value: Any, where: str, field: str = "id") -> int:
    """A motor / CAN id: an integer from 0 to :data:`MAX_MOTOR_ID`, else :class:`FileFormatError`."""
    motor_id = parse_int(value, where, field)
    if not 0 <= motor_id <= MAX_MOTOR_ID:
        raise FileFormatError(
            f"{where}: {field} {shown(motor_id)} is out of range; expected a motor id from 0 to {MAX_MOTOR_ID}"
        )
    return motor_id


def parse_direction(value: Any, where: str) -> int:
    """A direction, −1 or +1 (ints, integral floats or strings), else :class:`FileFormatError`."""
    if isinstance(value, bool) or value is None:
        raise FileFormatError(f"{where}: direction is {value!r}; expected -1 or 1")
    try:
        v = float(value.strip()) if isinstance(value, str) else float(value)
    except OverflowError:
        raise FileFormatError(f"{where}: direction {shown(value)} is invalid; expected -1 or 1") from None
    except (TypeError, ValueError):
        raise FileFormatError(
            f"{where}: direction {shown(value)} is not a number; expected -1 or 1"
        ) from None
    if v not in (-1.0, 1.0):
        raise FileFormatError(f"{where}: direction {shown(value)} is invalid; expected -1 or 1")
    return int(v)
