"""Measurement sessions for kinematic identification as CSV files a user can produce with any tool.

One row per pose, a header row naming the columns (any order; blank lines and lines starting with ``#`` are
skipped):

* one column per movable joint of the chain, named like the URDF joint: radians (or metres for a prismatic
  joint); ``<joint>_deg`` for degrees;
* ``points`` (a tracker, a CMM): ``x``, ``y``, ``z`` in metres, or ``x_mm``, ``y_mm``, ``z_mm``;
* ``touch``: ``group``: which fixed point the tool touched (any label; same label = same point);
* ``gauge``: ``socket``: ``A`` or ``B`` (the socket distance is given separately).

Columns ``pose``, ``id``, ``t``, ``time``, ``timestamp`` and ``note`` are allowed and ignored; any other column
is refused, so a misspelled joint is not silently dropped.
"""

from __future__ import annotations

import csv
import io
import math
import os
import re
from array import array
from collections.abc import Iterable, Iterator, Mapping, Sequence
from pathlib import Path

import numpy as np

from ..core.kinematic_problem import Measurements, check_kind
from ..errors import FileFormatError
from ..fileio import read_text
from ._numbers import format_float

__all__ = [
    "IGNORED_COLUMNS",
    "measurements_to_csv",
    "parse_joint_table",
    "parse_measurements",
    "read_image_session",
    "read_joint_table",
    "read_measurements",
    "read_pose_plan",
    "session_csv",
]

IGNORED_COLUMNS: tuple[str, ...] = ("pose", "id", "t", "time", "timestamp", "note")


def _float(text: str, where: str, column: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise FileFormatError(f"{where}: column {column!r} is {text!r}, not a number") from None
    if not math.isfinite(value):
        raise FileFormatError(f"{where}: column {column!r} is {text!r}; values must be finite")
    return value


_LINE_ENDS = "\n\r\x0b\x0c\x1c\x1d\x1e\x85\u2028\u2029"
_LINE = re.compile(f"([^{_LINE_ENDS}]*)(?:\r\n|[{_LINE_ENDS}])|([^{_LINE_ENDS}]+)\\Z")
"""One line as ``str.splitlines`` splits them, found lazily (a session may have a million rows)."""


def _lines(text: str) -> Iterator[tuple[int, str]]:
    """``enumerate(text.splitlines(), 1)`` without the list, blank and ``#`` lines left out."""
    for n, m in enumerate(_LINE.finditer(text), 1):
        line = m.group(1) if m.group(1) is not None else m.group(2)
        if line.strip() and not line.lstrip().startswith("#"):
            yield n, line


def _csv_stream(text: str, source: str) -> tuple[list[str], Iterator[tuple[int, list[str]]]]:
    """The header of a session CSV (names stripped of blanks) and its rows, lazily, with their line numbers.

    Blank and ``#`` lines are skipped.

    Raises:
        FileFormatError: No rows at all, columns separated by semicolons or tabs, or a column named twice.
    """
    lines = _lines(text)
    current = [0]

    def feed() -> Iterator[str]:
        for n, line in lines:
            current[0] = n
            yield line + "\n"

    reader = csv.reader(feed())
    first = next(reader, None)
    if first is None:
        raise FileFormatError(f"{source}: no header row and no poses")
    header = [h.strip() for h in first]
    for sep, name in ((";", "semicolons"), ("\t", "tabs")):
        if len(header) == 1 and sep in header[0]:
            raise FileFormatError(
                f"{source}: the header separates its columns with {name}; robocal reads comma-separated CSV "
                "(save the file with commas, and '.' as the decimal point)"
            )
    if len(set(header)) != len(header):
        dup = sorted({h for h in header if header.count(h) > 1})
        raise FileFormatError(f"{source}: duplicate columns {', '.join(dup)}")
    return header, ((current[0], row) for row in reader)


def _csv_rows(text: str, source: str) -> tuple[list[int], list[list[str]]]:
    """The rows of a session CSV without blank and ``#`` lines: their line numbers, and the rows (header first).

    The header's names are stripped of blanks.

    Raises:
        FileFormatError: No rows at all, columns separated by semicolons or tabs, or a column named twice.
    """
    header, stream = _csv_stream(text, source)
    numbered = list(stream)
    return [0] + [n for n, _ in numbered], [header, *(row for _, row in numbered)]


def _joint_columns(
    header: Sequence[str], joint_names: Sequence[str]
) -> tuple[list[tuple[int, float]], list[str]]:
    """Each joint's column and its scale to radians (``<joint>`` or ``<joint>_deg``); the joints not found."""
    cols: list[tuple[int, float]] = []
    missing = []
    for name in joint_names:
        if name in header:
            cols.append((header.index(name), 1.0))
        elif f"{name}_deg" in header:
            cols.append((header.index(f"{name}_deg"), math.pi / 180.0))
        else:
            missing.append(name)
    return cols, missing


_JOINTS_HINT = "joints are named as in the URDF (radians, or <joint>_deg for degrees)"


def _table_columns(
    rows: Sequence[Sequence[str]],
    source: str,
    joint_names: Sequence[str],
    *,
    need: Sequence[str] = (),
    skip: Iterable[str] = (),
    missing_what: str = "columns",
    hint: str = _JOINTS_HINT,
) -> list[tuple[int, float]]:
    """Check a table's header (``rows[0]``) and that it has poses; each joint's column and scale to radians.

    Args:
        rows: The header and the pose rows (:func:`_csv_rows`).
        source: File name for messages.
        joint_names: The chain's joints (``<joint>`` in radians or ``<joint>_deg``), all required.
        need: Further required columns (named in the unknown-column message).
        skip: Further columns that may stand and are skipped (beside :data:`IGNORED_COLUMNS`).
        missing_what: What the missing-column message calls the columns.
        hint: The missing-column message's last part.

    Raises:
        FileFormatError: A missing or unknown column, or no pose rows.
    """
    header = rows[0]
    cols, missing = _joint_columns(header, joint_names)
    missing += [c for c in need if c not in header]
    if missing:
        raise FileFormatError(
            f"{source}: missing {missing_what} {', '.join(missing)} (header: {', '.join(header)}); {hint}"
        )
    known = {header[i] for i, _ in cols} | set(need) | set(IGNORED_COLUMNS) | set(skip)
    unknown = [h for h in header if h not in known]
    if unknown:
        also = f" and {', '.join(need)}" if need else ""
        raise FileFormatError(
            f"{source}: unknown columns {', '.join(unknown)}; expected the chain's joints ({', '.join(joint_names)}){also}"
        )
    if len(rows) < 2:
        raise FileFormatError(f"{source}: has a header but no poses")
    return cols


def _joint_values(
    row: Sequence[str], header: Sequence[str], cols: Sequence[tuple[int, float]], where: str
) -> list[float]:
    """One row's joint values in radians, after checking that it has as many fields as the header."""
    if len(row) != len(header):
        raise FileFormatError(f"{where}: {len(row)} fields, the header has {len(header)}")
    return [_float(row[col].strip(), where, header[col]) * scale for col, scale in cols]


def parse_measurements(
    text: str,
    kind: str,
    joint_names: Sequence[str],
    *,
    distance_m: float | None = None,
    source: str = "<string>",
    held_out: bool = False,
) -> tuple[Measurements, tuple[str, ...]]:
    """Parse a measurement CSV.

    Args:
        text: The CSV text.
        kind: ``points``, ``touch`` or ``gauge``.
        joint_names: The chain's movable joints, the order of ``q``.
        distance_m: Socket distance for ``gauge`` (m).
        source: File name for messages.
        held_out: A validation session: a gauge session may then use one socket only.

    Returns:
        The measurements and the group labels in group-id order (``()`` for points; ``("A", "B")`` for gauge).

    Raises:
        FileFormatError: Missing, unknown or duplicate columns, a non-number, NaN or inf, a bad socket, no rows.
    """
    check_kind(kind)
    header, stream = _csv_stream(text, source)
    extra_cols: dict[str, list[str]] = {
        "points": ["x", "y", "z"],
        "touch": ["group"],
        "gauge": ["socket"],
    }
    need = extra_cols[kind]
    scale_xyz = 1.0
    if kind == "points" and all(f"{c}_mm" in header for c in need):
        need = [f"{c}_mm" for c in need]
        scale_xyz = 1e-3
    joint_cols = _table_columns([header, []], source, joint_names, need=need)
    need_cols = [header.index(c) for c in need]
    # numbers go into flat float64 arrays as they are read: 8 bytes each, whatever the number of rows
    q_flat: array[float] = array("d")
    p_flat: array[float] = array("d")
    labels: list[str] = []
    group: array[int] = array("q")
    n_rows = 0
    for line_number, row in stream:
        n_rows += 1
        where = f"{source} line {line_number}"
        q_flat.extend(_joint_values(row, header, joint_cols, where))
        if kind == "points":
            p_flat.extend(_float(row[i].strip(), where, c) * scale_xyz for i, c in zip(need_cols, need, strict=True))
            continue
        label = row[need_cols[0]].strip()
        if kind == "gauge":
            label = label.upper()
            if label not in ("A", "B"):
                raise FileFormatError(f"{where}: socket is {label!r}; expected A or B")
            group.append(0 if label == "A" else 1)
            continue
        if not label:
            raise FileFormatError(f"{where}: empty group")
        if label not in labels:
            labels.append(label)
        group.append(labels.index(label))
    if not n_rows:
        raise FileFormatError(f"{source}: has a header but no poses")
    q = np.frombuffer(q_flat, dtype=np.float64).reshape(n_rows, len(joint_names)).copy()
    p = np.frombuffer(p_flat, dtype=np.float64).reshape(n_rows, 3).copy() if kind == "points" else None
    if p is not None:
        return Measurements("points", q, p), ()
    if kind == "gauge":
        if set(group) != {0, 1} and not held_out:
            raise FileFormatError(f"{source}: a gauge session needs poses in both socket A and socket B")
        return Measurements("gauge", q, group=np.array(group, dtype=np.int64), distance_m=distance_m), ("A", "B")
    return Measurements("touch", q, group=np.array(group, dtype=np.int64)), tuple(labels)


def read_measurements(
    path: str | os.PathLike[str],
    kind: str,
    joint_names: Sequence[str],
    *,
    distance_m: float | None = None,
    held_out: bool = False,
) -> tuple[Measurements, tuple[str, ...]]:
    """Read a measurement CSV file; see :func:`parse_measurements`."""
    what = "validation file" if held_out else "measurement file"
    return parse_measurements(
        read_text(path, what), kind, joint_names, distance_m=distance_m, source=str(path), held_out=held_out
    )


MEASURED_COLUMNS: tuple[str, ...] = ("x", "y", "z", "x_mm", "y_mm", "z_mm", "group", "socket", "image")
"""Columns of a measured session that a joints-only table (a pose plan) skips."""


def parse_joint_table(text: str, joint_names: Sequence[str], *, source: str = "<string>") -> np.ndarray:
    """Parse a table of joint positions: a pose plan, or the joints of a recorded session.

    The chain's joints (radians, or ``<joint>_deg``) are read; the ignored columns and the measured ones
    (``x,y,z``, ``group``, ``socket``, ``image``) are skipped; any other column is refused.

    Returns:
        ``(N, n_q)`` joint positions in radians (m for prismatic joints).

    Raises:
        FileFormatError: A missing, unknown or duplicate column, a non-number, NaN or inf, no rows.
    """
    line_numbers, rows = _csv_rows(text, source)
    header = rows[0]
    joint_cols = _table_columns(rows, source, joint_names, skip=MEASURED_COLUMNS, missing_what="joint columns")
    q = np.zeros((len(rows) - 1, len(joint_names)))
    for r, row in enumerate(rows[1:]):
        q[r] = _joint_values(row, header, joint_cols, f"{source} line {line_numbers[r + 1]}")
    return q


def read_joint_table(path: str | os.PathLike[str], joint_names: Sequence[str]) -> np.ndarray:
    """Read a table of joint positions from a file; see :func:`parse_joint_table`."""
    return parse_joint_table(read_text(path, "pose table"), joint_names, source=str(path))


def read_pose_plan(path: str | os.PathLike[str], joint_names: Sequence[str]) -> tuple[np.ndarray, tuple[str, ...]]:
    """Read a pose plan (``kinematics plan``): the joints and, when it has one, the ``group``/``socket`` column.

    Returns:
        ``(N, n_q)`` joint positions and the ``N`` point labels (``()`` for a plan of free poses).
    """
    text = read_text(path, "pose plan")
    q = parse_joint_table(text, joint_names, source=str(path))
    _, rows = _csv_rows(text, str(path))
    for column in ("group", "socket"):
        if column in rows[0]:
            k = rows[0].index(column)
            return q, tuple(row[k].strip() for row in rows[1:])
    return q, ()


def measurements_to_csv(data: Measurements, joint_names: Sequence[str], labels: Sequence[str] = ()) -> str:
    """A session as CSV text that :func:`parse_measurements` reads back exactly (shortest round-trip floats)."""
    extra = {"points": ["x", "y", "z"], "touch": ["group"], "gauge": ["socket"]}[data.kind]
    out = io.StringIO()
    writer = csv.writer(out, lineterminator="\n")
    writer.writerow(["pose", *joint_names, *extra])
    for i in range(data.n_poses):
        row = [str(i + 1), *(format_float(float(v)) for v in data.q_rad[i])]
        if data.kind == "points":
            assert data.p_world_m is not None
            row += [format_float(float(v)) for v in data.p_world_m[i]]
        else:
            assert data.group is not None
            g = int(data.group[i])
            if data.kind == "gauge":
                row.append("A" if g == 0 else "B")
            else:
                row.append(labels[g] if g < len(labels) else f"P{g}")
        writer.writerow(row)
    return out.getvalue()


def session_csv(q_rad: np.ndarray, joint_names: Sequence[str], extra: Mapping[str, Sequence[str]]) -> str:
    """CSV text of a session: ``pose``, the joints (radians, shortest round-trip floats), then ``extra`` columns.

    Args:
        q_rad: ``(N, n_q)`` joint readings.
        joint_names: Column names of the joints.
        extra: Further columns in order, each with ``N`` values already formatted.
    """
    out = io.StringIO()
    writer = csv.writer(out, lineterminator="\n")
    writer.writerow(["pose", *joint_names, *extra])
    for i, row in enumerate(np.asarray(q_rad, dtype=np.float64)):
        writer.writerow([str(i + 1), *(format_float(float(v)) for v in row), *(col[i] for col in extra.values())])
    return out.getvalue()


def read_image_session(
    path: str | os.PathLike[str], joint_names: Sequence[str]
) -> tuple[np.ndarray, tuple[str, ...]]:
    """Read an image session CSV: the joints and an ``image`` column (a path, relative to the CSV's folder).

    Returns:
        ``(q_rad (N, n_q), image paths)``, the paths resolved against the CSV's folder.

    Raises:
        FileFormatError: As :func:`parse_measurements` (missing/unknown columns, non-numbers), or an empty image.
    """
    source = str(path)
    line_numbers, rows = _csv_rows(read_text(path, "measurement file"), source)
    header = rows[0]
    cols = _table_columns(
        rows, source, joint_names, need=["image"], hint="an image session has the URDF's joints and an image column"
    )
    base = Path(path).parent
    q = np.zeros((len(rows) - 1, len(joint_names)))
    images: list[str] = []
    for r, row in enumerate(rows[1:]):
        where = f"{source} line {line_numbers[r + 1]}"
        q[r] = _joint_values(row, header, cols, where)
        image = row[header.index("image")].strip()
        if not image:
            raise FileFormatError(f"{where}: empty image")
        images.append(str(base / image))
    return q, tuple(images)
