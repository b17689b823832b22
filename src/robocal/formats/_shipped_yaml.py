"""A quick reader for the layout of the robot profiles shipped with robocal (``robocal/data/profiles``).

Recognising a robot from a URDF reads every built-in profile, which took ruamel.yaml's round-trip parser about
0.2 s of CPU per process (12 files of block sequences of one-line flow mappings with long comments). The shipped
files use a small part of YAML: ``#`` comment lines (any text), block mappings nested by indentation, block
sequences whose items are one-line flow mappings (``- {name: a, id: 1, pose: {b: 0}}``), one-line flow lists
(``[a, b]``), plain scalars and simple double-quoted strings. :func:`load_shipped` reads exactly that into plain
``dict`` / ``list`` / ``str`` / ``int`` / ``float`` / ``bool`` values and returns None for anything else (a trailing
comment, a null, ``yes``, an escape, a tab...); the caller then reads the file with the full reader.

Only the shipped files come here: a user's profile file always goes through :func:`robocal.formats._yaml.load_yaml`
(its errors, its line numbers). ``tests/foundation/test_shipped_profiles.py`` checks that every shipped profile
reads to the same document and the same :class:`~robocal.core.profile.RobotProfile` both ways, and that each one
takes this path.
"""

from __future__ import annotations

import re
from typing import Any

__all__ = ["load_shipped"]

_KEY_LINE = re.compile(r"( *)([A-Za-z_][A-Za-z0-9_]*):(?: (.*))?")
_ITEM_LINE = re.compile(r"( *)- (\{.*\})")
_INT = re.compile(r"-?(?:0|[1-9][0-9]{0,17})")
_HEX = re.compile(r"0x[0-9a-fA-F]{1,16}")
_FLOAT = re.compile(r"-?(?:0|[1-9][0-9]{0,17})\.[0-9]{1,17}")
_FLOW_WORD = re.compile(r"[A-Za-z_/(][^:#\"'\[\]{},]*")  # text in a flow collection (checked further below)
_BLOCK_WORD = re.compile(r"[A-Za-z_/(][^\t]*")  # text after `key: ` (no ': ' or ' #', checked below)
_FLOW_TOKEN = re.compile(
    r'\s*(?:([{}\[\],])|"([^"\\]*)"|([A-Za-z0-9_.+\-/][^:,\[\]{}#"\']*?)\s*(:(?= )|(?=[,}\]])))'
)
_SPECIAL = frozenset({"null", "true", "false", "yes", "no", "on", "off", "y", "n"})


class _NotShippedLayoutError(Exception):
    """Not the shipped layout: the full reader decides."""


def _scalar(text: str, word: re.Pattern[str] = _FLOW_WORD) -> Any:
    """A plain scalar as YAML 1.2 (ruamel.yaml) reads it; refused where that is not plainly text or a number."""
    if text in ("true", "false"):
        return text == "true"
    if _INT.fullmatch(text):
        return int(text)
    if _HEX.fullmatch(text):
        return int(text, 16)
    if _FLOAT.fullmatch(text):
        return float(text)
    if not word.fullmatch(text) or text.lower() in _SPECIAL or text != text.strip() or text.endswith(":"):
        raise _NotShippedLayoutError(text)
    return text


def _block_value(text: str) -> Any:
    if text[:1] in ("{", "["):
        return _flow(text)
    if text[:1] == '"':
        if len(text) < 2 or not text.endswith('"') or '"' in text[1:-1] or "\\" in text:
            raise _NotShippedLayoutError(text)
        return text[1:-1]
    if " #" in text or ": " in text:
        raise _NotShippedLayoutError(text)
    return _scalar(text, _BLOCK_WORD)


def _flow(text: str) -> Any:
    """A one-line flow mapping or list of plain scalars, quoted strings and nested flow collections."""
    tokens: list[tuple[str, str]] = []
    pos = 0
    while pos < len(text):
        m = _FLOW_TOKEN.match(text, pos)
        if m is None or m.end() == pos:
            raise _NotShippedLayoutError(text)
        punct, quoted, plain, colon = m.groups()
        if punct is not None:
            tokens.append(("p", punct))
        elif quoted is not None:
            tokens.append(("s", quoted))
        else:
            tokens.append(("k" if colon else "v", plain))
        pos = m.end()
        while pos < len(text) and text[pos] == " ":
            pos += 1
    value, end = _flow_node(tokens, 0)
    if end != len(tokens):
        raise _NotShippedLayoutError(text)
    return value


def _flow_node(tokens: list[tuple[str, str]], i: int) -> tuple[Any, int]:
    if i >= len(tokens):
        raise _NotShippedLayoutError("end of line")
    kind, text = tokens[i]
    if kind == "v":
        return _scalar(text), i + 1
    if kind == "s":
        return text, i + 1
    if (kind, text) == ("p", "{"):
        mapping: dict[str, Any] = {}
        i += 1
        while tokens[i : i + 1] != [("p", "}")]:
            if i >= len(tokens) or tokens[i][0] != "k" or tokens[i][1] in mapping or tokens[i][1] in _SPECIAL:
                raise _NotShippedLayoutError("flow key")
            key = tokens[i][1]
            mapping[key], i = _flow_node(tokens, i + 1)
            if tokens[i : i + 1] == [("p", ",")] and tokens[i + 1 : i + 2] != [("p", "}")]:
                i += 1
            elif tokens[i : i + 1] != [("p", "}")]:
                raise _NotShippedLayoutError("flow mapping")
        return mapping, i + 1
    if (kind, text) == ("p", "["):
        items: list[Any] = []
        i += 1
        while tokens[i : i + 1] != [("p", "]")]:
            item, i = _flow_node(tokens, i)
            items.append(item)
            if tokens[i : i + 1] == [("p", ",")] and tokens[i + 1 : i + 2] != [("p", "]")]:
                i += 1
            elif tokens[i : i + 1] != [("p", "]")]:
                raise _NotShippedLayoutError("flow list")
        return items, i + 1
    raise _NotShippedLayoutError(text)


def load_shipped(text: str) -> dict[str, Any] | None:
    """The document of a shipped profile's text; None: not the shipped layout (read it with the full reader)."""
    try:
        return _load(text)
    except (_NotShippedLayoutError, IndexError):
        return None


def _load(text: str) -> dict[str, Any]:
    lines = [ln for ln in text.split("\n") if ln.strip() and not ln.lstrip().startswith("#")]
    if any("\t" in ln or "\r" in ln for ln in lines):
        raise _NotShippedLayoutError("tab or carriage return")
    root: dict[str, Any] = {}
    # open containers: (indent of their entries, the container); a `key:` opens one at the next line's indent
    stack: list[tuple[int, Any]] = [(0, root)]
    pending: tuple[dict[str, Any], str, int] | None = None
    for line in lines:
        indent = len(line) - len(line.lstrip(" "))
        if pending is not None:
            parent, key, parent_indent = pending
            if indent <= parent_indent:
                raise _NotShippedLayoutError("a key without a value (null)")
            parent[key] = [] if line.lstrip().startswith("- ") else {}
            stack.append((indent, parent[key]))
            pending = None
        while stack and stack[-1][0] > indent:
            stack.pop()
        if not stack or stack[-1][0] != indent:
            raise _NotShippedLayoutError("indentation")
        container = stack[-1][1]
        item = _ITEM_LINE.fullmatch(line)
        if item is not None:
            if not isinstance(container, list):
                raise _NotShippedLayoutError("a sequence item in a mapping")
            container.append(_flow(item.group(2)))
            continue
        m = _KEY_LINE.fullmatch(line)
        if m is None or not isinstance(container, dict) or m.group(2) in container or m.group(2) in _SPECIAL:
            raise _NotShippedLayoutError(line)
        key, value = m.group(2), m.group(3)
        if value is None or not value.strip():
            if value:  # `key: ` with trailing spaces: leave it to the full reader
                raise _NotShippedLayoutError(line)
            pending = (container, key, indent)
            continue
        container[key] = _block_value(value)
    if pending is not None or not root:
        raise _NotShippedLayoutError("a key without a value (null) at the end")
    return root
