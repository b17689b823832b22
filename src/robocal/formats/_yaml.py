"""The one place robocal talks to ruamel.yaml.

Round-trip mode keeps comments, key order and flow style when a file is updated in place. Floats are written
shortest-round-trip with a decimal point (``1.0e-20``, not ``1e-20``) so YAML 1.1 readers such as PyYAML also
read them as floats; ``-0.0`` is written as ``0.0``.
"""

from __future__ import annotations

import io
import re
import warnings
from collections.abc import Callable, Mapping, Sequence
from typing import Any

from ruamel.yaml import YAML
from ruamel.yaml.composer import Composer, ComposerError
from ruamel.yaml.error import YAMLError, YAMLWarning
from ruamel.yaml.events import AliasEvent
from ruamel.yaml.nodes import MappingNode, ScalarNode, SequenceNode
from ruamel.yaml.representer import RoundTripRepresenter
from ruamel.yaml.scalarfloat import ScalarFloat

from ..errors import FileFormatError
from ._json import MAX_INT_DIGITS, MAX_NESTING, check_tree, decimal_digits, huge_integer_problem
from ._yaml_fast import fast_dump, fast_load

__all__ = ["dump_yaml", "load_yaml", "yaml_float"]


def yaml_float(x: float) -> str:
    """YAML text of a float: shortest round trip, always with a ``.``, never ``-0``, ``.nan``/``.inf`` kept."""
    v = float(x)
    if v != v:
        return ".nan"
    if v in (float("inf"), float("-inf")):
        return ".inf" if v > 0 else "-.inf"
    if v == 0.0:
        return "0.0"
    text = repr(v)
    if "e" in text:
        mant, exp = text.split("e")
        if "." not in mant:
            mant += ".0"
        text = f"{mant}e{exp}"
    return text


def _represent_float(representer: Any, data: float) -> Any:
    return representer.represent_scalar("tag:yaml.org,2002:float", yaml_float(data))


def _represent_scalar_float(representer: Any, data: Any) -> Any:
    """Keep a loaded float's original spelling when it reads back exactly; otherwise write it exactly."""
    node = RoundTripRepresenter.represent_scalar_float(representer, data)
    text = str(node.value)
    try:
        exact = float(text.replace("_", "")) == float(data)
    except ValueError:
        exact = False
    # ruamel re-renders from the value; keep its spelling (e.g. "0.50") unless it is inexact or needlessly long
    # (exponent forms are re-rendered with ruamel's own digits, so those are written shortest-round-trip)
    keep = exact and "e" not in text.lower() and len(text) <= len(yaml_float(float(data))) + 3
    return node if keep else _represent_float(representer, float(data))


_STR_TAG = "tag:yaml.org,2002:str"
_INT_TAG = "tag:yaml.org,2002:int"
_KEY_KINDS = {
    "tag:yaml.org,2002:int": "a number",
    "tag:yaml.org,2002:float": "a number",
    "tag:yaml.org,2002:bool": "true/false",
    "tag:yaml.org,2002:null": "null",
    "tag:yaml.org,2002:timestamp": "a date",
}


class _PlainComposer(Composer):
    """ruamel's composer, refusing what no robocal file holds, at its line and column.

    Refused: anchors (``&a``), aliases (``*a``) and merge keys (``<<: *a``), which make two entries one shared
    object (an update in place would change both); explicit tags (``!!binary``, ``!!python/object``, ``!foo``);
    keys that are not text (a mapping or sequence used as a key, ``1:``, ``null:``, ``true:``); dates
    (``2001-12-14``), which no reader expects; and integers of more than
    :data:`~robocal.formats._json.MAX_INT_DIGITS` digits. Each is a ``ComposerError``, worded by
    :func:`load_yaml_ruamel`.
    """

    def compose_node(self, parent: Any, index: Any) -> Any:
        event = self.parser.peek_event()
        if isinstance(event, AliasEvent):
            self._refuse(f"an alias (*{event.anchor}); anchors and aliases are not allowed in robocal files", event)
        if event.anchor is not None:
            self._refuse(f"an anchor (&{event.anchor}); anchors and aliases are not allowed in robocal files", event)
        tag = getattr(event, "tag", None)
        if tag is not None:
            shown = str(tag).replace("tag:yaml.org,2002:", "!!")
            self._refuse(f"a tag ({shown}); tags are not allowed in robocal files", event)
        node = super().compose_node(parent, index)
        if isinstance(parent, MappingNode) and index is None:  # a key
            self._check_key(node)
        elif isinstance(node, ScalarNode) and str(node.tag) == "tag:yaml.org,2002:timestamp":
            self._refuse(f"the date {node.value!r}; expected a number or text (quote it if it is a name)", node)
        elif isinstance(node, ScalarNode) and str(node.tag) == _INT_TAG:
            digits = decimal_digits(node.value)
            if digits > MAX_INT_DIGITS:  # before Python's own refusal, whose words differ between versions
                self._refuse(huge_integer_problem(digits), node)
        return node

    def _check_key(self, node: Any) -> None:
        if isinstance(node, MappingNode | SequenceNode):
            what = "mapping" if isinstance(node, MappingNode) else "sequence"
            self._refuse(f"a {what} used as a key (a complex key); keys must be names", node)
        tag = str(node.tag)
        if tag == "tag:yaml.org,2002:merge":
            self._refuse("a merge key (<<); merge keys are not allowed in robocal files", node)
        if tag != _STR_TAG:
            kind = _KEY_KINDS.get(tag, tag)
            self._refuse(
                f"the key {node.value!r} is {kind}, not a name; quote it (\"{node.value}\") if it is a name", node
            )

    @staticmethod
    def _refuse(problem: str, at: Any) -> None:
        raise ComposerError(None, None, problem, at.start_mark)


def _yaml() -> YAML:
    y = YAML(typ="rt")
    y.Composer = _PlainComposer
    y.preserve_quotes = True
    y.indent(mapping=2, sequence=4, offset=2)
    y.width = 4096
    y.allow_duplicate_keys = False
    y.representer.add_representer(float, _represent_float)
    y.representer.add_representer(ScalarFloat, _represent_scalar_float)
    return y


_FLOW_TOKENS = re.compile(r'"(?:[^"\\\n]|\\.)*"|\'(?:[^\'\n]|\'\')*\'|(?<!\S)#[^\n]*|[\[\]{}]')


def _flow_depth(text: str) -> int:
    """Deepest nesting of flow collections (``[`` / ``{``) outside quotes and comments (a quick guard)."""
    if text.count("[") + text.count("{") <= MAX_NESTING:
        return 0
    depth = deepest = 0
    for m in _FLOW_TOKENS.finditer(text):
        c = m.group()
        if c in "[{":
            depth += 1
            deepest = max(deepest, depth)
        elif c in "]}":
            depth = max(depth - 1, 0)
    return deepest


def _line_of(data: Any) -> Callable[[Sequence[Any]], int | None]:
    """The 1-based line of a key path in a round-trip document (ruamel keeps them in ``.lc``)."""

    def line(path: Sequence[Any]) -> int | None:
        node = data
        found: int | None = None
        try:
            for key in path:
                lc = getattr(node, "lc", None)
                if lc is not None:
                    pos = lc.key(key) if isinstance(node, Mapping) else lc.item(key)
                    found = int(pos[0]) + 1
                node = node[key]
        except (KeyError, IndexError, TypeError, AttributeError):
            pass
        return found

    return line


def load_yaml(text: str, source: str, *, item: str = "key", round_trip: bool = False) -> Any:
    """Parse YAML text (round-trip types: ``CommentedMap`` / ``CommentedSeq``).

    The plain block layout robocal writes is read by :func:`~._yaml_fast.fast_load` (the same values, types
    and line records as ruamel.yaml gives, about 50× faster); anything else by ruamel.yaml.

    Args:
        text: The YAML document.
        source: File name for messages.
        item: What the top-level keys are (``"joint"``), for messages.
        round_trip: The document will be written back (:func:`dump_yaml`): its comments must be kept, so a
            document with comments is read by ruamel.yaml.

    Raises:
        FileFormatError: Syntax errors or duplicate keys, naming the file and line; what is not plain YAML
            (anchors, aliases, merge keys, tags, keys that are not names, dates; see :class:`_PlainComposer`),
            at its line and column; a document nested more than :data:`~robocal.formats._json.MAX_NESTING`
            levels deep; a key or string that is not valid Unicode.
    """
    fast = fast_load(text, allow_comments=not round_trip)
    if fast is not None:  # ASCII, at most 16 levels, no NaN constants: nothing for check_tree to refuse
        return fast
    return load_yaml_ruamel(text, source, item=item)


def load_yaml_ruamel(text: str, source: str, *, item: str = "key") -> Any:
    """:func:`load_yaml` through ruamel.yaml only (the reference the fast path is tested against)."""
    if _flow_depth(text) > MAX_NESTING:  # ruamel takes seconds for a few thousand levels: refuse them first
        raise FileFormatError(f"{source}: nested more than {MAX_NESTING} levels deep; not a robocal file")
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("error", YAMLWarning)  # e.g. a reused anchor: ambiguous, refused
            data = _yaml().load(text)
    except YAMLWarning as exc:
        lines = [ln.strip() for ln in str(exc).splitlines() if ln.strip()]
        second = next((ln for ln in lines if ln.startswith("second occurrence")), "")
        m = re.search(r"line (\d+), column (\d+)", second)
        where = f" (line {m.group(1)}, column {m.group(2)})" if m else ""
        raise FileFormatError(
            f"{source}: invalid YAML{where}: {lines[0] if lines else type(exc).__name__}"
        ) from None
    except YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        where = f" (line {mark.line + 1}, column {mark.column + 1})" if mark is not None else ""
        problem = getattr(exc, "problem", None) or str(exc).splitlines()[0]
        raise FileFormatError(f"{source}: invalid YAML{where}: {problem}") from None
    except RecursionError:
        raise FileFormatError(
            f"{source}: nested more than {MAX_NESTING} levels deep; not a robocal file"
        ) from None
    except (ValueError, OverflowError) as exc:  # a constructor refused a value, e.g. an int of 5000 digits
        raise FileFormatError(f"{source}: invalid YAML: {exc}") from None
    except TypeError as exc:  # ruamel: a complex key (``? {a: 1}``) that is a mapping is unhashable
        raise FileFormatError(f"{source}: invalid YAML: a key that is not a scalar ({exc})") from None
    check_tree(data, source, item=item, line_of=_line_of(data))
    return data


_REPRESENTER: list[Any] = []


def _float_text(value: float) -> str:
    """A float as :func:`dump_yaml` writes it (a loaded ``ScalarFloat`` keeps its spelling where exact)."""
    if type(value) is ScalarFloat:
        if not _REPRESENTER:
            _REPRESENTER.append(_yaml().representer)
        return str(_represent_scalar_float(_REPRESENTER[0], value).value)
    return yaml_float(value)


def dump_yaml(data: Any) -> str:
    """Serialise to YAML text, preserving comments and order of round-trip objects.

    A comment-free mapping of mappings of plain scalars is written by :func:`~._yaml_fast.fast_dump` (the same
    text ruamel.yaml writes); anything else by ruamel.yaml.
    """
    fast = fast_dump(data, _float_text)
    if fast is not None:
        return fast
    return dump_yaml_ruamel(data)


def dump_yaml_ruamel(data: Any) -> str:
    """:func:`dump_yaml` through ruamel.yaml only (the reference the fast path is tested against)."""
    buf = io.StringIO()
    _yaml().dump(data, buf)
    return buf.getvalue()
