"""What the installed pyarrow can read back, for tests that write damaged Parquet files."""

from __future__ import annotations

import pyarrow as pa
import pyarrow.parquet as pq


def reads_null_list_rows() -> bool:
    """Whether this pyarrow reads back a null row of a fixed-size list column (pyarrow 25 refuses: "Expected all
    lists to be of size=N"; robocal then says it cannot read the file, still one error line)."""
    buf = pa.BufferOutputStream()
    pq.write_table(pa.table({"a": pa.array([[0.0], None], pa.list_(pa.float32(), 1))}), buf)
    try:
        pq.read_table(pa.BufferReader(buf.getvalue()))
    except pa.ArrowInvalid:
        return False
    return True
