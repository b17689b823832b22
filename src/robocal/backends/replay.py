"""Recorded joint positions: CSV files and rosbag2 recordings (sqlite3 or mcap) of JointState messages.

CSV: a header ``t,<joint>,<joint>,…`` then one row per sample (``t`` in s, positions in rad). Columns of
joints robocal does not know are ignored; a known joint without a column has no samples (NaN).

rosbag2: a bag folder (with ``metadata.yaml``) or a single ``.db3`` / ``.mcap`` file, read with the
``rosbags`` library; ``sensor_msgs/msg/JointState`` messages on ``topic`` are matched to joints by name.
The time stamp is the message header's.

Missing positions, the same for both: a NaN position (legal in a ROS ``JointState``; written as ``nan`` in a
CSV) means "no reading of this joint in this sample" and is kept as NaN, so the sweep skips that joint's sample
and counts it; a joint absent from a message or without a CSV column is NaN too. An infinite position is never
a reading and is refused (``FileFormatError`` naming the line or time stamp), in both formats.

Both are read as a stream (:func:`iter_recording`): blocks of rows, so a replay of any length runs in bounded
memory; :class:`Recording` also reports how far the reading has got (bytes of a CSV, messages of a bag) for a
progress bar. :func:`read_recording` still returns whole arrays for small files and tests.
"""

from __future__ import annotations

import csv
import heapq
import math
from collections.abc import Iterable, Iterator, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from ..core.arrays import FloatArray
from ..errors import FileFormatError, JointMismatchError
from ..fileio import MAX_FILE_BYTES
from . import require

__all__ = [
    "BLOCK_ROWS",
    "DEFAULT_TOPIC",
    "Recording",
    "iter_recording",
    "open_recording",
    "read_csv_recording",
    "read_recording",
    "read_rosbag_recording",
]

DEFAULT_TOPIC = "/lite/joint_states"
"""The JointState topic a rosbag2 recording is read from unless another is named (``--topic``)."""

Block = tuple[FloatArray, FloatArray]
MAX_ROWS = 50_000_000
MAX_ABS_POSITION_RAD = 1.0e4
"""Largest joint position accepted from a recording, rad (beyond it the unwrapping loses all precision)."""
BLOCK_ROWS = 2048
"""Rows per block of a streamed recording (memory is a few blocks, whatever the recording's length)."""
REORDER_WINDOW = 4096
"""Messages of a bag held back to put header stamps in order (a bag is in receive order)."""


def _check_matched(found: Iterable[str], joint_names: Sequence[str], where: str) -> None:
    found = list(found)
    if not any(n in found for n in joint_names):
        raise JointMismatchError(
            f"{where}: 0/{len(joint_names)} joints matched; it has {', '.join(found) or 'no joints'}, "
            f"expected some of {', '.join(joint_names)}"
        )


class Recording:
    """A recording opened for streaming: checked header, blocks of rows on demand, progress.

    Iterate it for ``(t (k,), positions (k, N))`` blocks in time order (``k <= BLOCK_ROWS``); missing joints
    are NaN. Errors in a row are raised when the row is reached (nothing has been written by then).

    Attributes:
        path: The recording.
        kind: ``"csv"`` or ``"rosbag2"``.
        total: Size of the work: bytes of a CSV, messages of a bag (0 when unknown).
        done: Work done so far, same unit.
        unit: ``"bytes"`` or ``"messages"``.
        rows: Rows (messages) yielded so far.
    """

    def __init__(self, path: Path, kind: str, total: int, unit: str, blocks: Iterator[Block]) -> None:
        self.path = path
        self.kind = kind
        self.total = total
        self.unit = unit
        self.done = 0
        self.rows = 0
        self._blocks = blocks

    def __iter__(self) -> Iterator[Block]:
        return self._blocks

    def __next__(self) -> Block:
        return next(self._blocks)

    def close(self) -> None:
        """Stop reading and release the file."""
        close = getattr(self._blocks, "close", None)
        if close is not None:
            close()


# ------------------------------------------------------------------------------------------------------ CSV
def _row_error(
    path: Path, lineno: int, row: list[str], header: list[str], src: list[int]
) -> FileFormatError | None:
    """The error for one row (the fast block parser refused its block), or None when the row is fine."""
    if len(row) != len(header):
        return FileFormatError(
            f"recording {path}: line {lineno} has {len(row)} cells; expected {len(header)}"
        )
    try:
        values = [float(c) for c in row]
    except ValueError:
        return FileFormatError(f"recording {path}: line {lineno}: a cell is not a number")
    bad = [header[i] for i, v in enumerate(values) if math.isinf(v) or (i == 0 and math.isnan(v))]
    if bad:
        return FileFormatError(
            f"recording {path}: line {lineno}: {bad[0]} is not finite "
            "(a missing position may be nan; infinity is never one)"
        )
    big = [c for c in src if abs(values[c]) > MAX_ABS_POSITION_RAD]
    if big:
        return FileFormatError(
            f"recording {path}: line {lineno}: {header[big[0]]} is {values[big[0]]:g} rad; "
            f"expected a joint position within ±{MAX_ABS_POSITION_RAD:g} rad"
        )
    return None


def _parse_block(rows: list[list[str]], width: int, src: list[int]) -> FloatArray | None:
    """Rows of number strings → ``(k, width)`` floats (numpy's parser), or None to check row by row.

    None when a row is short, a cell is not a number for numpy, a time is not finite, a cell is infinite or a
    joint position is too large.
    """
    if any(len(r) != width for r in rows):
        return None
    try:
        values = np.array(rows, dtype=np.float64)
    except ValueError:
        return None
    if not np.isfinite(values[:, 0]).all() or np.isinf(values).any():
        return None
    if (np.abs(np.nan_to_num(values[:, src])) > MAX_ABS_POSITION_RAD).any():
        return None
    return values


def _header_rows(reader: Any, path: Path) -> Iterator[list[str]]:
    try:
        yield from reader
    except UnicodeDecodeError as exc:
        raise FileFormatError(f"recording {path}: not UTF-8 text ({exc.reason})") from None
    except csv.Error as exc:
        raise FileFormatError(f"recording {path}: line {reader.line_num}: {exc}") from None


def _open_csv(path: Path, joint_names: Sequence[str], block_rows: int) -> Recording:
    try:
        size = path.stat().st_size
        fh = open(path, encoding="utf-8-sig", newline="")  # noqa: SIM115 (closed by the generator)
    except OSError as exc:
        raise FileFormatError(f"recording {path}: cannot read ({exc.strerror or exc})") from None
    rec = Recording(path, "csv", size, "bytes", iter(()))
    reader = csv.reader(fh)
    try:
        header: list[str] | None = None
        for row in _header_rows(reader, path):
            if row and any(c.strip() for c in row):
                header = [h.strip() for h in row]
                break
        if header is None:
            raise FileFormatError(f"recording {path}: empty; expected a header t,<joint>,...")
        if header[0] != "t":
            raise FileFormatError(f"recording {path}: first column is {header[0]!r}; expected 't'")
        if len(set(header)) != len(header):
            raise FileFormatError(f"recording {path}: a column name appears twice in the header")
        _check_matched(header[1:], joint_names, f"recording {path}")
    except BaseException:
        fh.close()
        raise
    cols = [header.index(n) if n in header else -1 for n in joint_names]
    rec._blocks = _csv_blocks(fh, reader, rec, path, header, cols, len(joint_names), block_rows)
    return rec


def _csv_blocks(
    fh: Any,
    reader: Any,
    rec: Recording,
    path: Path,
    header: list[str],
    cols: list[int],
    n: int,
    block_rows: int,
) -> Iterator[Block]:
    width = len(header)
    seekable = fh.seekable()
    have = [j for j, c in enumerate(cols) if c >= 0]
    src = [cols[j] for j in have]
    last_t = -math.inf
    try:
        while True:
            rows: list[list[str]] = []
            lines: list[int] = []
            for row in reader:
                if not row or not any(c.strip() for c in row):
                    continue
                rows.append(row)
                lines.append(reader.line_num)
                if len(rows) >= block_rows:
                    break
            if seekable:  # bytes the text layer has read (ahead by at most its chunk); a FIFO has no position
                rec.done = fh.buffer.tell()
            if not rows:
                break
            values = _parse_block(rows, width, src)
            if values is None:  # the fast parser refused the block: find the row, or parse it as Python does
                for lineno, row in zip(lines, rows, strict=True):
                    err = _row_error(path, lineno, row, header, src)
                    if err is not None:
                        raise err
                values = np.array([[float(c) for c in r] for r in rows], dtype=np.float64)
            t = values[:, 0]
            pos = values[:, src]
            d = np.diff(t, prepend=last_t)
            if (d < 0).any():
                k = int(np.argmax(d < 0))
                raise FileFormatError(
                    f"recording {path}: column t is not in time order (line {lines[k]}: t = {t[k]:g} s "
                    f"after {t[k - 1] if k else last_t:g} s)"
                )
            last_t = float(t[-1])
            out = np.full((len(rows), n), np.nan)
            out[:, have] = pos
            rec.rows += len(rows)
            if rec.rows > MAX_ROWS:
                raise FileFormatError(f"recording {path}: more than {MAX_ROWS} rows")
            yield t, out
        if rec.rows == 0:
            raise FileFormatError(f"recording {path}: no samples after the header")
    except UnicodeDecodeError as exc:
        raise FileFormatError(f"recording {path}: not UTF-8 text ({exc.reason})") from None
    except csv.Error as exc:
        raise FileFormatError(f"recording {path}: line {reader.line_num}: {exc}") from None
    finally:
        fh.close()


# -------------------------------------------------------------------------------------------------- rosbag2
def _open_rosbag(path: Path, joint_names: Sequence[str], topic: str, block_rows: int) -> Recording:
    require("rosbags", "reading rosbag2 recordings")
    from rosbags.highlevel import AnyReader

    bag = path
    if path.is_file() and path.suffix in (".db3", ".mcap"):
        bag = path.parent
    try:
        reader = AnyReader([bag])
        reader.open()
    except Exception as exc:  # rosbags raises its own error types for unreadable bags
        raise FileFormatError(f"recording {path}: cannot read rosbag2 ({exc})") from None
    try:
        for c in reader.connections:  # rosbags takes a damaged metadata.yaml's topic entries as they are
            if not isinstance(c.topic, str) or not isinstance(c.msgtype, str):
                raise FileFormatError(
                    f"recording {path}: damaged rosbag2 metadata: a topic entry has name {c.topic!r:.40} "
                    f"and type {c.msgtype!r:.40}; expected two strings"
                )
        conns = [c for c in reader.connections if c.topic == topic]
        if not conns:
            topics = sorted({c.topic for c in reader.connections})
            listed = ", ".join(topics) or "none"
            raise FileFormatError(f"recording {path}: no topic {topic!r}; has {listed} (pass --topic)")
        bad = [c.msgtype for c in conns if c.msgtype != "sensor_msgs/msg/JointState"]
        if bad:
            raise FileFormatError(f"recording {path}: topic {topic} has type {bad[0]}; expected JointState")
        # a damaged metadata.yaml can give a non-integer count: it only feeds the progress bar
        counts = [getattr(c, "msgcount", 0) for c in conns]
        total = sum(n for n in counts if isinstance(n, int) and not isinstance(n, bool) and n > 0)
    except BaseException:
        reader.close()
        raise
    rec = Recording(path, "rosbag2", total, "messages", iter(()))
    rec._blocks = _rosbag_blocks(reader, conns, rec, path, joint_names, topic, block_rows)
    return rec


def _rosbag_rows(
    reader: Any, conns: Any, rec: Recording, path: Path, joint_names: Sequence[str], seen: set[str]
) -> Iterator[tuple[float, int, FloatArray]]:
    index = {n: i for i, n in enumerate(joint_names)}
    for seq, (conn, stamp_ns, raw) in enumerate(reader.messages(connections=conns)):
        rec.done += 1
        msg: Any = reader.deserialize(raw, conn.msgtype)
        row = np.full(len(joint_names), np.nan)
        for name, p in zip(msg.name, msg.position, strict=False):
            seen.add(name)
            i = index.get(name)
            if i is not None and not math.isnan(p):
                if math.isinf(p):
                    raise FileFormatError(
                        f"recording {path}: joint {name} is {p:g} at t = {stamp_ns * 1e-9:.9f} s; "
                        "not finite (a missing position may be NaN; infinity is never one)"
                    )
                if abs(p) > MAX_ABS_POSITION_RAD:
                    raise FileFormatError(
                        f"recording {path}: joint {name} is {p:g} rad at t = {stamp_ns * 1e-9:.9f} s; "
                        f"expected a joint position within ±{MAX_ABS_POSITION_RAD:g} rad"
                    )
                row[i] = p
        hs = msg.header.stamp
        ts = hs.sec + hs.nanosec * 1e-9 if (hs.sec or hs.nanosec) else stamp_ns * 1e-9
        if seq >= MAX_ROWS:
            raise FileFormatError(f"recording {path}: more than {MAX_ROWS} messages")
        yield ts, seq, row


def _rosbag_blocks(
    reader: Any,
    conns: Any,
    rec: Recording,
    path: Path,
    joint_names: Sequence[str],
    topic: str,
    block_rows: int,
) -> Iterator[Block]:
    """Messages in header-stamp order: a heap of :data:`REORDER_WINDOW` messages puts them back in order."""
    seen: set[str] = set()
    heap: list[tuple[float, int, FloatArray]] = []
    t: list[float] = []
    rows: list[FloatArray] = []

    def block() -> Block:
        out = (np.asarray(t, dtype=np.float64), np.vstack(rows))
        rec.rows += len(t)
        t.clear()
        rows.clear()
        return out

    try:
        try:
            for item in _rosbag_rows(reader, conns, rec, path, joint_names, seen):
                if len(heap) < REORDER_WINDOW:
                    heapq.heappush(heap, item)
                    continue
                ts, _, row = heapq.heappushpop(heap, item)
                t.append(ts)
                rows.append(row)
                if len(t) >= block_rows:
                    yield block()
            while heap:
                ts, _, row = heapq.heappop(heap)
                t.append(ts)
                rows.append(row)
                if len(t) >= block_rows:
                    yield block()
        except FileFormatError:
            raise
        except Exception as exc:  # rosbags raises its own error types for unreadable bags
            raise FileFormatError(f"recording {path}: cannot read rosbag2 ({exc})") from None
        _check_matched(sorted(seen), joint_names, f"recording {path} topic {topic}")
        if t:
            yield block()
    finally:
        reader.close()


# ------------------------------------------------------------------------------------------------- public
def open_recording(
    path: Path, joint_names: Sequence[str], *, topic: str = DEFAULT_TOPIC, block_rows: int = BLOCK_ROWS
) -> Recording:
    """Open a CSV or rosbag2 recording for streaming (``.csv`` → CSV, else rosbag2).

    The header (CSV) or the topic (bag) is checked at once; rows are read as the blocks are iterated.

    Raises:
        FileFormatError: No such file, an unreadable file, a bad header, no such topic.
        JointMismatchError: None of the joints has a CSV column (for a bag: raised at its end).
    """
    if not path.exists():
        raise FileFormatError(f"recording {path}: no such file or folder")
    if path.suffix.lower() == ".csv":
        if path.is_dir():
            raise FileFormatError(f"recording {path}: is a directory, expected a CSV file")
        return _open_csv(path, joint_names, block_rows)
    return _open_rosbag(path, joint_names, topic, block_rows)


def iter_recording(
    path: Path, joint_names: Sequence[str], *, topic: str = DEFAULT_TOPIC, block_rows: int = BLOCK_ROWS
) -> Iterator[Block]:
    """Blocks ``(t (k,), positions (k, N))`` of a recording in time order; see :func:`open_recording`."""
    return iter(open_recording(path, joint_names, topic=topic, block_rows=block_rows))


def _whole(blocks: Iterable[Block], n: int) -> tuple[FloatArray, FloatArray]:
    ts: list[FloatArray] = []
    ps: list[FloatArray] = []
    for t, p in blocks:
        ts.append(t)
        ps.append(p)
    if not ts:
        return np.empty(0), np.empty((0, n))
    return np.concatenate(ts), np.vstack(ps)


def read_csv_recording(path: Path, joint_names: Sequence[str]) -> tuple[FloatArray, FloatArray]:
    """Read a whole CSV recording into memory (for small files; a sweep streams it).

    Args:
        path: The file.
        joint_names: Joints in the order wanted.

    Returns:
        ``(t (T,), positions (T, N))``; missing joints are NaN columns.

    Raises:
        FileFormatError: No ``t`` column, a non-numeric cell, a non-finite time, an infinite position, a short
            row, no rows, time not in order. A NaN position (``nan``) is kept as NaN: no reading of that joint
            in that row.
        JointMismatchError: None of the joints has a column.
    """
    if path.stat().st_size > MAX_FILE_BYTES:
        raise FileFormatError(
            f"recording {path}: larger than {MAX_FILE_BYTES} bytes; stream it with open_recording"
        )
    return _whole(_open_csv(path, joint_names, BLOCK_ROWS), len(joint_names))


def read_rosbag_recording(
    path: Path, joint_names: Sequence[str], topic: str = DEFAULT_TOPIC
) -> tuple[FloatArray, FloatArray]:
    """Read ``sensor_msgs/msg/JointState`` messages on ``topic`` from a rosbag2 (sqlite3 or mcap) into memory.

    Returns:
        ``(t (T,), positions (T, N))`` in header-stamp order; a joint absent from a message, or published as
        NaN, is NaN in that row.

    Raises:
        FileFormatError: Not a readable bag, no such topic (the message lists the topics), an infinite or
            too large position.
        JointMismatchError: No message names any of the joints.
    """
    return _whole(_open_rosbag(path, joint_names, topic, BLOCK_ROWS), len(joint_names))


def read_recording(
    path: Path, joint_names: Sequence[str], *, topic: str = DEFAULT_TOPIC
) -> tuple[FloatArray, FloatArray]:
    """Read a whole CSV or rosbag2 recording (chosen by the path: ``.csv`` → CSV, else rosbag2)."""
    if not path.exists():
        raise FileFormatError(f"recording {path}: no such file or folder")
    if path.suffix.lower() == ".csv":
        return read_csv_recording(path, joint_names)
    return read_rosbag_recording(path, joint_names, topic)
