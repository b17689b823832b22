"""Every reader, fed hostile YAML, JSON and XML documents through the command a user would run.

Each document must give exit code 2, exactly one ``error:`` line naming the file and what was wrong, no
traceback, and no file created or changed. :data:`READERS` lists the readers with the command that reaches
each; :func:`test_every_parse_call_in_src_is_listed` fails when a module in ``src/`` parses YAML, JSON or XML
in a place that is neither listed here nor in :data:`NOT_FILE_READERS`, so a new reader gets this sweep too.
"""

from __future__ import annotations

import ast
import json
import re
import subprocess
import sys
from collections.abc import Callable
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path

import pytest
import seeds
from fuzzlib import snapshot

from robocal.cli.main import main
from robocal.core.ur import default_kinematics
from robocal.formats.ur_kinematics import kinematics_to_text

SRC = Path(__file__).resolve().parents[2] / "src" / "robocal"
SEEDS = seeds.calibration_seeds()
LITE_URDF = seeds.lite_urdf_text()
CAMERA_YAML = (
    "image_width: 640\nimage_height: 480\ncamera_name: cam\n"
    "camera_matrix:\n  rows: 3\n  cols: 3\n  data: [500.0, 0.0, 320.0, 0.0, 500.0, 240.0, 0.0, 0.0, 1.0]\n"
    "distortion_model: plumb_bob\n"
    "distortion_coefficients:\n  rows: 1\n  cols: 5\n  data: [0.0, 0.0, 0.0, 0.0, 0.0]\n"
)


def _profile_text() -> str:
    return resources.files("robocal").joinpath("data", "profiles", "so101_follower.yaml").read_text()


# --------------------------------------------------------------------------------------------- the readers
@dataclass(frozen=True)
class Reader:
    """One reader and the command that reaches it.

    Attributes:
        name: Test id.
        kind: ``yaml``, ``json`` or ``xml``: which hostile documents it gets.
        target: The file (relative to the run folder) that gets the hostile document.
        args: The ``robocal`` arguments (relative paths; the run folder is the working directory).
        files: The valid files of the run (relative path → content); ``target``'s entry is the valid seed.
        sites: The parse calls in ``src/`` it covers (``module:function``, see :func:`_parse_sites`).
        number: Where a number a hostile document replaces is (a regular expression whose group 1 is a
            number the reader uses); default: the first number outside comments and keys.
    """

    name: str
    kind: str
    target: str
    args: tuple[str, ...]
    files: dict[str, bytes]
    sites: tuple[str, ...]
    trees: dict[str, dict[str, bytes]] = field(default_factory=dict)
    number: str | None = None
    accepts: frozenset[str] = frozenset()


def _readers() -> list[Reader]:
    urdf = LITE_URDF.encode()
    current = seeds.current_seed().encode()
    legacy = seeds.legacy_seed().encode()
    ds = seeds.dataset_seed()
    return [
        Reader(
            "calibration-detected-yaml",
            "yaml",
            "cal.yaml",
            ("convert", "cal.yaml", "out.json"),
            {"cal.yaml": SEEDS["robocal"]},
            (
                "formats.calibration.registry:_parse_for_sniffing",
                "formats.calibration.registry:_parse_for_sniffing",
            ),
        ),
        Reader(
            "calibration-robocal",
            "yaml",
            "cal.yaml",
            ("convert", "cal.yaml", "out.json", "--from", "robocal"),
            {"cal.yaml": SEEDS["robocal"]},
            ("formats.calibration._base:yaml_data",),
        ),
        Reader(
            "calibration-lite-yaml",
            "yaml",
            "cal.yaml",
            ("check", "--calibration", "cal.yaml", "--urdf", "lite.urdf", "--format", "lite-yaml"),
            {"cal.yaml": SEEDS["lite-yaml-commented"], "lite.urdf": urdf},
            ("formats.calibration._base:yaml_data",),
        ),
        Reader(
            "calibration-berkeley-yaml",
            "yaml",
            "cal.yaml",
            ("convert", "cal.yaml", "out.json", "--from", "berkeley-offsets", "--urdf", "lite.urdf"),
            {"cal.yaml": SEEDS["berkeley-offsets"], "lite.urdf": urdf},
            ("formats.calibration.berkeley:read",),
        ),
        Reader(
            "existing-lite-yaml-output",
            "yaml",
            "out.yaml",
            ("convert", "cal.json", "out.yaml", "--to", "lite-yaml"),
            {"cal.json": SEEDS["lite-json"], "out.yaml": SEEDS["lite-yaml-commented"]},
            ("formats.calibration.lite_yaml:write",),
        ),
        Reader(
            "existing-sweep-output",
            "yaml",
            "offsets.yaml",
            ("sweep", "--urdf", "lite.urdf", "--source", "replay:sweep.csv", "--out", "offsets.yaml"),
            {
                "offsets.yaml": SEEDS["lite-yaml-commented"],
                "lite.urdf": urdf,
                "sweep.csv": seeds.csv_seed(60).encode(),
            },
            ("formats.calibration.lite_yaml:write",),
        ),
        Reader(
            "profile",
            "yaml",
            "robot.yaml",
            ("lerobot", "show", "--robot", "robot.yaml", "--port", "sim", "--file", "cal.json"),
            {"robot.yaml": _profile_text().encode(), "cal.json": current},
            ("formats.profiles:_read_profile_file", "formats.profiles:_builtin"),
        ),
        Reader(
            "ur-kinematics",
            "yaml",
            "k.yaml",
            ("ur", "verify", "k.yaml", "--model", "ur10e", "--samples", "5"),
            {"k.yaml": kinematics_to_text(default_kinematics("ur10e", rpy="urdf")).encode()},
            ("formats.ur_kinematics:read_kinematics",),
        ),
        Reader(
            "ur-dh",
            "yaml",
            "dh.yaml",
            ("ur", "correct", "--dh", "dh.yaml", "--out", "k.yaml"),
            {"dh.yaml": seeds.DH_YAML.encode()},
            ("formats.ur_kinematics:_load_mapping",),
        ),
        Reader(
            "ur-deltas",
            "yaml",
            "d.yaml",
            ("ur", "correct", "--model", "ur10e", "--deltas", "d.yaml", "--out", "k.yaml"),
            {"d.yaml": seeds.DELTAS_YAML.encode()},
            ("formats.ur_kinematics:_load_mapping",),
        ),
        Reader(
            "camera-info",
            "yaml",
            "cam.yaml",
            (
                "kinematics",
                "identify",
                "--urdf",
                "lite.urdf",
                "--data",
                "session.csv",
                "--kind",
                "tag",
                "--camera",
                "cam.yaml",
                "--target",
                "apriltag:36h11:0:50",
            ),
            {"cam.yaml": CAMERA_YAML.encode(), "lite.urdf": urdf, "session.csv": b"image\n"},
            ("formats.camera_info:read_camera_info",),
        ),
        Reader(
            "calibration-detected-json",
            "json",
            "cal.json",
            ("convert", "cal.json", "out.yaml"),
            {"cal.json": SEEDS["lite-json"]},
            ("formats.calibration.registry:_parse_for_sniffing",),
        ),
        Reader(
            "calibration-lite-json",
            "json",
            "cal.json",
            ("convert", "cal.json", "out.yaml", "--from", "lite-json"),
            {"cal.json": SEEDS["lite-json"]},
            ("formats.calibration.lite_json:read", "formats.calibration.lite_json:read"),
        ),
        Reader(
            "calibration-lerobot-legacy",
            "json",
            "legacy.json",
            ("convert", "legacy.json", "out.yaml", "--from", "lerobot-legacy", "--robot", "so101_follower"),
            {"legacy.json": legacy},
            ("formats.lerobot:parse_legacy",),
        ),
        Reader(
            "lerobot-current",
            "json",
            "cal.json",
            ("lerobot", "show", "--robot", "so101_follower", "--port", "sim", "--file", "cal.json"),
            {"cal.json": current},
            ("formats.lerobot:parse_current",),
        ),
        Reader(
            "lerobot-legacy-migrate",
            "json",
            "legacy.json",
            ("lerobot", "migrate", "legacy.json", "--vendor", "feetech", "--out", "current.json"),
            {"legacy.json": legacy},
            ("formats.lerobot:parse_legacy",),
        ),
        Reader(
            "dataset-calibration",
            "json",
            "cal.json",
            ("dataset", "inspect", "ds", "--calibration", "cal.json", "--robot", "so101_follower"),
            {"cal.json": current},
            ("dataset.lerobot:_json_kind",),
            trees={"ds": ds},
        ),
        Reader(
            "dataset-info",
            "json",
            "ds/meta/info.json",
            ("dataset", "inspect", "ds", "--calibration", "cal.json", "--robot", "so101_follower"),
            {"cal.json": current, "ds/meta/info.json": ds["meta/info.json"]},
            ("dataset._layout:read_layout",),
            trees={"ds": ds},
            number=r'"shape": \[\s*(\d+)',
        ),
        Reader(
            "dataset-stats",
            "json",
            "ds/meta/stats.json",
            seeds.DATASET_RECALIBRATE,
            {"cal.json": current, "new.json": current, "ds/meta/stats.json": ds["meta/stats.json"]},
            ("dataset._metadata:_read_stats",),
            trees={"ds": ds},
            # the recalibrated features' statistics are recomputed; a big integer is a valid JSON number
            accepts=frozenset({"int-1e30"}),
        ),
        Reader(
            "urdf",
            "xml",
            "lite.urdf",
            ("check", "--calibration", "cal.yaml", "--urdf", "lite.urdf"),
            {"lite.urdf": urdf, "cal.yaml": SEEDS["robocal"]},
            ("formats.urdf:_parse_tree",),
        ),
        Reader(
            "calibration-ros2-transmission",
            "xml",
            "robot.urdf",
            ("convert", "robot.urdf", "out.yaml", "--from", "ros2-transmission"),
            {"robot.urdf": SEEDS["ros2-transmission"]},
            ("formats.urdf:_parse_tree",),
        ),
        Reader(
            "kinematics-urdf",
            "xml",
            "lite.urdf",
            (
                "kinematics",
                "identify",
                "--urdf",
                "lite.urdf",
                "--data",
                "points.csv",
                "--tip-link",
                "left_wrist_pitch_link",
            ),
            {"lite.urdf": urdf, "points.csv": b"x,y,z\n"},
            ("formats.urdf:_parse_tree",),
        ),
    ]


READERS = _readers()

NOT_FILE_READERS = {
    "backends.sim.control:handle_line": "the simulator's control socket (one JSON request per line)",
    "backends.sim.control:request": "the simulator's control socket (its own JSON answers)",
    "formats.calibration.transmission:_append_transmission": "an XML snippet robocal builds itself",
    "viewer.shapes:add_simple_shapes": "a URDF text parse_urdf has already accepted",
    "workflows.demo.job:_lerobot_demo": "the calibration JSON the demo has just written",
    "workflows.demo.auto_openarm:openarm_demo": "the LeRobot JSON the OpenArm demo has just written",
    "workflows.motion.snapshot:find_left_changed": "robocal's own register snapshot in its state folder (a "
    "file it cannot read is ignored, never an error)",
}
"""Parse calls in src/ that read no user file, with the reason."""


# ----------------------------------------------------------------------------------- the hostile documents
@dataclass(frozen=True)
class Hostile:
    """A hostile document made from a reader's valid seed, and what the error line must say."""

    name: str
    make: Callable[[str, str | None], str]
    says: str  # a regular expression the error line must match (after the file name)


def _append(entry: str) -> Callable[[str, str | None], str]:
    return lambda seed, _at: seed.rstrip("\n") + "\n" + entry


_NUMBER = re.compile(r"(?<![\w.\-])-?\d+(?:\.\d+)?(?:[eE][-+]?\d+)?(?![\w.])")


def _replace_first_number(token: str) -> Callable[[str, str | None], str]:
    """Replace the number ``at`` points to (else the first outside comments and keys) with ``token``."""

    def make(seed: str, at_pattern: str | None) -> str:
        if at_pattern is not None:
            m = re.search(at_pattern, seed)
            assert m is not None, at_pattern
            return seed[: m.start(1)] + token + seed[m.end(1) :]
        start = 0
        for line in seed.splitlines(keepends=True):
            code = line if line.lstrip().startswith(("{", "[", '"', "0", "1", "-")) else line.split("#", 1)[0]
            value = code.split(":", 1)[1] if ":" in code and not code.lstrip().startswith("[") else code
            m = _NUMBER.search(value)
            if m is not None:
                at = start + len(code) - len(value) + m.start()
                return seed[:at] + token + seed[at + len(m.group()) :]
            start += len(line)
        raise AssertionError("no number in the seed")

    return make


def _duplicate_first_key(seed: str, _at: str | None) -> str:
    """Repeat the first top-level key at the end (a YAML document)."""
    line = next(ln for ln in seed.splitlines() if re.match(r'[A-Za-z_"][^:#]*:', ln))
    return seed.rstrip("\n") + "\n" + line.split(":", 1)[0] + ": 1\n"


def _duplicate_first_json_key(seed: str, _at: str | None) -> str:
    data = json.loads(seed)
    key = next(iter(data))
    return "{" + json.dumps(key) + ": " + json.dumps(data[key]) + ", " + seed.lstrip()[1:]


def _const(text: str) -> Callable[[str, str | None], str]:
    return lambda _seed, _at: text


NOT_NAME = r"not a name; quote it"
HOSTILE_YAML = [
    Hostile("top-mapping-key", _const("? b: 1\n: x\n"), r"line 1, column 3\): a mapping used as a key"),
    Hostile("top-sequence-key", _const("? [a, b]\n: 1\n"), r"line 1, column 3\): a sequence used as a key"),
    Hostile("flow-sequence-key", _const("{[1]: 2}\n"), r"a sequence used as a key"),
    Hostile("nested-mapping-key", _append("bad:\n  ? {a: 1}\n  : 2\n"), r"a mapping used as a key"),
    Hostile("nested-sequence-key", _append("bad:\n  ? [a, b]\n  : 2\n"), r"a sequence used as a key"),
    Hostile("merge-key", _append("bad:\n  <<: {x: 1}\n"), r"a merge key \(<<\)"),
    Hostile("merge-alias", _append("base: &a {x: 1}\nbad:\n  <<: *a\n"), r"an anchor \(&a\)"),
    Hostile("duplicate-key", _duplicate_first_key, r"duplicate key"),
    Hostile("int-key", _const("1: x\n"), r"the key '1' is a number, " + NOT_NAME),
    Hostile("float-key", _const("1.5: x\n"), r"the key '1.5' is a number, " + NOT_NAME),
    Hostile("null-key", _const("null: x\n"), r"the key 'null' is null, " + NOT_NAME),
    Hostile("tilde-key", _const("~: x\n"), r"the key '~' is null, " + NOT_NAME),
    Hostile("true-key", _const("true: x\n"), r"the key 'true' is true/false, " + NOT_NAME),
    Hostile("nested-int-key", _append("bad:\n  7: 0.5\n"), r"the key '7' is a number, " + NOT_NAME),
    Hostile("anchor-alias", _append("a: &x {y: 1}\nb: *x\n"), r"an anchor \(&x\)"),
    Hostile("alias-only", _append("b: *x\n"), r"an alias \(\*x\)"),
    Hostile("python-object", _append("bad: !!python/object:os.system {}\n"), r"a tag \(!!python/object:os"),
    Hostile(
        "python-apply", _append("bad: !!python/object/apply:os.system ['echo hi']\n"), r"a tag \(!!python/"
    ),
    Hostile("binary", _append("bad: !!binary aGVsbG8=\n"), r"a tag \(!!binary\)"),
    Hostile("local-tag", _append("bad: !foo 1\n"), r"a tag \(!foo\)"),
    Hostile("set", _const("!!set {a, b}\n"), r"a tag \(!!set\)"),
    Hostile("date", _append("bad: 2001-12-14\n"), r"the date '2001-12-14'"),
    Hostile("two-documents", _append("---\nb: 2\n"), r"another document"),
    Hostile("deep-flow", _const("a: " + "[" * 5000 + "]" * 5000 + "\n"), r"nested more than 100 levels"),
    Hostile(
        "deep-block",
        _const("".join(" " * i + f"k{i}:\n" for i in range(300)) + " " * 300 + "v: 1\n"),
        r"nested more than 100 levels",
    ),
    Hostile("huge-int", _replace_first_number("1" + "0" * 5000), r"digits|integer|too (large|long)"),
    Hostile("lone-surrogate", _append('bad: "\\ud800"\n'), r"not valid Unicode"),
    Hostile("top-list", _const("- 1\n- 2\n"), r"."),
    Hostile("top-scalar", _const("hello\n"), r"."),
]
HOSTILE_JSON = [
    Hostile("top-list", _const("[1, 2]\n"), r"."),
    Hostile("top-number", _const("1\n"), r"."),
    Hostile("top-string", _const('"x"\n'), r"."),
    Hostile("top-null", _const("null\n"), r"."),
    Hostile("duplicate-key", _duplicate_first_json_key, r"duplicate key"),
    Hostile("int-1e30", _replace_first_number("1" + "0" * 30), r"."),
    Hostile("int-5000-digits", _replace_first_number("1" + "0" * 5000), r"digits|integer|too (large|long)"),
    Hostile("nan", _replace_first_number("NaN"), r"(?i)\bNaN\b"),
    Hostile("infinity", _replace_first_number("-Infinity"), r"(?i)\binf"),
    Hostile("float-1e999", _replace_first_number("1e999"), r"(?i)1e999|\binf|finite"),
    Hostile("deep", _const("[" * 100_000 + "]" * 100_000), r"nested (more than 100 levels|too deep)"),
    Hostile(
        "deep-object", _const('{"a": ' * 5000 + "1" + "}" * 5000), r"nested (more than 100 levels|too deep)"
    ),
    Hostile("lone-surrogate", lambda s, _: s.replace('"', '"\\ud800', 1), r"not valid Unicode"),
    Hostile("truncated", lambda s, _: s[: len(s) // 2], r"."),
]
HOSTILE_XML = [
    Hostile(
        "external-entity",
        lambda s, _: s.replace(
            "<robot", '<!DOCTYPE robot [<!ENTITY e SYSTEM "file:///etc/passwd">]>\n<robot', 1
        ).replace('name="', 'name="&e;', 1),
        r"entit|DOCTYPE|DTD",
    ),
    Hostile(
        "billion-laughs",
        lambda s, _: s.replace(
            "<robot",
            '<!DOCTYPE robot [<!ENTITY a "aaaaaaaaaa">'
            + "".join(
                f'<!ENTITY {c} "{("&" + p + ";") * 10}">' for p, c in zip("abcdefgh", "bcdefghi", strict=True)
            )
            + "]>\n<robot",
            1,
        ).replace('name="', 'name="&i;', 1),
        r"entit|DOCTYPE|DTD",
    ),
    Hostile("deep", lambda s, _: s.replace("</robot>", "<g>" * 5000 + "</g>" * 5000 + "</robot>"), r"."),
    Hostile("two-roots", lambda s, _: s + "<robot name='x'/>\n", r"not well-formed"),
    Hostile("truncated", lambda s, _: s[: len(s) // 2], r"not well-formed"),
    Hostile("not-xml", _const("{}\n"), r"."),
    Hostile("wrong-root", _const("<html><body/></html>\n"), r"robot"),
    Hostile("bad-char-ref", lambda s, _: s.replace('name="', 'name="&#0;', 1), r"not well-formed"),
]
HOSTILE = {"yaml": HOSTILE_YAML, "json": HOSTILE_JSON, "xml": HOSTILE_XML}


def _cases() -> list[tuple[Reader, Hostile]]:
    return [(r, h) for r in READERS for h in HOSTILE[r.kind]]


def _setup(root: Path, reader: Reader, hostile: Hostile) -> Path:
    for sub, files in reader.trees.items():
        seeds.write_tree(root / sub, files)
    for rel, content in reader.files.items():
        p = root / rel
        p.parent.mkdir(parents=True, exist_ok=True)
        p.write_bytes(content)
    target = root / reader.target
    text = hostile.make(reader.files[reader.target].decode(), reader.number)
    target.write_bytes(text.encode("utf-8", "surrogatepass"))
    return target


def _assert_refused(
    reader: Reader, hostile: Hostile, root: Path, code: int, err: str, before: object
) -> None:
    where = f"{reader.name} / {hostile.name}: robocal {' '.join(reader.args)} (exit {code})\n{err[-2000:]}"
    assert "Traceback" not in err, where
    assert code == 2, where
    lines = [ln for ln in err.splitlines() if ln.startswith("error:")]
    assert len(lines) == 1, where
    name = Path(reader.target).name
    assert name in lines[0], f"{where}\nthe error line does not name {name}"
    assert re.search(hostile.says, lines[0].split(name, 1)[1]), f"{where}\nexpected /{hostile.says}/"
    for said in ("invalid JSON", "invalid YAML", "not well-formed"):
        assert lines[0].count(said) <= 1, f"{where}\n{said!r} said twice"
    assert snapshot(root) == before, f"{where}\nfiles changed"


# The fast tier (`-m "not slow"`) feeds every reader the first hostile document of its kind; the full suite all.
@pytest.mark.parametrize(
    ("reader", "hostile"),
    [
        pytest.param(r, h, id=f"{r.name}-{h.name}", marks=() if h is HOSTILE[r.kind][0] else pytest.mark.slow)
        for r, h in _cases()
    ],
)
def test_reader_refuses_hostile_document_through_the_cli(
    reader: Reader,
    hostile: Hostile,
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str],
) -> None:
    root = tmp_path / "run"
    root.mkdir()
    _setup(root, reader, hostile)
    home = tmp_path / "home"
    home.mkdir()
    for key in ("HOME", "HF_HOME", "HF_LEROBOT_HOME", "HF_LEROBOT_CALIBRATION", "XDG_STATE_HOME"):
        monkeypatch.setenv(key, str(home))
    monkeypatch.chdir(root)
    before = snapshot(root)
    code = main(list(reader.args))
    _out, err = capsys.readouterr()
    if hostile.name in reader.accepts:
        assert code in (0, 1) and "error:" not in err and "Traceback" not in err, err
        return
    _assert_refused(reader, hostile, root, code, err, before)


@pytest.mark.parametrize(
    "kind",
    [pytest.param("yaml", marks=pytest.mark.slow), "json", pytest.param("xml", marks=pytest.mark.slow)],
)
def test_one_hostile_document_per_kind_in_a_real_process(kind: str, tmp_path: Path) -> None:
    """The same through ``python -m robocal`` (the installed entry point): no traceback reaches the terminal."""
    reader = next(r for r in READERS if r.kind == kind)
    hostile = HOSTILE[kind][0]
    root = tmp_path / "run"
    root.mkdir()
    _setup(root, reader, hostile)
    before = snapshot(root)
    proc = subprocess.run(
        [sys.executable, "-m", "robocal", *reader.args],
        cwd=root,
        env={"PATH": "/usr/bin:/bin", "HOME": str(tmp_path), "COLUMNS": "200"},
        capture_output=True,
        text=True,
        timeout=120,
        check=False,
    )
    _assert_refused(reader, hostile, root, proc.returncode, proc.stderr, before)


@pytest.mark.slow
def test_the_seed_of_every_reader_is_accepted(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """Without a hostile document every listed command gets past its reader (so a refusal above is the
    document's, not a broken command line)."""
    for reader in READERS:
        root = tmp_path / reader.name
        root.mkdir()
        _setup(root, reader, Hostile("seed", lambda s, _: s, "."))
        monkeypatch.chdir(root)
        code = main(list(reader.args))
        _out, err = capsys.readouterr()
        assert reader.target not in err or code in (0, 1), f"{reader.name}: exit {code}\n{err}"


# ------------------------------------------------------------------------------ every parse call is listed
_PARSERS = {"load_yaml", "load_yaml_ruamel", "load_json", "loads", "load", "fromstring", "parse", "XML"}
_MODULES = {"json", "etree", "_yaml", "yaml"}


def _parse_sites() -> set[str]:
    """``module:function`` (the innermost function) of every YAML / JSON / XML parser call in src/robocal."""
    sites: set[str] = set()

    class Visitor(ast.NodeVisitor):
        def __init__(self, rel: str) -> None:
            self.rel = rel
            self.stack: list[str] = ["<module>"]

        def visit_FunctionDef(self, node: ast.FunctionDef | ast.AsyncFunctionDef) -> None:
            self.stack.append(node.name)
            self.generic_visit(node)
            self.stack.pop()

        visit_AsyncFunctionDef = visit_FunctionDef  # noqa: N815

        def visit_Call(self, node: ast.Call) -> None:
            f = node.func
            direct = isinstance(f, ast.Name) and f.id in {"load_yaml", "load_json", "load_yaml_ruamel"}
            method = (
                isinstance(f, ast.Attribute)
                and f.attr in _PARSERS
                and isinstance(f.value, ast.Name)
                and f.value.id in _MODULES
            )
            if direct or method:
                sites.add(f"{self.rel}:{self.stack[-1]}")
            self.generic_visit(node)

    for path in sorted(SRC.rglob("*.py")):
        rel = path.relative_to(SRC).with_suffix("").as_posix().replace("/", ".")
        if rel in {"formats._yaml", "formats._json", "formats._yaml_fast"}:
            continue  # the parsers themselves
        Visitor(rel).visit(ast.parse(path.read_text(encoding="utf-8")))
    return sites


@pytest.mark.slow
def test_every_parse_call_in_src_is_listed() -> None:
    """A new YAML/JSON/XML reader must be added to READERS (with a command reaching it) or NOT_FILE_READERS."""
    found = _parse_sites()
    listed = {s for r in READERS for s in r.sites} | set(NOT_FILE_READERS)
    assert sorted(found - listed) == [], "parse calls no READERS entry covers: add them to READERS"
    assert sorted(listed - found) == [], "READERS / NOT_FILE_READERS name parse calls that no longer exist"
