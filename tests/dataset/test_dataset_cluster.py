from __future__ import annotations

from pathlib import Path

import numpy as np
import pyarrow.parquet as pq
import pytest
from dataset_testutil import A, B, all_values, tree

from robocal.dataset import generate_dataset, recalibrate_dataset
from robocal.errors import FileFormatError

pytest.importorskip("datatrove")

from robocal.dataset.cluster import finish, prepare, recalibrate_with_datatrove


@pytest.fixture(scope="module")
def src(tmp_path_factory: pytest.TempPathFactory) -> Path:
    root = tmp_path_factory.mktemp("cluster") / "src"
    generate_dataset(
        root, n_episodes=6, frames_per_episode=[20, 31, 17, 40, 22, 9], episodes_per_file=2, convention=A
    )
    return root


@pytest.mark.slow
@pytest.mark.parametrize(("tasks", "workers"), [(1, 1), pytest.param(3, 2, marks=pytest.mark.slow)])
def test_datatrove_matches_local_engine(src: Path, tmp_path: Path, tasks: int, workers: int) -> None:
    local = recalibrate_dataset(src, tmp_path / "local", A, B)
    dt = recalibrate_with_datatrove(src, tmp_path / "dt", A, B, tasks=tasks, workers=workers)
    assert (
        (dt.frames, dt.files, dt.row_groups) == (local.frames, local.files, local.row_groups) == (139, 3, 6)
    )
    assert dt.out_of_range == local.out_of_range
    assert tree(tmp_path / "dt") == tree(tmp_path / "local")
    for rel in ("meta/stats.json", "meta/info.json", "meta/episodes/chunk-000/file-000.parquet"):
        if rel.endswith(".json"):
            assert (tmp_path / "dt" / rel).read_text() == (tmp_path / "local" / rel).read_text()
        else:
            assert pq.read_table(tmp_path / "dt" / rel).equals(pq.read_table(tmp_path / "local" / rel))
    for key in ("observation.state", "action"):
        np.testing.assert_array_equal(all_values(tmp_path / "dt", key), all_values(tmp_path / "local", key))
    # nothing but the two roots is left next to them (no work or log folders)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["dt", "local"]


def test_unfinished_cluster_run_publishes_nothing(src: Path, tmp_path: Path) -> None:
    job = prepare(src, tmp_path / "dst", A, B)  # no task ran
    with pytest.raises(FileFormatError, match=r"data file data/chunk-000/file-000.parquet: no result"):
        finish(job)
    assert list(tmp_path.iterdir()) == []
