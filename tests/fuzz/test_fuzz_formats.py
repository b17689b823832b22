"""Fuzz every file reader with mutated valid inputs: only CalibError may escape and nothing may be written.

Readers covered: the calibration formats (lite-json, lite-yaml, berkeley-offsets, ros2-transmission URDF,
robocal, lerobot-legacy, with and without format detection), URDF, LeRobot current JSON, UR DH / deltas YAML,
``calibration.conf`` and kinematics YAML, replay CSV, rosbag2 (sqlite3 and mcap) and LeRobot v3 dataset metadata.
"""

from __future__ import annotations

import contextlib
import functools
import json
import math
import re
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest
import seeds
from fuzzlib import (
    byte_mutation,
    deep_json,
    encode_text,
    fuzz_settings,
    json_mutation,
    only_calib_error,
    reader_raises_only_calib_error,
    scratch,
    snapshot,
    text_mutation,
    yaml_mutation,
)
from hypothesis import given
from hypothesis import strategies as st

from robocal.core.ur import default_kinematics
from robocal.errors import CalibError, FileFormatError
from robocal.formats import detect_format, read_calibration
from robocal.formats.lerobot import read_current, read_legacy
from robocal.formats.ur_kinematics import kinematics_to_text, read_deltas, read_dh, read_kinematics
from robocal.formats.urdf import UrdfDocument, parse_urdf, read_urdf

SEEDS = seeds.calibration_seeds()
LITE_URDF = seeds.lite_urdf_text()
JSON_FORMATS = ["lite-json", "berkeley-offsets", "lerobot-legacy"]
YAML_FORMATS = ["lite-yaml", "lite-yaml-commented", "robocal"]
_ELEMENT = re.compile(rb"<(joint|transmission|link|param)\b.*?(?:/>|</\1>)", re.S)


@functools.cache
def _yaml_tree(text: str) -> Any:
    from robocal.formats._yaml import load_yaml

    return json.loads(json.dumps(load_yaml(text, "seed")))


def xml_mutation(data: st.DataObject, seed: bytes) -> bytes:
    """Text/byte mutations plus XML ones: a duplicated element, deep nesting, odd attribute values."""
    kind = data.draw(st.sampled_from(["text", "dup-element", "nest", "entity"]), label="xml")
    if kind == "dup-element":
        spans = [m.span() for m in _ELEMENT.finditer(seed)]
        a, b = data.draw(st.sampled_from(spans), label="element")
        return seed[:b] + seed[a:b] + seed[b:]
    if kind == "nest":
        depth = data.draw(st.sampled_from([10, 300, 5000]), label="depth")
        i = seed.index(b"<link")
        return seed[:i] + b"<g>" * depth + seed[i:].replace(b"</robot>", b"</g>" * depth + b"</robot>")
    if kind == "entity":
        return seed.replace(
            b"<robot",
            b'<!DOCTYPE robot [<!ENTITY x "&#xD800;"><!ENTITY e SYSTEM "file:///etc/passwd">]>\n<robot',
            1,
        ).replace(b'name="left_wrist_roll"', b'name="&e;&x;"', 1)
    return text_mutation(data, seed)


def mutated_calibration(data: st.DataObject, fmt: str) -> bytes:
    seed = SEEDS[fmt]
    if fmt in JSON_FORMATS and fmt != "berkeley-offsets":
        return json_mutation(data, seed.decode())
    if fmt in YAML_FORMATS or fmt == "berkeley-offsets":
        return yaml_mutation(data, seed.decode(), _yaml_tree(seed.decode()))
    return xml_mutation(data, seed)


def _read_all_ways(p: Path, fmt: str) -> None:
    """Explicit format, detection, and (berkeley) the URDF-supplied order."""
    name = fmt.replace("-commented", "")
    kwargs: dict[str, Any] = {}
    if name == "berkeley-offsets":
        kwargs = {"urdf": parse_urdf(LITE_URDF)}
    with contextlib.suppress(CalibError):
        read_calibration(p, name, **kwargs)
    try:
        detected = detect_format(p)
    except CalibError:
        return
    read_calibration(p, detected, **kwargs)


@pytest.mark.slow
@pytest.mark.parametrize("fmt", [*JSON_FORMATS, *YAML_FORMATS, "ros2-transmission"])
@fuzz_settings(60)
@given(data=st.data())
def test_calibration_readers_raise_only_calib_error(fmt: str, data: st.DataObject) -> None:
    blob = mutated_calibration(data, fmt)
    suffix = {"ros2-transmission": ".urdf"}.get(
        fmt, ".yaml" if "yaml" in fmt or fmt == "robocal" else ".json"
    )
    reader_raises_only_calib_error(
        blob, f"calibration{suffix}", lambda p: _read_all_ways(p, fmt), f"{fmt} reader"
    )


@pytest.mark.slow
@pytest.mark.parametrize("fmt", ["berkeley-offsets", "ros2-transmission"])
@fuzz_settings(60)
@given(data=st.data())
def test_calibration_readers_with_a_mutated_urdf(fmt: str, data: st.DataObject) -> None:
    """The URDF a positional format leans on (directions, order, ids) is itself mutated."""
    urdf_blob = xml_mutation(data, LITE_URDF.encode())
    with scratch() as root:
        cal = root / ("c.yaml" if fmt == "berkeley-offsets" else "c.urdf")
        cal.write_bytes(SEEDS[fmt] if fmt == "berkeley-offsets" else urdf_blob)
        u = root / "robot.urdf"
        u.write_bytes(urdf_blob)

        def run() -> None:
            read_calibration(cal, fmt, urdf=read_urdf(u))

        only_calib_error(run, root, f"{fmt} reader with a mutated URDF")


def _use_urdf(p: Path) -> None:
    model = read_urdf(p)
    for name in model.joint_names:
        model.joint(name)
        model.direction(name)
        model.motor_id(name)
        model.limits(name)
    assert set(model.calibration_joint_names()) <= set(model.joint_names) | set(
        model.ros2_control_joint_names
    )
    doc = UrdfDocument.load(p)
    doc.to_bytes()


@pytest.mark.slow
@fuzz_settings(100)
@given(data=st.data())
def test_urdf_reader_raises_only_calib_error(data: st.DataObject) -> None:
    blob = xml_mutation(data, LITE_URDF.encode())
    reader_raises_only_calib_error(blob, "robot.urdf", _use_urdf, "URDF reader")


@pytest.mark.slow
@fuzz_settings(100)
@given(data=st.data())
def test_lerobot_current_reader_raises_only_calib_error(data: st.DataObject) -> None:
    blob = json_mutation(data, seeds.current_seed())
    reader_raises_only_calib_error(blob, "so101_follower.json", read_current, "LeRobot current reader")


@pytest.mark.slow
@fuzz_settings(100)
@given(data=st.data())
def test_lerobot_legacy_reader_raises_only_calib_error(data: st.DataObject) -> None:
    from robocal.lerobot.legacy import to_robot_calibration

    blob = json_mutation(data, seeds.legacy_seed())
    reader_raises_only_calib_error(
        blob, "main_follower.json", lambda p: to_robot_calibration(read_legacy(p)), "LeRobot legacy reader"
    )


UR_SEEDS = {
    "dh.yaml": (seeds.DH_YAML, read_dh),
    "deltas.yaml": (seeds.DELTAS_YAML, read_deltas),
    "calibration.conf": (seeds.CALIBRATION_CONF, read_deltas),
}


@pytest.mark.slow
@pytest.mark.parametrize("name", list(UR_SEEDS))
@fuzz_settings(60)
@given(data=st.data())
def test_ur_dh_and_deltas_readers_raise_only_calib_error(name: str, data: st.DataObject) -> None:
    text, reader = UR_SEEDS[name]
    if name.endswith(".yaml") and data.draw(st.booleans(), label="tree?"):
        blob = yaml_mutation(data, text, _yaml_tree(text))
    else:
        blob = text_mutation(data, text.encode())
    reader_raises_only_calib_error(blob, name, lambda p: reader(p, warnings=[]), f"UR {name} reader")


@pytest.mark.slow
@fuzz_settings(50)
@given(data=st.data())
def test_ur_kinematics_reader_raises_only_calib_error(data: st.DataObject) -> None:
    text = kinematics_to_text(default_kinematics("ur10e"))
    blob = yaml_mutation(data, text, _yaml_tree(text))
    reader_raises_only_calib_error(blob, "ur10e_calibration.yaml", read_kinematics, "UR kinematics reader")


def csv_mutation(data: st.DataObject, seed: str) -> bytes:
    kind = data.draw(st.sampled_from(["text", "cell", "dup-column", "header"]), label="csv")
    lines = seed.splitlines()
    if kind == "cell":
        r = data.draw(st.integers(0, len(lines) - 1), label="row")
        cells = lines[r].split(",")
        c = data.draw(st.integers(0, len(cells) - 1), label="col")
        from fuzzlib import HUGE_NUMBERS, ODD_TEXT, RAW_TOKENS

        cells[c] = data.draw(
            st.one_of(
                st.sampled_from(RAW_TOKENS),
                st.sampled_from(ODD_TEXT),
                st.sampled_from([repr(x) for x in HUGE_NUMBERS]),
            ),
            label="cell",
        )
        lines[r] = ",".join(cells)
        return encode_text(data, "\n".join(lines) + "\n")
    if kind == "dup-column":
        lines = [ln + "," + ln.split(",")[1] for ln in lines]
        return "\n".join(lines).encode()
    if kind == "header":
        return encode_text(data, '"t",' + '"a""b",' + lines[0][2:] + "\n" + "\n".join(lines[1:]))
    return text_mutation(data, seed.encode())


@pytest.mark.slow
@fuzz_settings(100)
@given(data=st.data())
def test_replay_csv_reader_raises_only_calib_error(data: st.DataObject) -> None:
    from robocal.backends.replay import read_recording

    blob = csv_mutation(data, seeds.csv_seed())
    reader_raises_only_calib_error(
        blob, "sweep.csv", lambda p: read_recording(p, seeds.LITE_NAMES), "replay CSV reader"
    )


@pytest.mark.slow
@pytest.mark.parametrize("plugin", ["sqlite3", "mcap"])
@fuzz_settings(40)
@given(data=st.data())
def test_rosbag_reader_raises_only_calib_error(plugin: str, data: st.DataObject) -> None:
    from robocal.backends.replay import read_recording

    files = dict(seeds.bag_seed(plugin))
    target = data.draw(st.sampled_from(sorted(files)), label="file")
    if target == "metadata.yaml":
        text = files[target].decode()
        files[target] = yaml_mutation(data, text, _yaml_tree(text))
    else:
        files[target] = byte_mutation(data, files[target])
    how = data.draw(st.sampled_from(["folder", "file"]), label="open")
    with scratch() as root:
        bag = root / "bag"
        seeds.write_tree(bag, files)
        path = bag if how == "folder" else next(bag.glob("*.db3"), None) or next(bag.glob("*.mcap"), bag)
        only_calib_error(lambda: read_recording(path, seeds.LITE_NAMES), root, f"rosbag2 {plugin} reader")


DATASET_META = ["meta/info.json", "meta/stats.json"]


@pytest.mark.slow
@fuzz_settings(40)
@given(data=st.data())
def test_dataset_inspect_raises_only_calib_error(data: st.DataObject) -> None:
    """inspect reads info.json, stats and the parquet files: each of them is mutated in turn."""
    from robocal.dataset import inspect_dataset

    files = dict(seeds.dataset_seed())
    target = data.draw(
        st.sampled_from(
            [*DATASET_META, "meta/episodes/chunk-000/file-000.parquet", "data/chunk-000/file-000.parquet"]
        ),
        label="file",
    )
    if target.endswith(".json"):
        files[target] = json_mutation(data, files[target].decode())
    else:
        files[target] = byte_mutation(data, files[target])
    with scratch() as root:
        ds = root / "ds"
        seeds.write_tree(ds, files)
        only_calib_error(lambda: inspect_dataset(ds), root, f"dataset inspect ({target} mutated)")


# -------------------------------------------------- deep nesting and huge integers (issue 9 item 6)
DEEP = {
    "lite-json": "c.json",
    "berkeley-offsets": "c.json",
    "lerobot-legacy": "c.json",
    "lite-yaml": "c.yaml",
    "robocal": "c.yaml",
    None: "c.json",
}


@pytest.mark.parametrize("depth", [1_000, 100_000])
@pytest.mark.parametrize("objects", [False, True], ids=["lists", "objects"])
@pytest.mark.parametrize("fmt", list(DEEP), ids=[str(k) for k in DEEP])
def test_deeply_nested_documents_are_refused(fmt: str | None, objects: bool, depth: int) -> None:
    with scratch() as root:
        p = root / DEEP[fmt]
        p.write_text(deep_json(depth, objects))
        before = snapshot(root)
        with pytest.raises(FileFormatError, match=re.escape(str(p))):
            read_calibration(p, fmt)
        assert snapshot(root) == before


def test_legacy_integer_of_10_to_the_30_is_refused() -> None:
    with scratch() as root:
        p = root / "legacy.json"
        p.write_text(seeds.legacy_seed().replace("-2048", str(10**30), 1))
        with pytest.raises(FileFormatError, match="homing_offset"):
            read_legacy(p)


# ------------------------------------------------------------------------------- seeds and found crashes
def test_seeds_are_valid_inputs() -> None:
    """The fuzzers mutate valid files: each seed reads back to the calibration it was written from."""
    expected = seeds.lite_calibration()
    with scratch() as root:
        for fmt in ("lite-json", "lite-yaml", "berkeley-offsets", "robocal", "ros2-transmission"):
            p = root / f"{fmt}.{'urdf' if fmt == 'ros2-transmission' else 'txt'}"
            p.write_bytes(SEEDS[fmt])
            assert detect_format(p) == fmt
            cf = read_calibration(p, fmt, urdf=parse_urdf(LITE_URDF))
            assert cf.calibration.joint_names == expected.joint_names
            assert list(cf.calibration.homing_offset) == pytest.approx(list(expected.homing_offset), abs=1e-9)
        p = root / "current.json"
        p.write_text(seeds.current_seed())
        assert read_current(p)["elbow_flex"].range_max == 3100
        p.write_text(seeds.legacy_seed())
        assert read_legacy(p).calib_mode[-1] == "LINEAR"
        for name, (text, reader) in UR_SEEDS.items():
            p = root / name
            p.write_text(text)
            assert len(reader(p, warnings=[]).d_m) == 6


@pytest.mark.parametrize("fmt", ["lite-yaml", "robocal"])
def test_yaml_integer_beyond_the_int_string_limit_is_a_file_format_error(fmt: str) -> None:
    """Found by the fuzzer: ruamel's ValueError for an int of > 4300 digits escaped as a traceback."""
    with scratch() as root:
        p = root / "c.yaml"
        p.write_bytes(SEEDS[fmt].replace(b"id: 11", b"id: 1" + b"0" * 5000, 1))
        with pytest.raises(FileFormatError, match=r"c\.yaml: invalid YAML \(line \d+, column \d+\): an integer of 5001 digits; robocal reads integers of at most 4300 digits"):
            read_calibration(p, fmt)


@pytest.mark.parametrize("kind", ["csv", "sqlite3", "mcap"])
def test_recording_seeds_are_valid(kind: str) -> None:
    from robocal.backends.replay import read_recording

    with scratch() as root:
        if kind == "csv":
            path = root / "sweep.csv"
            path.write_text(seeds.csv_seed())
            rows = 30
        else:
            path = root / "bag"
            seeds.write_tree(path, seeds.bag_seed(kind))
            rows = 10
        t, q = read_recording(path, seeds.LITE_NAMES)
        assert t[1] > t[0]
        assert q.shape == (rows, len(seeds.LITE_NAMES))
        assert q[3, 2] == pytest.approx(0.5 * math.sin(0.9 + 2))


HUGE_INT = "1" + "0" * 5000


def test_dataset_info_with_an_integer_beyond_the_int_string_limit_is_a_file_format_error() -> None:
    """Found by the fuzzer: json's ValueError for an int of > 4300 digits escaped from read_layout."""
    from robocal.dataset import inspect_dataset

    with scratch() as root:
        seeds.write_tree(root / "ds", seeds.dataset_seed())
        info = root / "ds" / "meta" / "info.json"
        info.write_text(info.read_text().replace('"fps": 30', f'"fps": {HUGE_INT}', 1))
        assert HUGE_INT in info.read_text()
        with pytest.raises(FileFormatError, match=r"info\.json: invalid JSON \(line \d+, column \d+\): an integer of 5001 digits; robocal reads integers of at most 4300 digits"):
            inspect_dataset(root / "ds")


def test_dataset_stats_with_an_integer_beyond_the_int_string_limit_is_a_file_format_error() -> None:
    from robocal.dataset import read_layout
    from robocal.dataset._metadata import check_metadata

    with scratch() as root:
        seeds.write_tree(root / "ds", seeds.dataset_seed())
        (root / "ds" / "meta" / "stats.json").write_text(f'{{"action": {{"count": [{HUGE_INT}]}}}}')
        with pytest.raises(FileFormatError, match=r"stats\.json: invalid JSON \(line 1, column 23\): an integer of 5001 digits; robocal reads integers of at most 4300 digits"):
            check_metadata(read_layout(root / "ds"))


def test_calibration_json_with_an_integer_beyond_the_int_string_limit_is_a_file_format_error() -> None:
    from robocal.dataset.lerobot import load_convention

    with scratch() as root:
        p = root / "cal.json"
        p.write_text(seeds.current_seed().replace('"homing_offset": 100', f'"homing_offset": {HUGE_INT}', 1))
        with pytest.raises(FileFormatError, match=r"cal\.json"):
            load_convention(p, joint_names=seeds.SO_NAMES)


@pytest.mark.parametrize(
    ("mutate", "message"),
    [
        (lambda text: text.replace("\n", "\r", 3).replace("0.01,", "0.01\r,", 1), None),
        (
            lambda text: text.replace("0.01,", "0.01" + "9" * 200_000 + ",", 1),
            r"sweep\.csv: .*field larger than field limit",
        ),
    ],
    ids=["bare-CR", "huge-field"],
)
def test_replay_csv_quirks_found_by_fuzzing(mutate: Callable[[str], str], message: str | None) -> None:
    """Found by the fuzzer: a bare CR inside a line (and an oversized field) raised csv.Error, a traceback."""
    from robocal.backends.replay import read_recording

    with scratch() as root:
        p = root / "sweep.csv"
        p.write_text(mutate(seeds.csv_seed()), newline="")
        if message is None:  # a bare CR ends a line, like in any CSV reader; the extra line is then short
            with pytest.raises(FileFormatError, match=r"sweep\.csv: line \d+ has \d+ cells; expected 15"):
                read_recording(p, seeds.LITE_NAMES)
        else:
            with pytest.raises(FileFormatError, match=message):
                read_recording(p, seeds.LITE_NAMES)


@pytest.mark.parametrize("fmt", ["lite-yaml", "robocal", None])
def test_yaml_reused_anchor_is_a_file_format_error(fmt: str | None) -> None:
    """Found by the thorough fuzz run: ruamel's ReusedAnchorWarning escaped (printed, or raised where warnings
    are errors) instead of the file being refused with its line. Every anchor is refused now, at the first."""
    with scratch() as root:
        p = root / "c.yaml"
        text = SEEDS["lite-yaml"].decode().replace("id: 11", "id: &a 11", 1).replace("id: 12", "id: &a 12", 1)
        p.write_text(text)
        with pytest.raises(
            FileFormatError, match=r"c\.yaml: invalid YAML \(line 2, column 7\): an anchor \(&a\)"
        ):
            read_calibration(p, fmt)


def test_subnormal_scale_is_refused() -> None:
    """Found by the thorough fuzz run: a robocal file with scale 5e-324 overflowed 1/scale (RuntimeWarning,
    an infinite inverse gain) instead of being refused."""
    from robocal.core.jointmap import RobotCalibration
    from robocal.errors import InvalidCalibrationError

    with pytest.raises(InvalidCalibrationError, match=r"joint 'a': scale 5e-324 must be finite and > 0"):
        RobotCalibration(["a"], [1], [0.0], [5e-324])
    assert RobotCalibration(["a"], [1], [0.0], [2.2250738585072014e-308]).scale[0] > 0
    with scratch() as root:
        p = root / "r.yaml"
        p.write_bytes(SEEDS["robocal"].replace(b"scale: 1.0", b"scale: 5e-324", 1))
        assert b"5e-324" in p.read_bytes()
        with pytest.raises(FileFormatError, match=r"r\.yaml.*scale 5e-324 must be finite and > 0"):
            read_calibration(p, "robocal")


def test_rosbag_metadata_with_a_non_integer_message_count_is_read() -> None:
    """Found by the thorough fuzz run: message_count: NaN in metadata.yaml crashed the progress total
    (TypeError) although the messages themselves are intact."""
    from robocal.backends.replay import read_recording

    with scratch() as root:
        files = dict(seeds.bag_seed("sqlite3"))
        files["metadata.yaml"] = files["metadata.yaml"].replace(b"message_count: 10", b"message_count: NaN")
        assert b"message_count: NaN" in files["metadata.yaml"]
        seeds.write_tree(root / "bag", files)
        _t, q = read_recording(root / "bag", seeds.LITE_NAMES)
        assert q.shape == (10, len(seeds.LITE_NAMES))


@pytest.mark.parametrize("plugin", ["sqlite3", "mcap"])
@pytest.mark.parametrize("name", ["null", "[]", "{a: 1}", "7"])
def test_rosbag_topic_name_that_is_not_a_string_is_a_damaged_metadata_error(
    tmp_path: Path, plugin: str, name: str
) -> None:
    """Found by the thorough run: a metadata.yaml topic name of null / a list escaped as a TypeError."""
    import re

    from robocal.backends.replay import read_recording

    bag = tmp_path / "bag"
    bag.mkdir()
    for rel, blob in seeds.bag_seed(plugin).items():
        (bag / rel).write_bytes(blob)
    meta = bag / "metadata.yaml"
    text, n = re.subn(r"name: /lite/joint_states", f"name: {name}", meta.read_text())
    assert n == 1
    meta.write_text(text)
    with pytest.raises(FileFormatError, match=r"damaged rosbag2 metadata: a topic entry has name"):
        read_recording(bag, seeds.LITE_NAMES)
