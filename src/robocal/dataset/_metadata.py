"""The dataset's statistics metadata: ``meta/stats.json`` and the ``stats/...`` columns of the episode files.

:func:`check_metadata` reads both before anything is written; after the data files are converted,
:func:`rewrite_episode_stats` and :func:`write_dataset_stats` replace the statistics of the converted features
(statistics robocal cannot recompute are kept and reported).
"""

from __future__ import annotations

import json
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import pyarrow as pa
import pyarrow.parquet as pq

from ..errors import FileFormatError
from ..fileio import MAX_DOCUMENT_BYTES, read_text
from ..formats._json import load_json
from ._layout import DatasetLayout
from ._stats import StatAccumulator, is_known_stat
from .teleop_frames import episode_numbers

__all__ = ["check_metadata", "rewrite_episode_stats", "write_dataset_stats"]


def check_metadata(layout: DatasetLayout) -> None:
    """Check ``meta/stats.json`` and the episode files can be rewritten, before anything is written.

    Raises:
        FileFormatError: Naming the file.
    """
    stats = layout.root / "meta" / "stats.json"
    if stats.is_file():
        _read_stats(stats)
    for rel in layout.episode_files:
        try:
            names = pq.read_schema(layout.root / rel).names
        except (pa.ArrowException, OSError) as exc:
            raise FileFormatError(f"episodes file {rel}: cannot read Parquet ({exc})") from None
        if "episode_index" not in names:
            raise FileFormatError(f"episodes file {rel}: no 'episode_index' column")


def _read_stats(path: Path) -> dict[str, Any]:
    data = load_json(read_text(path, "statistics JSON", limit=MAX_DOCUMENT_BYTES), str(path), item="feature")
    if not isinstance(data, dict):
        raise FileFormatError(f"{path}: expected a JSON object of features")
    return data


def rewrite_episode_stats(
    src: Path,
    dst: Path,
    episode_stats: Mapping[int, Mapping[str, StatAccumulator]],
    features: Sequence[str],
    rel: str = "",
    *,
    keep_missing: bool = False,
) -> list[str]:
    """Copy an episodes metadata file, replacing ``stats/<feature>/<stat>`` columns of ``features``.

    Row groups, schema and metadata are kept; statistics robocal cannot compute are left out of the
    replacement and reported.

    Args:
        src: Source episodes file.
        dst: Destination file.
        episode_stats: Episode → feature → statistics of the new values.
        features: Converted feature keys.
        rel: Path used in messages.
        keep_missing: An episode without statistics keeps its source values (reported) instead of being an
            error; used when some data files have no ``episode_index`` column.

    Returns:
        Warnings (statistics kept from the source because they cannot be recomputed).
    """
    name = rel or str(src)
    warnings: list[str] = []
    kept: set[int] = set()
    try:
        pf = pq.ParquetFile(src)
        schema = pf.schema_arrow
        with pq.ParquetWriter(dst, schema=schema) as writer:
            for g in range(pf.metadata.num_row_groups):
                table = pf.read_row_group(g)
                if "episode_index" not in table.schema.names:
                    raise FileFormatError(f"episodes file {name}: no 'episode_index' column")
                eps = episode_numbers(table, name, "episodes file").tolist()
                for i, col_name in enumerate(table.schema.names):
                    parts = col_name.split("/")
                    if len(parts) != 3 or parts[0] != "stats" or parts[1] not in features:
                        continue
                    key, stat = parts[1], parts[2]
                    if not is_known_stat(stat):
                        warnings.append(f"{name}: statistic {col_name!r} cannot be recomputed; kept as is")
                        continue
                    values: list[Any] = []
                    source = table.column(i).to_pylist() if keep_missing else []
                    for row, e in enumerate(eps):
                        acc = episode_stats.get(e, {}).get(key)
                        if acc is None:
                            if not keep_missing:
                                raise FileFormatError(
                                    f"episodes file {name}: episode {e} has no frames in data/"
                                )
                            kept.add(e)
                            values.append(source[row])
                            continue
                        values.append(acc.get(stat))
                    field_ = table.schema.field(i)
                    table = table.set_column(i, field_, pa.array(values, type=field_.type))
                writer.write_table(table, row_group_size=max(table.num_rows, 1))
    except (pa.ArrowException, OSError) as exc:
        raise FileFormatError(f"episodes file {name}: cannot read or write Parquet ({exc})") from None
    if kept:
        listed = ", ".join(str(e) for e in sorted(kept)[:10]) + (", ..." if len(kept) > 10 else "")
        warnings.append(
            f"{name}: per-episode statistics of {', '.join(features)} for {len(kept)} episode(s) "
            f"({listed}) could not be updated (their frames are in data files without 'episode_index'); "
            "they still describe the old calibration"
        )
    return warnings


def write_dataset_stats(
    src: Path, dst: Path, totals: Mapping[str, StatAccumulator], features: Sequence[str]
) -> list[str]:
    """Write ``meta/stats.json`` with the statistics of ``features`` recomputed; others copied as they are.

    Returns:
        Warnings (statistics kept from the source because they cannot be recomputed).
    """
    warnings: list[str] = []
    stats = _read_stats(src)
    for key in features:
        total = totals.get(key)
        if total is None:
            continue
        entry = stats.get(key)
        names = list(entry) if isinstance(entry, dict) else ["min", "max", "mean", "std", "count"]
        new_entry: dict[str, Any] = {}
        for stat in names:
            value = total.get(stat)
            if value is None:
                warnings.append(f"{src.name}: statistic {key}/{stat} cannot be recomputed; kept unchanged")
                assert isinstance(entry, dict)
                value = entry[stat]
            new_entry[stat] = value
        stats[key] = new_entry
    dst.write_text(json.dumps(stats, indent=4), encoding="utf-8")
    return warnings
