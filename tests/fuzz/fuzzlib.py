"""Mutation strategies and the "only CalibError, nothing written" harness shared by the fuzz tests.

Every strategy starts from a *valid* input (a seed written by robocal's own writers, the simulators or the
upstream formats' published examples) and mutates it: byte flips, truncation, inserted invalid or overlong
UTF-8, odd Unicode (lone surrogates, NUL, RTL marks, BOM, combining marks), huge and non-finite numbers,
type swaps, deep nesting and duplicate keys. The profile (``HYPOTHESIS_PROFILE``) decides how many examples
run: the default is derandomized and database-less so CI is repeatable; ``thorough`` runs ~100× more with
random seeds.
"""

from __future__ import annotations

import copy
import hashlib
import json
import os
import re
import tempfile
import traceback
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from hypothesis import HealthCheck, Phase, settings
from hypothesis import strategies as st

from robocal.errors import CalibError

THOROUGH = os.environ.get("HYPOTHESIS_PROFILE", "default") == "thorough"
SCALE = 100 if THOROUGH else 1


def fuzz_settings(examples: int) -> settings:
    """``examples`` per test in CI (derandomized, no database); 100× as many, random, under ``thorough``."""
    return settings(
        max_examples=examples * SCALE,
        derandomize=not THOROUGH,
        database=None,
        deadline=None,
        print_blob=True,
        phases=[Phase.explicit, Phase.reuse, Phase.generate, Phase.shrink],  # no slow "explain" tracing
        suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large, HealthCheck.filter_too_much],
    )


# ------------------------------------------------------------------------------------------ value pools
ODD_TEXT = [
    "\ud800",  # lone high surrogate
    "\udfff",  # lone low surrogate
    "a\ud83dz",  # half an emoji pair
    "\x00",
    "j\x00oint",
    "\u202eesrever",  # RTL override
    "\u200f\u200e",  # RTL / LTR marks
    "\ufeff",  # BOM / zero-width no-break space
    "\u2028\u2029",  # line / paragraph separators
    "e\u0301\u0301\u0301",  # combining marks
    "\U0001f916",  # 🤖
    "\uffff\ufffe",
    "\x1b[31mred\x1b[0m",
    "",
    " ",
    "\t\r\n",
    "x" * 300,
    "名前",
    "Ünïcødé",
    "${HOME}",
    "%s%n",
    "<&>'\"",
]
ODD_BYTES = [
    b"\xc0\x80",  # overlong NUL
    b"\xc0\xaf",  # overlong '/'
    b"\xe0\x80\xaf",  # overlong '/' (3 bytes)
    b"\xf0\x80\x80\xaf",  # overlong '/' (4 bytes)
    b"\xed\xa0\x80",  # UTF-8-encoded lone surrogate (CESU)
    b"\xf4\x90\x80\x80",  # beyond U+10FFFF
    b"\xff",
    b"\xfe\xff",
    b"\x80",
    b"\x00",
    b"\xef\xbb\xbf",  # BOM
    b"\xe2\x80\xae",  # RTL override
    b"\r",
    b"\n" * 3,
]
HUGE_NUMBERS: list[Any] = [
    10**30,
    -(10**30),
    2**63,
    2**64 + 1,
    -(2**63) - 1,
    2**31,
    4096,
    -1,
    0,
    1e308,
    -1e308,
    1.7976931348623157e308,
    5e-324,
    -0.0,
    float(2**53 + 1),
    float("nan"),
    float("inf"),
    float("-inf"),
]
RAW_TOKENS = [
    "NaN",
    "Infinity",
    "-Infinity",
    "nan",
    ".nan",
    ".inf",
    "-.inf",
    "1e999",
    "-1e999",
    "1" + "0" * 30,
    "1" + "0" * 5000,  # beyond CPython's int-string limit
    "0x1F",
    "0o17",
    "1_000",
    "01",
    "-0",
    "1.",
    ".5",
    "+1",
    "1e",
    "true",
    "null",
    "~",
    "''",
    '""',
    "[]",
    "{}",
    "!!binary AAAA",
    "&a x",
    "*a",
    "2001-12-14",
    "0b101",
    "１２",  # full-width digits
    "٣",  # Arabic-Indic digit
]


# ----------------------------------------------------------------------------------------- byte mutations
def _ops(data: st.DataObject, seed: bytes, max_ops: int = 3) -> bytes:
    out = bytearray(seed)
    for _ in range(data.draw(st.integers(1, max_ops), label="ops")):
        kind = data.draw(
            st.sampled_from(["flip", "truncate", "delete", "insert", "odd", "dup", "set"]), label="op"
        )
        n = len(out)
        pos = data.draw(st.integers(0, max(n, 1) - 1 if n else 0), label="pos") if n else 0
        if kind == "flip" and n:
            out[pos] ^= 1 << data.draw(st.integers(0, 7), label="bit")
        elif kind == "truncate":
            del out[pos:]
        elif kind == "delete" and n:
            del out[pos : pos + data.draw(st.integers(1, 16), label="len")]
        elif kind == "insert":
            out[pos:pos] = data.draw(st.binary(min_size=1, max_size=8), label="bytes")
        elif kind == "odd":
            out[pos:pos] = data.draw(st.sampled_from(ODD_BYTES), label="odd")
        elif kind == "dup" and n:
            end = min(n, pos + data.draw(st.integers(1, 64), label="len"))
            out[pos:pos] = out[pos:end]
        elif kind == "set" and n:
            out[pos] = data.draw(st.integers(0, 255), label="byte")
    return bytes(out)


def byte_mutation(data: st.DataObject, seed: bytes) -> bytes:
    """Seed with 1-3 byte-level edits (flip, truncate, delete, insert random/invalid/overlong UTF-8, dup)."""
    return _ops(data, seed)


_NUMBER = re.compile(rb"-?\d+(?:\.\d+)?(?:[eE][-+]?\d+)?")
_WORD = re.compile(rb"[A-Za-z_][A-Za-z0-9_]*")


def encode_text(data: st.DataObject, text: str) -> bytes:
    """UTF-8 (lone surrogates written as CESU bytes, which are invalid UTF-8) or with an odd prefix."""
    how = data.draw(st.sampled_from(["utf8", "bom", "utf16"]), label="encoding")
    raw = text.encode("utf-8", "surrogatepass")
    if how == "bom":
        return b"\xef\xbb\xbf" + raw
    if how == "utf16":
        return text.encode("utf-16", "surrogatepass")
    return raw


def token_mutation(data: st.DataObject, seed: bytes) -> bytes:
    """Replace numbers / words of the seed with huge, non-finite, odd-Unicode or syntax-breaking tokens."""
    out = seed
    for _ in range(data.draw(st.integers(1, 3), label="tokens")):
        pattern = data.draw(st.sampled_from([_NUMBER, _WORD]), label="what")
        spans = [m.span() for m in pattern.finditer(out)]
        if not spans:
            continue
        a, b = data.draw(st.sampled_from(spans), label="span")
        repl = data.draw(
            st.one_of(
                st.sampled_from(RAW_TOKENS),
                st.sampled_from(ODD_TEXT),
                st.sampled_from([repr(x) for x in HUGE_NUMBERS]),
            ),
            label="token",
        )
        out = out[:a] + repl.encode("utf-8", "surrogatepass") + out[b:]
    return out


def text_mutation(data: st.DataObject, seed: bytes) -> bytes:
    """One of the byte-level or token-level mutations (possibly both)."""
    kind = data.draw(st.sampled_from(["bytes", "tokens", "both"]), label="mutation")
    out = seed
    if kind in ("tokens", "both"):
        out = token_mutation(data, out)
    if kind in ("bytes", "both"):
        out = byte_mutation(data, out)
    return out


# ----------------------------------------------------------------------------------------- tree mutations
class Pairs(list):  # type: ignore[type-arg]
    """A JSON/YAML object as a list of ``[key, value]`` pairs, so keys may repeat."""


@dataclass
class Raw:
    """A literal token emitted as is (``NaN``, ``1e999``, ``0x10``...)."""

    text: str


@dataclass
class Deep:
    """``value`` wrapped in ``depth`` single-element lists (or objects)."""

    value: Any
    depth: int
    objects: bool = False


def to_pairs(obj: Any) -> Any:
    """Turn dicts of a loaded document into :class:`Pairs` (recursively)."""
    if isinstance(obj, dict):
        return Pairs([[str(k), to_pairs(v)] for k, v in obj.items()])
    if isinstance(obj, list):
        return [to_pairs(v) for v in obj]
    return obj


def _paths(obj: Any, prefix: tuple[Any, ...] = ()) -> Iterator[tuple[Any, ...]]:
    yield prefix
    if isinstance(obj, Pairs):
        for i, (_k, v) in enumerate(obj):
            yield from _paths(v, (*prefix, ("v", i)))
            yield (*prefix, ("k", i))
    elif isinstance(obj, list):
        for i, v in enumerate(obj):
            yield from _paths(v, (*prefix, ("i", i)))


def _get_parent(obj: Any, path: tuple[Any, ...]) -> tuple[Any, Any]:
    cur = obj
    for kind, i in path[:-1]:
        cur = cur[i][1] if kind == "v" else cur[i]
    return cur, path[-1]


def scalars(max_depth: int) -> st.SearchStrategy[Any]:
    """Values that replace a node: type swaps, huge/non-finite numbers, odd strings, raw tokens, nesting."""
    leaf = st.one_of(
        st.none(),
        st.booleans(),
        st.sampled_from(HUGE_NUMBERS),
        st.integers(-(2**70), 2**70),
        st.floats(allow_nan=True, allow_infinity=True),
        st.sampled_from(ODD_TEXT),
        st.text(max_size=12),
        st.builds(Raw, st.sampled_from(RAW_TOKENS)),
        st.just([]),
        st.just(Pairs()),
    )
    return st.one_of(
        leaf,
        st.lists(leaf, max_size=4),
        st.builds(Deep, leaf, st.integers(2, max_depth), st.booleans()),
    )


def tree_mutation(data: st.DataObject, tree: Any, max_depth: int = 40) -> Any:
    """Apply 1-3 structural edits to a copy of ``tree``: replace, delete, duplicate key, rename key, nest."""
    tree = to_pairs(json.loads(json.dumps(tree)))
    for _ in range(data.draw(st.integers(1, 3), label="edits")):
        paths = list(_paths(tree))
        path = data.draw(st.sampled_from(paths), label="path")
        op = data.draw(st.sampled_from(["replace", "delete", "dup", "rename", "nest"]), label="edit")
        if not path:
            if op in ("replace", "nest"):
                tree = data.draw(scalars(max_depth), label="root") if op == "replace" else Deep(tree, 3)
            continue
        parent, (kind, i) = _get_parent(tree, path)
        if op == "replace":
            value = data.draw(scalars(max_depth), label="value")
            if kind == "k":
                parent[i][0] = data.draw(st.sampled_from(ODD_TEXT), label="key")
            elif kind == "v":
                parent[i][1] = value
            else:
                parent[i] = value
        elif op == "delete":
            del parent[i]
        elif op == "dup":
            parent.insert(i, copy.deepcopy(parent[i]))
        elif op == "rename" and kind in ("k", "v"):
            parent[i][0] = data.draw(
                st.sampled_from([*ODD_TEXT, "id", "direction", "homing_offset"]), label="key"
            )
        elif op == "nest":
            if kind == "v":
                parent[i][1] = Deep(parent[i][1], data.draw(st.integers(2, max_depth), label="depth"))
            elif kind == "i":
                parent[i] = Deep(parent[i], data.draw(st.integers(2, max_depth), label="depth"))
    return tree


def _num(x: Any, nan: str, inf: str) -> str:
    """A number's token: booleans and ints as themselves, NaN and ±inf spelled ``nan`` and ``inf``/``-inf``."""
    if isinstance(x, bool):
        return "true" if x else "false"
    if isinstance(x, int):
        return str(x)
    if x != x:
        return nan
    if x in (float("inf"), float("-inf")):
        return inf if x > 0 else "-" + inf
    return repr(x)


def _num_json(x: Any) -> str:
    return _num(x, "NaN", "Infinity")


def _leaf(obj: Any, emit: Callable[[Any], str], num: Callable[[Any], str], key: str) -> str | None:
    """The text of a nesting (``{key`` or ``[`` ``depth`` times around its value), raw token, null or number."""
    if isinstance(obj, Deep):
        inner = emit(obj.value)
        if obj.objects:
            return key * obj.depth + inner + "}" * obj.depth
        return "[" * obj.depth + inner + "]" * obj.depth
    if isinstance(obj, Raw):
        return obj.text
    if obj is None:
        return "null"
    if isinstance(obj, (bool, int, float)):
        return num(obj)
    return None


def emit_json(obj: Any, ascii_only: bool = True) -> str:
    """JSON text of a (mutated) tree; repeated keys, NaN/Infinity and raw tokens are written verbatim."""
    leaf = _leaf(obj, lambda v: emit_json(v, ascii_only), _num_json, '{"k": ')
    if leaf is not None:
        return leaf
    if isinstance(obj, str):
        return json.dumps(obj, ensure_ascii=ascii_only)
    if isinstance(obj, Pairs):
        return (
            "{"
            + ", ".join(f"{emit_json(str(k), ascii_only)}: {emit_json(v, ascii_only)}" for k, v in obj)
            + "}"
        )
    if isinstance(obj, list):
        return "[" + ", ".join(emit_json(v, ascii_only) for v in obj) + "]"
    return json.dumps(str(obj))


def _num_yaml(x: Any) -> str:
    return _num(x, ".nan", ".inf")


def emit_yaml(obj: Any, indent: int = 0) -> str:
    """Block-style YAML of a (mutated) tree (flow style for nesting); repeated keys are written verbatim."""
    pad = "  " * indent
    if isinstance(obj, Pairs) and obj:
        lines = []
        for k, v in obj:
            key = json.dumps(str(k))
            if isinstance(v, (Pairs, list)) and v and not isinstance(v, Deep):
                lines.append(f"{pad}{key}:\n{emit_yaml(v, indent + 1)}")
            else:
                lines.append(f"{pad}{key}: {_flow_yaml(v)}")
        return "\n".join(lines)
    if isinstance(obj, list) and obj and not isinstance(obj, Pairs):
        return "\n".join(f"{pad}- {_flow_yaml(v)}" for v in obj)
    return pad + _flow_yaml(obj)


def _flow_yaml(obj: Any) -> str:
    leaf = _leaf(obj, _flow_yaml, _num_yaml, "{k: ")
    if leaf is not None:
        return leaf
    if isinstance(obj, str):
        return json.dumps(obj)  # a JSON string is a YAML double-quoted scalar (\ud800 escapes included)
    if isinstance(obj, Pairs):
        return "{" + ", ".join(f"{json.dumps(str(k))}: {_flow_yaml(v)}" for k, v in obj) + "}"
    if isinstance(obj, list):
        return "[" + ", ".join(_flow_yaml(v) for v in obj) + "]"
    return json.dumps(str(obj))


def json_mutation(data: st.DataObject, seed_text: str) -> bytes:
    """A JSON seed mutated at tree level (then encoded) or at text level."""
    if data.draw(st.booleans(), label="tree?"):
        tree = tree_mutation(data, json.loads(seed_text))
        text = emit_json(tree, ascii_only=data.draw(st.booleans(), label="ascii"))
        return encode_text(data, text)
    return text_mutation(data, seed_text.encode())


def yaml_mutation(data: st.DataObject, seed_text: str, tree: Any) -> bytes:
    """A YAML seed mutated at tree level (``tree`` is the seed's plain data) or at text level."""
    if data.draw(st.booleans(), label="tree?"):
        text = emit_yaml(tree_mutation(data, tree)) + "\n"
        return encode_text(data, text)
    return text_mutation(data, seed_text.encode())


def deep_json(depth: int, objects: bool) -> str:
    """A JSON document nested ``depth`` levels deep."""
    return emit_json(Deep(0, depth, objects))


# ------------------------------------------------------------------------------------------- the harness
def snapshot(root: Path) -> dict[str, tuple[int, int, str]]:
    """Every file under ``root``: relative path → (size, mtime_ns, sha256)."""
    out: dict[str, tuple[int, int, str]] = {}
    for p in sorted(root.rglob("*")):
        st_ = p.lstat()
        digest = hashlib.sha256(p.read_bytes()).hexdigest() if p.is_file() and not p.is_symlink() else ""
        out[p.relative_to(root).as_posix()] = (st_.st_size, st_.st_mtime_ns, digest)
    return out


@contextmanager
def scratch() -> Iterator[Path]:
    """A fresh temporary folder (hypothesis runs many examples per test, so no pytest ``tmp_path``)."""
    with tempfile.TemporaryDirectory(prefix="robocal-fuzz-") as d:
        yield Path(d)


def reader_raises_only_calib_error(blob: bytes, name: str, read: Callable[[Path], object], what: str) -> None:
    """Write ``blob`` as ``name`` in a fresh folder and :func:`only_calib_error` ``read`` of it."""
    with scratch() as root:
        p = root / name
        p.write_bytes(blob)
        only_calib_error(lambda: read(p), root, what)


# Crashes of issue 9 that another branch fixes. While one is pending the fuzz tests tolerate exactly that
# signature (exception type + a text of its message or innermost frames) so they keep hunting other crashes;
# each also has a dedicated xfail(strict=False) test. Remove the entry once the fix is on main.
PENDING: list[tuple[type[BaseException], str, str]] = []


def pending_item(exc: BaseException, tb: str) -> str | None:
    """The pending issue item an escaped exception belongs to, if any."""
    for kind, text, item in PENDING:
        if isinstance(exc, kind) and text in f"{exc}\n{tb}":
            return item
    return None


def only_calib_error(fn: Callable[[], object], root: Path, what: str) -> CalibError | None:
    """Run ``fn``; fail on any exception that is not a CalibError, or on any change under ``root``.

    Returns:
        The CalibError raised, or None when ``fn`` accepted the input (or hit a :data:`PENDING` crash).
    """
    before = snapshot(root)
    caught: CalibError | None = None
    try:
        fn()
    except CalibError as exc:
        caught = exc
        assert str(exc).strip(), f"{what}: {type(exc).__name__} with an empty message"
    except BaseException as exc:  # anything else is the defect this suite hunts
        if isinstance(exc, KeyboardInterrupt):
            raise
        tb = "".join(traceback.format_exception(type(exc), exc, exc.__traceback__, limit=-6))
        if pending_item(exc, tb) is not None:
            return None
        raise AssertionError(
            f"{what}: {type(exc).__name__} escaped (not a CalibError): {exc!r}\n{tb}"
        ) from None
    after = snapshot(root)
    assert after == before, f"{what}: files changed: {sorted(set(after.items()) ^ set(before.items()))}"
    return caught
