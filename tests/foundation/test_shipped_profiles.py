"""The shipped robot profiles read quickly (``formats/_shipped_yaml.py``) and to the same value as ruamel.yaml reads.

A change to a shipped profile that leaves the quick reader's layout (a trailing comment, a block mapping inside a
list...) fails :func:`test_each_shipped_profile_takes_the_quick_path`: either keep to the layout described in the
module or extend the reader (and this test's cases).
"""

from __future__ import annotations

from importlib import resources
from typing import Any

import pytest

from robocal.errors import FileFormatError
from robocal.formats._shipped_yaml import load_shipped
from robocal.formats._yaml import load_yaml, load_yaml_ruamel
from robocal.formats.profiles import builtin_profile_names, builtin_profiles, load_profile, parse_profile

NAMES = builtin_profile_names()


def _text(name: str) -> str:
    return (resources.files("robocal") / "data" / "profiles" / f"{name}.yaml").read_text(encoding="utf-8")


def _typed(value: Any) -> Any:
    """The document as plain values with each scalar's kind (``True`` and ``1`` differ; ruamel's types count as
    their base types)."""
    if isinstance(value, dict):
        return {("key", str(k), type(k) is str): _typed(v) for k, v in value.items()}
    if isinstance(value, list):
        return [_typed(v) for v in value]
    for kind in (bool, int, float, str):
        if isinstance(value, kind):
            return (kind.__name__, kind(value))
    return ("other", repr(value))


def test_there_are_shipped_profiles() -> None:
    assert len(NAMES) == 12 and "so101_follower" in NAMES and "bhl_biped" in NAMES


@pytest.mark.parametrize("name", NAMES)
def test_each_shipped_profile_takes_the_quick_path(name: str) -> None:
    assert load_shipped(_text(name)) is not None


@pytest.mark.parametrize("name", NAMES)
def test_each_shipped_profile_reads_the_same_both_ways(name: str) -> None:
    text, source = _text(name), f"robocal:data/profiles/{name}.yaml"
    quick, full = load_shipped(text), load_yaml_ruamel(text, source)
    assert _typed(quick) == _typed(full)
    profile = parse_profile(full, source)
    assert parse_profile(quick, source) == profile
    assert load_profile(name) == profile and load_profile(name).name == name
    assert name in {p.name for p in builtin_profiles()}


@pytest.mark.parametrize(
    ("text", "expected"),
    [
        (
            "a: 1\nb: -2.50\nc: 0x1F\nd: true\ne: word with, comma (x)\n",
            {"a": 1, "b": -2.5, "c": 31, "d": True},
        ),
        ('a:\n  - {nm: x, k: "q: r", p: {s: 0}}\n  - {nm: z, l: [1, b], m: []}\n', None),
        ("# é comment ·\na:\n  b: [x]\n", {"a": {"b": ["x"]}}),
    ],
)
def test_the_layout_reads_as_ruamel_reads_it(text: str, expected: dict[str, Any] | None) -> None:
    quick = load_shipped(text)
    assert quick is not None
    assert _typed(quick) == _typed(load_yaml_ruamel(text, "t.yaml"))
    if expected is not None:
        assert {k: quick[k] for k in expected} == expected


@pytest.mark.parametrize(
    "text",
    [
        "a: 1  # a trailing comment\n",  # comments are kept only on comment lines
        "a:\nb: 1\n",  # a key without a value (null)
        "a: null\n",
        "a: yes\n",  # YAML 1.1 would read a bool
        "a: ~\n",
        "a: 1e3\n",
        "a: 012\n",
        "a: 2001-12-14\n",
        "a: .inf\n",
        'a: "with \\" escape"\n',
        "a: {b: 1,}\n",
        "a: {b: 1, b: 2}\n",  # a duplicate key: the full reader words the error
        "a: 1\na: 2\n",
        "a:\n  - b: 1\n",  # a block mapping in a list
        "a:\n- {b: 1}\n",  # a list at the key's own indentation
        "a: &x 1\n",
        "a: !!str 1\n",
        "\ta: 1\n",
        "- {a: 1}\n",
        "null: 1\n",
        "a: {n: 1}\n",  # n, y, on, off: booleans to YAML 1.1 readers
        "a:\n    b: 1\n  c: 2\n",  # odd indentation
        "a: b: c\n",
        "",
    ],
)
def test_anything_else_goes_to_the_full_reader(text: str) -> None:
    assert load_shipped(text) is None


def test_a_users_profile_file_still_gets_the_full_readers_errors(tmp_path: Any) -> None:
    path = tmp_path / "mine.yaml"
    path.write_text(_text("so101_follower").replace("joints:\n", "joints:\n  - {name: a, name: b}\n", 1))
    with pytest.raises(FileFormatError, match=r"invalid YAML \(line \d+, column \d+\)"):
        load_profile(path)
    assert load_yaml(_text("koch_leader"), "k.yaml") is not None
