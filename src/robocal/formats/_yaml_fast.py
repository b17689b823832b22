"""A fast path for the plain YAML layout robocal writes, giving exactly what ruamel.yaml's round-trip mode gives.

ruamel.yaml's round-trip parser costs about 0.5 ms per joint, so a calibration of 10⁶ joints took minutes to
read. The files robocal writes (``robocal``, ``lite-yaml``, ``berkeley-offsets``, UR kinematics) use one small
part of YAML: block mappings nested by indentation, plain or simply double-quoted keys, plain numbers and
words, simply double-quoted strings, and one-line flow lists of numbers, with ``#`` comments. :func:`fast_load`
reads exactly that part in one pass over the lines and builds the same ``CommentedMap`` / ``CommentedSeq``
values, with the same line/column records (``.lc``, used for line numbers in messages) and scalar types
(``ScalarFloat`` with its spelling, ``DoubleQuotedScalarString`` keys), deciding each scalar's type with
ruamel's own resolver where it is not a plain decimal number. It returns None for anything else (a tab, a
non-ASCII character, a sequence in block style, an anchor, a tag, a null value, a duplicate key, odd
indentation...), and the caller then uses ruamel, which also gives the error message for a broken file.

:func:`fast_dump` does the same for writing: a mapping of mappings of plain scalars without comments is
written as ruamel writes it; anything else returns None.

The tests check on generated documents that both paths give the same values, types, line records and text.
"""

from __future__ import annotations

import gc
import re
from collections import OrderedDict
from collections.abc import Callable, Mapping
from typing import Any

from ruamel.yaml.comments import Comment, CommentedMap, CommentedSeq, Format, LineCol
from ruamel.yaml.nodes import ScalarNode
from ruamel.yaml.scalarfloat import ScalarFloat
from ruamel.yaml.scalarstring import DoubleQuotedScalarString

from ._json import MAX_INT_DIGITS, decimal_digits

__all__ = ["fast_dump", "fast_load"]

MAX_DEPTH = 16
"""Deeper documents go through ruamel (and the nesting check)."""

_MAX_KEY = 100
"""Longer keys go through ruamel (YAML limits implicit keys to 1024 characters, the emitter to 128)."""

_LINE = re.compile(
    r"( *)"  # indentation
    r'(?:([A-Za-z_][A-Za-z0-9_.\-/]*)|"([ !#-\[\]-~]*)")'  # plain or simply double-quoted key
    r":(?:( +)"
    r'(\[[^\[\]{}#"\']*\]|"[ !#-\[\]-~]*"|(?![-+](?: |$))[A-Za-z0-9_.+\-/~][A-Za-z0-9_.+\-/~ ]*?)'  # value
    r")?(?:( +#.*)| *)"  # an optional comment, trailing spaces
)
_COMMENT = re.compile(r" *(?:#.*)?")
_NUMBER = (
    re.compile(  # an int (not 0: ruamel reads "0" as ScalarInt(width=1)), or a float (.digits, exponent)
        r"-?(?:[1-9][0-9]{0,17}|(?:0|[1-9][0-9]{0,30})(\.[0-9]{1,30})(e[-+]?[0-9]{1,3})?)"
    )
)
_ITEM = re.compile(r"[^,\s]+")


class _Resolver:
    """The resolver (YAML 1.2 tables) and constructors of ruamel, for scalars other than plain decimals.

    :meth:`tag` does what ``VersionedResolver.resolve`` does for a plain scalar.
    """

    def __init__(self) -> None:
        from ._yaml import _yaml  # the same configured YAML object as the slow path

        y = _yaml()
        self._constructor = y.constructor
        table = y.resolver.versioned_resolver  # first character -> [(tag, regexp)]; None: any character
        anywhere = list(table.get(None, []))
        self._by_char = {ch: [*rules, *anywhere] for ch, rules in table.items() if ch is not None}
        self._anywhere = anywhere

    def tag(self, text: str) -> str:
        """The tag ruamel gives the plain scalar ``text`` (non-empty)."""
        for tag, regexp in self._by_char.get(text[0], self._anywhere):
            if regexp.match(text):
                return str(tag)
        return _STR

    def construct(self, text: str) -> Any:
        tag = self.tag(text)
        if tag == _STR:
            return text
        if tag not in _CONSTRUCTED:
            return _NO  # null, timestamps, merge keys...: leave them to ruamel
        if tag == _INT and decimal_digits(text) > MAX_INT_DIGITS:
            return _NO  # refused by ruamel's path (robocal's words, the same on every Python)
        node = ScalarNode(tag, text, None, None, style=None)
        try:
            return self._constructor.yaml_constructors[tag](self._constructor, node)
        except (ValueError, OverflowError):  # e.g. an int of 5000 digits: ruamel reads it and words the error
            return _NO


_STR = "tag:yaml.org,2002:str"
_INT = "tag:yaml.org,2002:int"
_CONSTRUCTED = frozenset({_INT, "tag:yaml.org,2002:float", "tag:yaml.org,2002:bool"})
_NO = object()
_resolver: _Resolver | None = None


def _get_resolver() -> _Resolver:
    global _resolver
    if _resolver is None:
        _resolver = _Resolver()
    return _resolver


def _lead0(mantissa: str) -> int:
    n = 0
    for ch in mantissa:
        if ch == "0":
            n += 1
        elif ch != ".":
            break
    return n


_new_float = float.__new__


def _float(text: str, exponent: str | None) -> ScalarFloat:
    """The round-trip float ruamel gives a plain decimal (``-1.50``, ``2.0e-05``), with its spelling recorded.

    The attributes are those ``RoundTripConstructor.construct_yaml_float`` gives (set directly: the
    constructor's keyword handling costs more than the parse).
    """
    negative = text[0] == "-"
    value = _new_float(ScalarFloat, -float(text[1:]) if negative else float(text))
    mantissa = text[: -len(exponent)] if exponent else text
    attrs = value.__dict__
    attrs["_width"] = len(mantissa) - 1 if negative and exponent else len(mantissa)
    attrs["_prec"] = mantissa.find(".")
    attrs["_m_sign"] = "-" if negative else False
    attrs["_m_lead0"] = _lead0(mantissa)
    attrs["_exp"] = "e" if exponent else None
    attrs["_e_width"] = len(exponent) - 1 if exponent else None
    attrs["_e_sign"] = exponent[1] in "+-" if exponent else None
    attrs["_underscore"] = None
    return value


def _scalar(text: str, res: Callable[[], _Resolver]) -> Any:
    m = _NUMBER.fullmatch(text)
    if m is not None:
        return int(text) if m.group(1) is None else _float(text, m.group(2))
    if text[0] == '"':
        return DoubleQuotedScalarString(text[1:-1])
    return res().construct(text)


def _flow_list(text: str, line: int, col: int, res: Callable[[], _Resolver]) -> CommentedSeq | None:
    """A one-line flow list of numbers (``[1.0, -2, 3.5e-3]``), or None."""
    seq = CommentedSeq()
    seq._yaml_set_line_col(line, col)
    seq.fa.set_flow_style()
    inner = text[1:-1]
    if not inner.strip():
        return None  # ruamel leaves an empty flow list's style unset
    if inner.strip():
        lc = seq.lc
        pos = col + 1
        for i, part in enumerate(inner.split(",")):
            m = _ITEM.search(part)
            if m is None or part[m.end() :].strip() or m.start() != len(part) - len(part.lstrip()):
                return None  # an empty item (a trailing comma) or two words
            value = _scalar(m.group(), res)
            if value is _NO or isinstance(value, (str, bool)):
                return None
            seq.append(value)
            lc.add_kv_line_col(i, [line, pos + m.start()])
            pos += len(part) + 1
    return seq


def _new_map(line: int, col: int) -> tuple[CommentedMap, dict[Any, list[int]]]:
    """A block mapping starting at (line, col), and its (empty) key line/column record."""
    mapping = CommentedMap()
    lc: Any = LineCol()  # what ``_yaml_set_line_col`` and ``fa.set_block_style`` set, without lookups
    lc.line, lc.col = line, col
    lines: dict[Any, list[int]] = {}
    lc.data = lines
    setattr(mapping, LineCol.attrib, lc)
    fmt = Format()
    fmt._flow_style = False
    setattr(mapping, Format.attrib, fmt)
    return mapping, lines


def fast_load(text: str, *, allow_comments: bool = True) -> CommentedMap | None:
    """The document ruamel's round-trip loader gives for ``text``; None: not the plain layout known here.

    None means the caller uses ruamel (which also words the error for a broken file).

    Args:
        text: The YAML text.
        allow_comments: False: return None when the text has a comment (the document is going to be
            written back, and the comments are kept only by ruamel).
    """
    if not text.isascii() or "\x7f" in text or any(ch < " " and ch != "\n" for ch in set(text)):
        return None  # tabs, CR, NUL, controls, non-ASCII: ruamel
    # the document is a tree of new objects (no cycles): the cyclic collector's passes over the growing
    # heap cost ~40 % of the parse, so it is paused (and resumed as it was)
    was_enabled = gc.isenabled()
    gc.disable()
    try:
        return _load(text, allow_comments)
    finally:
        if was_enabled:
            gc.enable()


def _load(text: str, allow_comments: bool) -> CommentedMap | None:
    res = _get_resolver
    keys: dict[str, Any] = {}  # plain key text -> key (resolved once per distinct key)
    root: CommentedMap | None = None
    # stack of (indent, mapping, its line records); `pending`: a key whose nested mapping starts on a later line
    stack: list[tuple[int, CommentedMap, dict[Any, list[int]]]] = []
    pending: tuple[CommentedMap, dict[Any, list[int]], Any, int, int] | None = None
    match_line = _LINE.fullmatch
    setitem = OrderedDict.__setitem__
    all_lines = text.split("\n")
    last = len(all_lines) - 1
    for lineno, raw in enumerate(all_lines):
        m = match_line(raw)
        if m is None:
            if _COMMENT.fullmatch(raw) is None:
                return None
            if not allow_comments and (raw or lineno == 0 or lineno < last):
                return None  # ruamel keeps comments and blank lines (but the end of the last line) for writing
            continue
        indent_s, plain, quoted, gap, value, comment = m.groups()
        if comment is not None and not allow_comments:
            return None
        indent = len(indent_s)
        if pending is not None:
            parent, parent_lines, pkey, pline, pcol = pending
            if indent <= stack[-1][0] or len(stack) >= MAX_DEPTH:
                return None  # `key:` with no value (null) or odd indentation: ruamel decides
            child, child_lines = _new_map(lineno, indent)
            setitem(parent, pkey, child)
            parent._ok.add(pkey)
            parent_lines[pkey] = [pline, pcol, lineno, indent]
            stack.append((indent, child, child_lines))
            pending = None
        elif root is None:
            if indent != 0:
                return None
            root, root_lines = _new_map(lineno, 0)
            stack.append((0, root, root_lines))
        elif indent != stack[-1][0]:
            while stack and stack[-1][0] > indent:
                stack.pop()
            if not stack or stack[-1][0] != indent:
                return None
        _, mapping, lines = stack[-1]
        if plain is not None:
            key = keys.get(plain)
            if key is None:
                if len(plain) > _MAX_KEY:
                    return None
                if res().tag(plain) != _STR:
                    return None  # true:, null: ... keys of other types
                key = plain
                if len(keys) < 100_000:
                    keys[plain] = key
            vcol = indent + len(plain) + 1
        else:
            if len(quoted) > _MAX_KEY:
                return None
            key = DoubleQuotedScalarString(quoted)
            vcol = indent + len(quoted) + 3
        if key in lines:
            return None  # a duplicate key: ruamel words the error
        if value is None:
            lines[key] = []  # placeholder for the duplicate check; filled with the nested mapping
            pending = (mapping, lines, key, lineno, indent)
            continue
        vcol += len(gap)
        if value[0] == "[":
            item: Any = _flow_list(value, lineno, vcol, res)
            if item is None:
                return None
        else:
            item = _scalar(value, res)
            if item is _NO:
                return None
        setitem(mapping, key, item)
        mapping._ok.add(key)
        lines[key] = [lineno, indent, lineno, vcol]
    if pending is not None:
        return None  # a trailing `key:` (null)
    return root


# ------------------------------------------------------------------------------------------------ writing
_PLAIN_OUT = re.compile(r"[A-Za-z_][A-Za-z0-9_]{0,99}")
_QUOTED_OUT = re.compile(r"[A-Za-z0-9_ .\-/]{0,100}")
_YAML11_WORDS = frozenset({"y", "n", "yes", "no", "on", "off", "true", "false", "null"})


def _plain_ok(text: str) -> bool:
    return (
        _PLAIN_OUT.fullmatch(text) is not None
        and text.lower() not in _YAML11_WORDS
        and _get_resolver().tag(text) == "tag:yaml.org,2002:str"
    )


def _no_comments(node: Any) -> bool:
    ca = getattr(node, Comment.attrib, None)  # (``.ca`` would create an empty one)
    if ca is None:
        return True
    return not ca.items and ca.comment is None and not ca.end and not getattr(ca, "pre", None)


def _key_text(key: Any) -> str | None:
    if type(key) is str:
        return key if _plain_ok(key) else None
    if type(key) is DoubleQuotedScalarString and _QUOTED_OUT.fullmatch(key):
        return f'"{key}"'
    return None


def _scalar_text(value: Any, float_text: Callable[[float], str]) -> str | None:
    kind = type(value)
    if kind is bool:
        return "true" if value else "false"
    if kind is int:
        return str(value)
    if kind is float or kind is ScalarFloat:
        return float_text(value)
    if kind is str:
        return value if _plain_ok(value) else None
    if kind is DoubleQuotedScalarString and _QUOTED_OUT.fullmatch(value):
        return f'"{value}"'
    return None


def fast_dump(data: Any, float_text: Callable[[float], str]) -> str | None:
    """The text ruamel's round-trip dumper writes for ``data``; None: not a plain comment-free mapping.

    A plain mapping nests mappings of plain scalars; for anything else the caller uses ruamel.

    Args:
        data: The document.
        float_text: How a float (or a loaded ``ScalarFloat``) is written; the dumper's own rule.
    """
    if not isinstance(data, Mapping) or not data:
        return None
    out: list[str] = []
    return "".join(out) if _dump_mapping(data, 0, out, float_text) else None


def _dump_mapping(
    node: Mapping[Any, Any], depth: int, out: list[str], float_text: Callable[[float], str]
) -> bool:
    if depth >= MAX_DEPTH or not _no_comments(node):
        return False
    anchor = getattr(node, "anchor", None)
    fa = getattr(node, "fa", None)
    if (anchor is not None and anchor.value) or (fa is not None and fa.flow_style() is True):
        return False
    pad = "  " * depth
    for key, value in node.items():
        key_text = _key_text(key)
        if key_text is None:
            return False
        if isinstance(value, Mapping):
            out.append(f"{pad}{key_text}:\n")
            if not value or not _dump_mapping(value, depth + 1, out, float_text):
                return False
            continue
        text = _scalar_text(value, float_text)
        if text is None:
            return False
        out.append(f"{pad}{key_text}: {text}\n")
    return True
