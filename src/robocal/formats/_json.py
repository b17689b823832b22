r"""Strict JSON loading shared by the file formats, and the checks every parsed document gets.

Refused, each as a :class:`~robocal.errors.FileFormatError` naming the file (and, where JSON allows, the line):
duplicate keys, ``NaN`` / ``Infinity`` (``file:line: joint 'x': homing_offset is NaN``), documents nested more
than :data:`MAX_NESTING` levels deep (also those too deep for Python's parser), integers of more than
:data:`MAX_INT_DIGITS` digits (worded by robocal, the same on every Python), and strings that are not valid Unicode
(a lone surrogate written as ``\ud800``).
"""

from __future__ import annotations

import json
import re
from collections.abc import Callable, Mapping, Sequence
from typing import Any

from ..errors import FileFormatError

__all__ = [
    "MAX_INT_DIGITS",
    "MAX_NESTING",
    "HugeIntegerError",
    "check_tree",
    "decimal_digits",
    "describe_path",
    "huge_integer_problem",
    "is_valid_unicode",
    "json_int",
    "load_json",
]

MAX_NESTING = 100
"""Deepest nesting of lists and mappings accepted in a JSON or YAML document (robocal's files need < 10)."""

MAX_INT_DIGITS = 4300
"""Most decimal digits of an integer read from a JSON or YAML document.

Python itself refuses to convert longer digit strings (its ``sys.get_int_max_str_digits()``, 4300 by default,
absent before 3.10.7 and 3.11) with a message that differs between versions and asks to change Python's settings;
robocal refuses them first, in its own words, on every Python."""


def decimal_digits(token: str) -> int:
    """Decimal digits of an integer token (``-123`` → 3; ``1_000`` → 4); 0 for a token that is not decimal."""
    body = token.lstrip("+-").replace("_", "")
    return len(body) if body.isdigit() and body.isascii() else 0


def huge_integer_problem(digits: int) -> str:
    """The words for an integer of ``digits`` digits (more than :data:`MAX_INT_DIGITS`)."""
    return f"an integer of {digits} digits; robocal reads integers of at most {MAX_INT_DIGITS} digits"


class HugeIntegerError(ValueError):
    """:func:`json_int` refused an integer token of more than :data:`MAX_INT_DIGITS` digits."""

    def __init__(self, token: str) -> None:
        self.token = token
        super().__init__(huge_integer_problem(decimal_digits(token)))


def json_int(token: str) -> int:
    """``int(token)`` for ``json.loads(parse_int=...)``, refusing more than :data:`MAX_INT_DIGITS` digits.

    Raises:
        HugeIntegerError: The token has more digits (a ``ValueError``, as Python's own refusal is).
    """
    if decimal_digits(token) > MAX_INT_DIGITS:
        raise HugeIntegerError(token)
    return int(token)

# a JSON string, or a NaN / Infinity constant outside strings (in document order)
_TOKENS = re.compile(r'"(?:[^"\\]|\\.)*"|-?Infinity|NaN', re.DOTALL)


class _Constant(float):
    """A NaN / Infinity read from JSON, remembered so the walk can report where it was."""

    name: str


def _constant(name: str) -> _Constant:
    value = _Constant({"NaN": "nan", "Infinity": "inf", "-Infinity": "-inf"}[name])
    value.name = name
    return value


def describe_path(path: Sequence[Any], item: str) -> str:
    """``("j1", "homing_offset")`` → ``"joint 'j1': homing_offset"`` (``item`` names the top-level entries).

    Keys below the first are joined with ``.``; list indices are written ``[i]``.
    """
    if not path:
        return "the document"
    head = path[0]
    text = f"{item} {head!r}" if isinstance(head, str) else f"{item} [{head}]"
    rest = "".join(f"[{k}]" if isinstance(k, int) else f".{k}" for k in path[1:]).lstrip(".")
    return f"{text}: {rest}" if rest else text


def is_valid_unicode(s: str) -> bool:
    """False when ``s`` holds a lone surrogate (it cannot be written as UTF-8 or shown on a terminal)."""
    if s.isascii():
        return True
    try:
        s.encode("utf-8")
    except UnicodeEncodeError:
        return False
    return True


def _bad_unicode(s: str) -> bool:
    return not is_valid_unicode(s)


def check_tree(
    data: Any,
    source: str,
    *,
    item: str = "key",
    line_of: Callable[[Sequence[Any]], int | None] | None = None,
    constants: Sequence[int] | None = None,
    text: str | None = None,
) -> None:
    """Walk a parsed document (iteratively) and refuse what no robocal file may hold.

    Args:
        data: The parsed document (dicts, lists, scalars).
        source: File name for messages.
        item: What the top-level keys are (``"joint"``, ``"motor"``), for messages.
        line_of: Returns the 1-based line of a key path, when the parser kept lines (YAML).
        constants: Offsets in ``text`` of the JSON ``NaN`` / ``Infinity`` tokens, in document order.
        text: The document's text (for line numbers of ``constants``).

    Raises:
        FileFormatError: Nested deeper than :data:`MAX_NESTING`, a string or key that is not valid Unicode,
            or a JSON ``NaN`` / ``Infinity``; the message names the file, line where known, and key path.
    """

    def where(path: Sequence[Any]) -> str:
        line = line_of(path) if line_of is not None else None
        return f"{source}:{line}" if line is not None else source

    seen_constants = 0
    stack: list[tuple[Any, tuple[Any, ...]]] = [(data, ())]
    while stack:
        node, path = stack.pop()
        if len(path) > MAX_NESTING:
            raise FileFormatError(f"{source}: nested more than {MAX_NESTING} levels deep; not a robocal file")
        if isinstance(node, Mapping):
            children = list(node.items())
            for key, _ in children:
                if isinstance(key, str) and _bad_unicode(key):
                    what = f"{item} name {key!a}" if not path else f"{describe_path(path, item)}: key {key!a}"
                    raise FileFormatError(
                        f"{where((*path, key))}: {what} is not valid Unicode (a lone surrogate)"
                    )
            stack.extend(((v, (*path, k)) for k, v in reversed(children)))
        elif isinstance(node, list | tuple):
            stack.extend(((v, (*path, i)) for i, v in reversed(list(enumerate(node)))))
        elif isinstance(node, str):
            if _bad_unicode(node):
                raise FileFormatError(
                    f"{where(path)}: {describe_path(path, item)}: the text {node!a} is not valid Unicode "
                    "(a lone surrogate)"
                )
        elif isinstance(node, _Constant):
            line = None
            if constants is not None and text is not None and seen_constants < len(constants):
                line = text.count("\n", 0, constants[seen_constants]) + 1
            seen_constants += 1
            at = f"{source}:{line}" if line is not None else source
            raise FileFormatError(
                f"{at}: {describe_path(path, item)} is {node.name}; JSON has no NaN or Infinity, "
                "expected a finite number"
            )


def load_json(text: str, source: str, *, item: str = "key", strict: bool = True) -> Any:
    """Parse JSON text strictly and check the result with :func:`check_tree`.

    Args:
        text: The JSON document.
        source: File name for messages.
        item: What the top-level keys are (``"joint"``, ``"motor"``), for messages.
        strict: Refuse duplicate keys, ``NaN`` / ``Infinity`` and numbers too large for a float (``1e999``)
            (``False`` accepts them, like Python's ``json``; depth and Unicode are always checked).

    Raises:
        FileFormatError: Syntax errors (with line and column), duplicate keys, ``NaN`` / ``Infinity`` (with
            line and key path), nesting deeper than :data:`MAX_NESTING`, integers of more than
            :data:`MAX_INT_DIGITS` digits (with line and column), lone surrogates.
    """

    def number(text: str) -> float:
        value = float(text)
        if value in (float("inf"), float("-inf")):
            raise FileFormatError(
                f"{source}: invalid JSON: the number {text[:40]} is beyond the range of a float (it reads as "
                "infinity); expected a finite number"
            )
        return value

    def pairs(items: list[tuple[str, Any]]) -> dict[str, Any]:
        out: dict[str, Any] = {}
        for key, value in items:
            if key in out:
                raise FileFormatError(f"{source}: invalid JSON: duplicate key {key!r}")
            out[key] = value
        return out

    try:
        if strict:
            data = json.loads(
                text, object_pairs_hook=pairs, parse_constant=_constant, parse_float=number, parse_int=json_int
            )
        else:
            data = json.loads(text, parse_int=json_int)
    except HugeIntegerError as exc:
        at = text.find(exc.token)
        line = text.count("\n", 0, at) + 1
        column = at - text.rfind("\n", 0, at)
        raise FileFormatError(f"{source}: invalid JSON (line {line}, column {column}): {exc}") from None
    except json.JSONDecodeError as exc:
        raise FileFormatError(
            f"{source}: invalid JSON (line {exc.lineno}, column {exc.colno}): {exc.msg}"
        ) from None
    except RecursionError:
        raise FileFormatError(
            f"{source}: nested more than {MAX_NESTING} levels deep; not a robocal file"
        ) from None
    except FileFormatError:  # from the hooks (duplicate key, a number beyond a float): already worded
        raise
    except ValueError as exc:  # e.g. an integer with more digits than Python converts
        raise FileFormatError(f"{source}: invalid JSON: {exc}") from None
    constants: list[int] | None = None
    if strict and ("NaN" in text or "Infinity" in text):
        constants = [m.start() for m in _TOKENS.finditer(text) if m.group()[0] != '"']
    check_tree(data, source, item=item, constants=constants, text=text)
    return data
