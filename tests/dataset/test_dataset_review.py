"""Regression tests from the review of the dataset area (each failed before its fix)."""

from __future__ import annotations

import json
import multiprocessing
import os
import shutil
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import pytest
from dataset_testutil import A, B, all_values, column, tree

from robocal.cli.main import main
from robocal.core.lerobot import LegacyCalibration
from robocal.dataset import (
    _driver,
    generate_dataset,
    inspect_dataset,
    recalibrate_dataset,
    recalibrate_table,
)
from robocal.dataset.lerobot import LegacyConvention
from robocal.errors import FileFormatError, UsageError
from robocal.formats import write_calibration

VIDEO = "videos/observation.images.front/chunk-000/file-000.mp4"


@pytest.fixture()
def src(tmp_path: Path) -> Path:
    root = tmp_path / "src"
    generate_dataset(root, n_episodes=4, frames_per_episode=[30, 40, 25, 12], convention=A)
    return root


def _split_episode_across_files(root: Path) -> None:
    """Move the second half of episode 2 (file-001) into a new file of a second chunk, in two row groups."""
    path = root / "data/chunk-000/file-001.parquet"
    table = pq.read_table(path)
    pq.write_table(table.slice(0, 10), path, row_group_size=10)
    (root / "data/chunk-001").mkdir()
    with pq.ParquetWriter(root / "data/chunk-001/file-000.parquet", table.schema) as writer:
        writer.write_table(table.slice(10, 7), row_group_size=7)
        writer.write_table(table.slice(17), row_group_size=100)


def test_episode_spanning_files_has_exact_quantiles(src: Path, tmp_path: Path) -> None:
    _split_episode_across_files(src)
    rep = recalibrate_dataset(src, tmp_path / "dst", A, B, workers=2)
    assert (rep.files, rep.frames) == (3, 107)
    values = all_values(tmp_path / "dst", "action")
    episodes = np.concatenate(
        [
            np.asarray(pq.read_table(p).column("episode_index"))
            for p in sorted((tmp_path / "dst").glob("data/chunk-*/file-*.parquet"))
        ]
    )
    rows = pq.read_table(tmp_path / "dst/meta/episodes/chunk-000/file-000.parquet").to_pylist()
    for row in rows:
        seg = values[episodes == row["episode_index"]]
        assert row["stats/action/count"] == [len(seg)]
        for name, f in (("q01", 0.01), ("q10", 0.1), ("q50", 0.5), ("q90", 0.9), ("q99", 0.99)):
            np.testing.assert_allclose(row[f"stats/action/{name}"], np.quantile(seg, f, axis=0), rtol=1e-12)
        np.testing.assert_allclose(row["stats/action/std"], seg.std(axis=0), rtol=1e-9)


def test_dangling_symlink_destination(src: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    write_calibration(tmp_path / "a.yaml", A.calibration, "robocal")
    (tmp_path / "dst").symlink_to(tmp_path / "nowhere")
    args = [
        str(src),
        str(tmp_path / "dst"),
        "--old",
        str(tmp_path / "a.yaml"),
        "--new",
        str(tmp_path / "a.yaml"),
    ]
    code = main(["dataset", "recalibrate", *args])
    err = capsys.readouterr().err
    assert code == 2
    assert err.count("\n") == 1 and "is a broken symbolic link" in err
    with pytest.raises(UsageError, match="broken symbolic link"):
        recalibrate_dataset(src, tmp_path / "dst", A, B)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.yaml", "dst", "src"]


def test_symlinked_videos_and_folders(src: Path, tmp_path: Path) -> None:
    # a Hugging Face cache snapshot: files are relative links into a blob store; here also a linked folder
    store = tmp_path / "blobs"
    store.mkdir()
    (src / VIDEO).rename(store / "video")
    (src / VIDEO).symlink_to(os.path.relpath(store / "video", (src / VIDEO).parent))
    shutil.move(str(src / "meta/tasks.parquet"), store / "tasks")
    (src / "meta/tasks.parquet").symlink_to(store / "tasks")
    (tmp_path / "extra").mkdir()
    (tmp_path / "extra/notes.txt").write_text("kept")
    (src / "docs").symlink_to(tmp_path / "extra")
    nested = tmp_path / "deeper" / "out"
    nested.parent.mkdir()
    recalibrate_dataset(src, nested, A, B)
    assert tree(nested) == sorted([*tree(src), "docs/notes.txt"])
    out_video = nested / VIDEO
    assert not out_video.is_symlink()
    assert out_video.read_bytes() == (store / "video").read_bytes()
    assert out_video.stat().st_ino == (store / "video").stat().st_ino  # hard link to the real file
    assert not (nested / "meta/tasks.parquet").is_symlink()
    assert (nested / "docs/notes.txt").read_text() == "kept"


def test_broken_symlink_in_source_is_an_error(src: Path, tmp_path: Path) -> None:
    (src / "videos/broken.mp4").symlink_to(tmp_path / "missing.mp4")
    with pytest.raises(FileFormatError, match=r"videos/broken\.mp4 is a broken symbolic link"):
        recalibrate_dataset(src, tmp_path / "dst", A, B)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["src"]


def _slow_work(args: tuple[str, str, str, list[object]]) -> object:
    import time

    with open(os.environ["ROBOCAL_TEST_LOG"], "a") as log:
        log.write(args[2] + "\n")
    time.sleep(0.05)
    return _driver.recalibrate_file(*args[:2], args[3], args[2])  # type: ignore[arg-type]


@pytest.mark.skipif(multiprocessing.get_start_method() != "fork", reason="patches the worker function")
def test_interrupt_cancels_queued_files(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    src = tmp_path / "src"
    generate_dataset(src, n_episodes=20, frames_per_episode=5, episodes_per_file=1, convention=A)
    log = tmp_path.parent / f"{tmp_path.name}.log"
    monkeypatch.setenv("ROBOCAL_TEST_LOG", str(log))
    monkeypatch.setattr(_driver, "_work", _slow_work)

    def interrupt(path: str, frames: int) -> None:
        raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        recalibrate_dataset(src, tmp_path / "dst", A, B, workers=2, on_file_done=interrupt)
    started = log.read_text().splitlines()
    log.unlink()
    assert len(started) < 20  # the queued files were dropped, not converted into a folder being deleted
    assert multiprocessing.active_children() == []
    assert sorted(p.name for p in tmp_path.iterdir()) == ["src"]


def test_empty_dataset(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    src = tmp_path / "src"
    generate_dataset(src, n_episodes=1, frames_per_episode=5, convention=A)
    info = json.loads((src / "meta/info.json").read_text())
    info.update(total_frames=0, total_episodes=0)
    (src / "meta/info.json").write_text(json.dumps(info))
    shutil.rmtree(src / "data")
    (src / "meta/episodes/chunk-000/file-000.parquet").unlink()
    rep = recalibrate_dataset(src, tmp_path / "dst", A, B, workers=2)
    assert (rep.frames, rep.files, rep.row_groups) == (0, 0, 0)
    files = [rel for rel in tree(src) if (src / rel).is_file()]
    assert [rel for rel in tree(tmp_path / "dst") if (tmp_path / "dst" / rel).is_file()] == files
    assert "meta/stats.json" in files
    summary = inspect_dataset(src, calibration=A)
    assert summary.frames == 0 and summary.flagged == ()
    assert np.isnan(summary.joints[0].min) and np.isnan(summary.joints[0].mean)


def test_recalibrate_table_bad_inputs() -> None:
    vals = pa.FixedSizeListArray.from_arrays(pa.array(np.zeros(12, np.float32)), 6)
    table = pa.table({"action": vals})
    with pytest.raises(UsageError, match=r"feature 'action': no new calibration for it \(given for: obs\)"):
        recalibrate_table(table, {"action": A}, {"obs": B})
    with pytest.raises(
        UsageError, match=r"none of the columns observation\.state, action; name the features"
    ):
        recalibrate_table(pa.table({"joints": vals}), A, B)
    with pytest.raises(UsageError, match=r"expected a pyarrow\.Table, got FixedSizeListArray"):
        recalibrate_table(vals, A, B)  # type: ignore[arg-type]
    with pytest.raises(UsageError, match="the old calibration is a str; expected a ValueConvention"):
        recalibrate_table(table, "a.json", B)  # type: ignore[arg-type]
    ints = pa.FixedSizeListArray.from_arrays(pa.array(np.zeros(12, np.int64)), 6)
    with pytest.raises(FileFormatError, match=r"'action': expected fixed_size_list<float>, found fixed_size"):
        recalibrate_table(pa.table({"action": ints}), A, B)


def test_dataset_per_feature_mapping_without_the_feature(src: Path, tmp_path: Path) -> None:
    with pytest.raises(UsageError, match="feature 'action': no old calibration for it"):
        recalibrate_dataset(src, tmp_path / "dst", {"observation.state": A}, B)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["src"]


def test_inspect_counts_and_flags_nan(src: Path) -> None:
    path = src / "data/chunk-000/file-000.parquet"
    table = pq.read_table(path)
    vals = column(path, "action").astype(np.float32)
    vals[3, 2] = np.nan
    vals[4, 2] = np.inf
    col = pa.FixedSizeListArray.from_arrays(pa.array(vals.ravel()), 6)
    pq.write_table(table.set_column(1, table.schema.field(1), col), path)
    rep = inspect_dataset(src, features=["action"])
    elbow = next(j for j in rep.joints if j.joint == "elbow_flex")
    assert elbow.non_finite == 2 and elbow.flagged
    finite = vals[np.isfinite(vals[:, 2]), 2]
    assert elbow.min <= finite.min() and np.isfinite(elbow.max) and np.isfinite(elbow.mean)
    assert [j.joint for j in rep.flagged] == ["elbow_flex"]


def test_legacy_degree_motor_with_equal_start_and_end() -> None:
    # start_pos/end_pos only matter for LINEAR motors
    cal = LegacyCalibration(["j"], [-2048], [0], [0], [0], ["DEGREE"])
    values, mask = LegacyConvention(cal).from_actual(np.array([[3072.0]]))
    assert values.tolist() == [[90.0]] and not mask.any()


def test_overwrite_keeps_old_destination_when_the_final_rename_fails(
    src: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    dst = tmp_path / "dst"
    dst.mkdir()
    (dst / "keep.txt").write_text("old")
    real_replace = os.replace

    def failing_replace(a: object, b: object) -> None:
        if Path(str(a)).name.startswith(".dst.robocal-"):
            raise OSError(28, "No space left on device")
        real_replace(a, b)  # type: ignore[arg-type]

    monkeypatch.setattr(os, "replace", failing_replace)
    with pytest.raises(FileFormatError, match=r"cannot move the new dataset into place \(No space left"):
        recalibrate_dataset(src, dst, A, B, overwrite=True)
    assert (dst / "keep.txt").read_text() == "old"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["dst", "src"]


def test_relative_paths_and_dot_destination(
    src: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    write_calibration(tmp_path / "a.yaml", A.calibration, "robocal")
    write_calibration(tmp_path / "b.yaml", B.calibration, "robocal")
    recalibrate_dataset(src, tmp_path / "ref", A, B)
    monkeypatch.chdir(tmp_path)
    code = main(["dataset", "recalibrate", "src", "out", "--old", "a.yaml", "--new", "b.yaml"])
    assert (code, capsys.readouterr().err) == (0, "")
    np.testing.assert_array_equal(
        all_values(tmp_path / "out", "action"), all_values(tmp_path / "ref", "action")
    )
    shutil.rmtree(tmp_path / "ref")
    # DST "." (the current folder) with --overwrite: replaced as a whole
    monkeypatch.chdir(tmp_path / "out")
    code = main(
        ["dataset", "recalibrate", "../src", ".", "--old", "../a.yaml", "--new", "../a.yaml", "--overwrite"]
    )
    assert (code, capsys.readouterr().err) == (0, "")
    monkeypatch.chdir(tmp_path)
    np.testing.assert_array_equal(all_values(tmp_path / "out", "action"), all_values(src, "action"))
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.yaml", "b.yaml", "out", "src"]


def _dying_work(args: object) -> object:
    os._exit(1)  # a worker killed mid-file (e.g. by the OOM killer)


def test_dead_worker_is_one_error_not_a_traceback(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    src = tmp_path / "src"
    generate_dataset(src, n_episodes=4, frames_per_episode=5, episodes_per_file=1, convention=A)
    monkeypatch.setattr(_driver, "_work", _dying_work)
    with pytest.raises(_driver.DatasetWorkerError, match="worker process died") as info:
        recalibrate_dataset(src, tmp_path / "dst", A, B, workers=2)
    assert info.value.exit_code == 3
    assert multiprocessing.active_children() == []
    assert sorted(p.name for p in tmp_path.iterdir()) == ["src"]
