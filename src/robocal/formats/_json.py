"""Strict JSON loading shared by the file formats: duplicate keys and NaN/Infinity are refused."""

from __future__ import annotations

import json
from typing import Any

from ..errors import FileFormatError

__all__ = ["load_json"]


def _reject_constant(name: str) -> Any:
    raise ValueError(f"{name} is not valid JSON")


def load_json(text: str, source: str) -> Any:
    """Parse JSON text strictly.

    Raises:
        FileFormatError: Syntax errors (with line and column), duplicate keys, ``NaN`` / ``Infinity``.
    """

    def pairs(items: list[tuple[str, Any]]) -> dict[str, Any]:
        out: dict[str, Any] = {}
        for key, value in items:
            if key in out:
                raise FileFormatError(f"{source}: invalid JSON: duplicate key {key!r}")
            out[key] = value
        return out

    try:
        return json.loads(text, object_pairs_hook=pairs, parse_constant=_reject_constant)
    except json.JSONDecodeError as exc:
        raise FileFormatError(
            f"{source}: invalid JSON (line {exc.lineno}, column {exc.colno}): {exc.msg}"
        ) from None
    except ValueError as exc:
        raise FileFormatError(f"{source}: invalid JSON: {exc}") from None
