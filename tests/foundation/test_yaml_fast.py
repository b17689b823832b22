"""The fast YAML path gives exactly what ruamel.yaml gives, or declines (and ruamel reads the file).

Generated documents in the plain layout robocal writes, and in near variants (odd scalars, indentation,
comments, quoting, single-character damage), are read by both paths: whenever the fast path answers, the
values, their types (``ScalarFloat`` spelling, quoted keys), the line/column records and the block/flow styles
equal ruamel's; the text written back equals ruamel's.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from ruamel.yaml.comments import CommentedMap

from robocal.core import RobotCalibration
from robocal.errors import FileFormatError
from robocal.formats import read_calibration, write_calibration
from robocal.formats._yaml import dump_yaml, dump_yaml_ruamel, load_yaml, load_yaml_ruamel
from robocal.formats._yaml_fast import fast_load

SETTINGS = settings(
    max_examples=100, deadline=None, suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large]
)


def assert_same(fast: Any, ref: Any, path: tuple[Any, ...] = ()) -> None:
    """Values, exact types, scalar spelling records, line/column records and styles are equal."""
    assert type(fast) is type(ref), (path, type(fast), type(ref))
    if hasattr(ref, "lc"):
        assert (fast.lc.line, fast.lc.col) == (ref.lc.line, ref.lc.col), path
        assert fast.lc.data == ref.lc.data, path
        assert fast.fa.flow_style() == ref.fa.flow_style(), path
    if isinstance(ref, dict):
        assert list(fast) == list(ref), path
        assert fast._ok == ref._ok, path
        ref_keys = {k: k for k in ref}
        for key in ref:
            fk = next(k for k in fast if k == key)
            assert type(fk) is type(ref_keys[key]), (path, key)
            assert_same(fast[key], ref[key], (*path, key))
    elif isinstance(ref, list):
        assert len(fast) == len(ref), path
        for i, (a, b) in enumerate(zip(fast, ref, strict=True)):
            assert_same(a, b, (*path, i))
    else:
        assert repr(fast) == repr(ref), path
        assert getattr(fast, "__dict__", None) == getattr(ref, "__dict__", None), path


# ----------------------------------------------------------------------------------------- documents
KEYS = st.one_of(
    st.from_regex(r"[a-z_][a-z0-9_]{0,6}", fullmatch=True),
    st.sampled_from(
        [
            "true",
            "True",
            "null",
            "Null",
            "yes",
            "no",
            "on",
            "off",
            "y",
            "n",
            "e5",
            "inf",
            "nan",
            "_",
            "x.y",
            "a-b",
        ]
    ),
    st.sampled_from(["1", "0", "1.5", "~", "-", "a b", "01"]),
)
FLOATS = st.floats(allow_nan=True, allow_infinity=True, width=64)
FLOAT_TEXT = st.one_of(
    FLOATS.map(lambda x: f"{x!r}" if np.isfinite(x) else ".nan"),
    FLOATS.filter(np.isfinite).map(lambda x: f"{x:.3f}"),
    FLOATS.filter(np.isfinite).map(lambda x: f"{x:e}"),
    FLOATS.filter(np.isfinite).map(lambda x: f"{x:.2E}"),
    st.sampled_from(
        ["0.50", "-0.0", "0.0", "1.", ".5", "-.5", "+1.5", "1e5", "1.0e-05", "1.5e+300", "00.5", "1_000.5"]
    ),
    st.sampled_from([".inf", "-.inf", ".NaN", "1.0e400", "-1.0e-400", "0.000000000000000000000000000001"]),
)
INT_TEXT = st.one_of(
    st.integers(-(2**70), 2**70).map(str),
    st.sampled_from(
        ["0", "-0", "+7", "007", "0x1F", "0o17", "0b101", "1_000", "99999999999999999999999", "9" * 5000]
    ),
)
WORDS = st.one_of(
    st.from_regex(r"[A-Za-z][A-Za-z0-9_./-]{0,8}( [a-z]{1,3})?", fullmatch=True),
    st.sampled_from(
        ["true", "false", "TRUE", "yes", "No", "~", "null", "2001-01-01", "12:30", "a:b", "-x", "<<", "="]
    ),
)
QUOTED = st.from_regex(r'"[ !#-\[\]-~]{0,8}"', fullmatch=True)
FLOW = st.lists(st.one_of(FLOAT_TEXT, INT_TEXT), max_size=4).map(lambda xs: "[" + ", ".join(xs) + "]")
SCALAR = st.one_of(FLOAT_TEXT, INT_TEXT, WORDS, QUOTED, FLOW)


@st.composite
def tree(draw: st.DrawFn, depth: int = 0) -> list[tuple[str, Any]]:
    """A mapping as (key text, value) pairs; a value is scalar text or a nested list of pairs."""
    n = draw(st.integers(1, 4))
    out: list[tuple[str, Any]] = []
    for _ in range(n):
        key = draw(KEYS)
        if draw(st.booleans()):
            key = f'"{key}"'
        if depth < 2 and draw(st.integers(0, 2)) == 0:
            out.append((key, draw(tree(depth + 1))))
        else:
            out.append((key, draw(SCALAR)))
    return out


@st.composite
def document(draw: st.DrawFn, comments: bool = True) -> str:
    """YAML text of a generated tree: indentation, spacing, comments and blank lines vary."""
    step = draw(st.sampled_from([2, 2, 4, 3]))
    gap = draw(st.sampled_from([" ", " ", "  "]))
    lines: list[str] = []

    def extra() -> None:
        if comments and draw(st.integers(0, 5)) == 0:
            lines.append(" " * draw(st.integers(0, 6)) + "# " + draw(st.sampled_from(["note", "", "x: 1"])))
        if draw(st.integers(0, 8)) == 0:
            lines.append("")

    def emit(pairs: list[tuple[str, Any]], indent: int) -> None:
        for key, value in pairs:
            extra()
            tail = "  # c" if comments and draw(st.integers(0, 6)) == 0 else ""
            if isinstance(value, list):
                lines.append(f"{' ' * indent}{key}:{tail}")
                emit(value, indent + step)
            else:
                lines.append(f"{' ' * indent}{key}:{gap}{value}{tail}")

    emit(draw(tree()), 0)
    extra()
    return "\n".join(lines) + draw(st.sampled_from(["\n", "", "\n\n"]))


DAMAGE = list(" :#-[]{}\"'\t\r\n&*!|>%@,?~\x00\u00e9")


@st.composite
def damaged(draw: st.DrawFn) -> str:
    """A generated document with one character inserted, replaced or deleted."""
    text = draw(document())
    pos = draw(st.integers(0, len(text)))
    kind = draw(st.sampled_from(["insert", "replace", "delete"]))
    ch = draw(st.sampled_from(DAMAGE))
    if kind == "insert":
        return text[:pos] + ch + text[pos:]
    if kind == "replace":
        return text[:pos] + ch + text[pos + 1 :]
    return text[:pos] + text[pos + 1 :]


def _compare(text: str) -> bool:
    """Both paths on ``text``; True when the fast path answered."""
    fast = fast_load(text)
    try:
        ref = load_yaml_ruamel(text, "doc.yaml")
    except FileFormatError as exc:
        assert fast is None, f"ruamel refuses ({exc}) what the fast path read"
        with pytest.raises(FileFormatError) as got:
            load_yaml(text, "doc.yaml")
        assert str(got.value) == str(exc)
        return False
    if fast is None:  # load_yaml is ruamel's reading then
        return False
    assert_same(fast, ref)
    assert_same(load_yaml(text, "doc.yaml"), ref)
    return True


@pytest.mark.slow
@SETTINGS
@given(text=document())
def test_fast_load_equals_ruamel_on_generated_documents(text: str) -> None:
    _compare(text)


@pytest.mark.slow
@SETTINGS
@given(text=damaged())
def test_fast_load_equals_ruamel_or_declines_on_damaged_documents(text: str) -> None:
    _compare(text)


@pytest.mark.slow
@SETTINGS
@given(text=document(comments=False))
def test_fast_dump_of_a_loaded_document_equals_ruamel(text: str) -> None:
    fast = fast_load(text, allow_comments=False)
    try:
        ref = load_yaml_ruamel(text, "doc.yaml")
    except FileFormatError:
        return
    if fast is None:
        return
    written = dump_yaml(fast)
    assert written == dump_yaml_ruamel(ref)
    assert written == dump_yaml_ruamel(fast)


NAMES = st.one_of(
    st.from_regex(r"[a-z_][a-z0-9_]{0,10}", fullmatch=True),
    st.sampled_from(["yes", "on", "null", "x y", "1"]),
)


@pytest.mark.slow
@SETTINGS
@given(
    entries=st.dictionaries(
        NAMES,
        st.fixed_dictionaries(
            {
                "id": st.integers(0, 300),
                "direction": st.sampled_from([-1, 1]),
                "homing_offset": st.floats(allow_nan=True, allow_infinity=True),
                "flag": st.booleans(),
            }
        ),
        min_size=1,
        max_size=5,
    )
)
def test_fast_dump_of_new_values_equals_ruamel(entries: dict[str, dict[str, Any]]) -> None:
    doc = CommentedMap()
    for name, entry in entries.items():
        node = CommentedMap()
        for key, value in entry.items():
            node[key] = value
        doc[name] = node
    assert dump_yaml(doc) == dump_yaml_ruamel(doc)


def test_robocal_written_files_take_the_fast_path(tmp_path: Path) -> None:
    """The speed of 10⁶-joint files depends on it: every YAML format robocal writes is in the plain layout."""
    names = [f"j{i}" for i in range(5)]
    cal = RobotCalibration(names, [1, -1, 1, -1, 1], [0.5, -1e-20, 0.0, 3.25, 1e300])
    ids = {n: i + 1 for i, n in enumerate(names)}
    for fmt in ("robocal", "lite-yaml", "berkeley-offsets"):
        path = tmp_path / f"{fmt}.yaml"
        write_calibration(path, cal, fmt, ids=ids, joint_order=names)
        text = path.read_text()
        fast = fast_load(text)
        assert fast is not None, fmt
        assert_same(fast, load_yaml_ruamel(text, fmt))
        if fmt == "berkeley-offsets":  # positional: reads back only with directions (URDF or profile)
            assert len(fast["position_offsets"]) == 5
            continue
        back = read_calibration(path, fmt)
        assert back.calibration.joint_names == tuple(names)
        assert list(back.calibration.homing_offset) == [0.5, -1e-20, 0.0, 3.25, 1e300]


def test_lite_yaml_update_keeps_comments_through_ruamel(tmp_path: Path) -> None:
    """A commented file written back keeps its comments (the fast path declines documents with comments)."""
    path = tmp_path / "cal.yaml"
    path.write_text("# my robot\nleft_hip:  # the left one\n  id: 1\n  direction: 1\n  homing_offset: 0.50\n")
    assert fast_load(path.read_text(), allow_comments=False) is None
    write_calibration(path, RobotCalibration(["left_hip"], [1], [0.25]), "lite-yaml", ids={"left_hip": 1})
    assert path.read_text() == (
        "# my robot\nleft_hip:  # the left one\n  id: 1\n  direction: 1\n  homing_offset: 0.25\n"
    )


def test_lite_yaml_update_without_comments_keeps_spelling(tmp_path: Path) -> None:
    """Through the fast path, an unchanged value keeps its spelling (0.50) and a changed one is rewritten."""
    path = tmp_path / "cal.yaml"
    path.write_text(
        "a:\n    id: 1\n    direction: 1\n    homing_offset: 0.50\nb:\n  id: 2\n  direction: -1\n  homing_offset: 1.0\n"
    )
    write_calibration(
        path, RobotCalibration(["a", "b"], [1, -1], [0.5, 2.0]), "lite-yaml", ids={"a": 1, "b": 2}
    )
    assert path.read_text() == (
        "a:\n  id: 1\n  direction: 1\n  homing_offset: 0.50\nb:\n  id: 2\n  direction: -1\n  homing_offset: 2.0\n"
    )


def test_a_complex_mapping_key_is_a_yaml_error_not_a_type_error() -> None:
    """Found by the fast-path comparison: ruamel raises TypeError for a ``? key`` that is a mapping; it escaped
    every YAML reader (a traceback from the CLI). It is refused where it is, like every non-name key."""
    with pytest.raises(
        FileFormatError,
        match=r"^cal\.yaml: invalid YAML \(line 2, column 4\): a mapping used as a key \(a complex key\)",
    ):
        load_yaml("_:\n ? k:\n    x: 0.0\n", "cal.yaml")


@pytest.mark.parametrize(
    ("text", "why"),
    [
        ("a:\tb\n", "tab"),
        ("a: 1\na: 2\n", "duplicate key"),
        ("a:\n", "null value"),
        ("a: &x 1\nb: *x\n", "anchor"),
        ("- 1\n- 2\n", "block sequence"),
        ("a: caf\u00e9\n", "non-ASCII"),
        ("%YAML 1.1\n---\na: yes\n", "directive"),
        ("a:\n  b: 1\n c: 2\n", "odd indentation"),
        ("x" * 101 + ": 1\n", "long key"),
    ],
)
def test_fast_path_declines_what_it_does_not_know_exactly(text: str, why: str) -> None:
    assert fast_load(text) is None, why
