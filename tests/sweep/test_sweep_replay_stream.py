"""Replays are streamed: memory does not grow with the recording, progress is reported, errors keep their lines."""

from __future__ import annotations

import io
import math
import subprocess
import sys
import tracemalloc
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from tests.bags import write_joint_states

from robocal.backends.replay import BLOCK_ROWS, open_recording, read_recording
from robocal.backends.sim.lite import LITE_JOINTS
from robocal.backends.sources import StreamReplaySource, open_source
from robocal.errors import FileFormatError
from robocal.workflows.sweep.job import SweepRequest, run_sweep

NAMES = [j.name for j in LITE_JOINTS]


def write_sweep_csv(path: Path, rows: int) -> None:
    """Every joint swept lower → upper → lower (identity frame, offset 0.3·direction), ``rows`` rows."""
    lo = np.array([j.lower for j in LITE_JOINTS])
    up = np.array([j.upper for j in LITE_JOINTS])
    d = np.array([j.direction for j in LITE_JOINTS])
    k = np.arange(rows)
    x = 0.5 - 0.5 * np.cos(2 * math.pi * k / (rows - 1))[:, None]
    with open(path, "w") as fh:
        fh.write("t," + ",".join(NAMES) + "\n")
        np.savetxt(fh, np.column_stack([k / 1000.0, 0.3 * d + lo + (up - lo) * x]), fmt="%.9g", delimiter=",")


def _peak_mib(fn: Any) -> float:
    tracemalloc.start()
    try:
        fn()
        return tracemalloc.get_traced_memory()[1] / 2**20
    finally:
        tracemalloc.stop()


@pytest.mark.slow
def test_replay_memory_does_not_grow_with_the_recording(urdf: Path, tmp_path: Path) -> None:
    small, large = tmp_path / "small.csv", tmp_path / "large.csv"
    write_sweep_csv(small, 2 * BLOCK_ROWS)
    write_sweep_csv(large, 20 * BLOCK_ROWS)  # 10x the rows, about 7 MB
    peaks = {}
    for name, rec in (("small", small), ("large", large)):
        out = tmp_path / f"{name}.yaml"
        peaks[name] = _peak_mib(lambda rec=rec, out=out: run_sweep(SweepRequest(urdf, f"replay:{rec}", out)))
    # bounded: the large file costs no more than the small one (a few blocks), not 10x
    assert peaks["large"] < 1.25 * peaks["small"] + 0.5, peaks
    assert peaks["large"] < 16.0, peaks
    # the test can tell: reading the whole file into memory (what the sweep did before) grows with it
    whole = _peak_mib(lambda: read_recording(large, NAMES))
    assert whole > 2 * peaks["large"], (whole, peaks)
    t, pos = read_recording(large, NAMES)
    assert len(t) == 20 * BLOCK_ROWS and pos.shape == (len(t), 14)


def test_streamed_source_reports_progress_and_reads_every_row(tmp_path: Path) -> None:
    rec = tmp_path / "r.csv"
    rows = 3 * BLOCK_ROWS + 17
    write_sweep_csv(rec, rows)
    src = open_source(f"replay:{rec}", [_spec(n) for n in NAMES])
    assert isinstance(src, StreamReplaySource)
    done0, total, unit, _ = src.progress
    assert unit == "bytes" and total == rec.stat().st_size and done0 < total
    seen = 0
    last_done = done0
    while not src.exhausted:
        t, pos = src.read_block(1000)
        assert 0 < len(t) <= 1000 and pos.shape == (len(t), 14)
        seen += len(t)
        done = src.progress[0]
        assert done >= last_done
        last_done = done
    assert seen == rows and src.progress == (total, total, "bytes", rows)
    src.close()


def _spec(name: str) -> Any:
    from robocal.backends.sources import JointSpec

    j = next(x for x in LITE_JOINTS if x.name == name)
    return JointSpec(j.name, j.can_id, j.model, j.direction, j.lower, j.upper)


def test_streamed_csv_errors_name_the_line(tmp_path: Path) -> None:
    rec = tmp_path / "r.csv"
    write_sweep_csv(rec, 2 * BLOCK_ROWS + 50)
    lines = rec.read_text().splitlines()
    cases = {
        "x": f"recording {rec}: line {BLOCK_ROWS + 7}: a cell is not a number",
        "inf": f"recording {rec}: line {BLOCK_ROWS + 7}: {NAMES[2]} is not finite",
        "2e4": f"recording {rec}: line {BLOCK_ROWS + 7}: {NAMES[2]} is 20000 rad",
    }
    for cell, message in cases.items():
        bad = list(lines)
        cells = bad[BLOCK_ROWS + 6].split(",")
        cells[3] = cell
        bad[BLOCK_ROWS + 6] = ",".join(cells)
        rec.write_text("\n".join(bad) + "\n")
        with pytest.raises(FileFormatError, match="^" + message.replace("(", r"\(")):
            read_recording(rec, NAMES)
    short = list(lines)
    short[2 * BLOCK_ROWS + 3] = "1.0,2.0"
    rec.write_text("\n".join(short) + "\n")
    with pytest.raises(FileFormatError, match=rf"line {2 * BLOCK_ROWS + 4} has 2 cells; expected 15"):
        read_recording(rec, NAMES)
    backwards = list(lines)
    backwards[BLOCK_ROWS + 1] = "0.0" + backwards[BLOCK_ROWS + 1][backwards[BLOCK_ROWS + 1].index(",") :]
    rec.write_text("\n".join(backwards) + "\n")  # t goes back inside the second block
    with pytest.raises(
        FileFormatError, match=rf"column t is not in time order \(line {BLOCK_ROWS + 2}: t = 0 s"
    ):
        read_recording(rec, NAMES)
    across = list(lines)
    across[BLOCK_ROWS + 1] = "0.5" + across[BLOCK_ROWS + 1][across[BLOCK_ROWS + 1].index(",") :]
    across[BLOCK_ROWS] = "0.6" + across[BLOCK_ROWS][across[BLOCK_ROWS].index(",") :]  # first row of block 2
    rec.write_text("\n".join(across) + "\n")  # t goes back across the block boundary
    with pytest.raises(
        FileFormatError, match=rf"column t is not in time order \(line {BLOCK_ROWS + 1}: t = 0.6"
    ):
        read_recording(rec, NAMES)


def test_python_number_syntax_numpy_refuses_is_still_read(tmp_path: Path) -> None:
    rec = tmp_path / "r.csv"
    rec.write_text(f"t,{NAMES[0]}\n0,1_0\n0.01, 2.5 \n")  # Python's float() reads both
    t, pos = read_recording(rec, NAMES)
    assert t.tolist() == [0.0, 0.01] and pos[:, 0].tolist() == [10.0, 2.5]
    assert np.isnan(pos[:, 1:]).all()


def test_open_recording_checks_the_header_before_any_row(tmp_path: Path) -> None:
    rec = tmp_path / "r.csv"
    rec.write_text("time,a\n" + "x\n" * 10)
    with pytest.raises(FileFormatError, match="first column is 'time'; expected 't'"):
        open_recording(rec, NAMES)


@pytest.mark.slow
def test_piped_replay_prints_progress_lines_with_percent(urdf: Path, tmp_path: Path) -> None:
    rec = tmp_path / "r.csv"
    write_sweep_csv(rec, 2 * BLOCK_ROWS)
    code = "import sys; from robocal.cli.main import main; sys.exit(main(sys.argv[1:]))"
    p = subprocess.run(
        [
            sys.executable,
            "-c",
            code,
            "sweep",
            "--urdf",
            str(urdf),
            "--source",
            f"replay:{rec}",
            "--out",
            str(tmp_path / "c.yaml"),
        ],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert p.returncode == 1, p.stderr  # replays do not know zero_sta: wrap_in_travel warnings
    progress = [x for x in p.stderr.splitlines() if x.startswith("sweep: replay ")]
    mb = rec.stat().st_size / 1e6
    assert progress[-1] == (
        f"sweep: replay 100% ({mb:.1f} of {mb:.1f} MB), {2 * BLOCK_ROWS} samples, 14/14 joints at full span"
    )


@pytest.mark.slow
def test_rosbag_is_streamed_in_header_stamp_order(urdf: Path, tmp_path: Path) -> None:
    n = BLOCK_ROWS + 900
    k = np.arange(n)
    t = k / 1000.0
    stamps = t.copy()
    stamps[1::2], stamps[0:-1:2] = t[0:-1:2], t[1::2]  # neighbours swapped: received before their stamp
    lo = np.array([j.lower for j in LITE_JOINTS])
    up = np.array([j.upper for j in LITE_JOINTS])
    x = 0.5 - 0.5 * np.cos(2 * math.pi * k / (n - 1))[:, None]
    s = lo + (up - lo) * x
    bag = tmp_path / "bag"
    write_joint_states(bag, NAMES, stamps, s, receive_s=t)  # receive times in order, header stamps swapped in pairs
    rec = open_recording(bag, NAMES)
    assert (rec.unit, rec.total) == ("messages", n)
    blocks = list(rec)
    got_t = np.concatenate([b[0] for b in blocks])
    got_s = np.vstack([b[1] for b in blocks])
    assert rec.done == n and rec.rows == n and len(blocks) == 2
    assert np.all(np.diff(got_t) > 0)  # back in stamp order
    order = np.argsort(stamps, kind="stable")
    np.testing.assert_array_equal(got_s, s[order])
    out = run_sweep(SweepRequest(urdf, f"replay:{bag}", tmp_path / "c.yaml"))
    assert out.samples == n and all(abs(j.homing_offset) < 1e-5 for j in out.result.joints)


def test_terminal_live_view_draws_a_progress_bar_over_the_table(urdf: Path, tmp_path: Path) -> None:
    from rich.console import Console

    from robocal.cli._sweep_view import LiveView
    from robocal.workflows.sweep.session import SweepSession

    rec = tmp_path / "r.csv"
    write_sweep_csv(rec, 4 * BLOCK_ROWS)
    joints = [_spec(n) for n in NAMES]
    session = SweepSession(open_source(f"replay:{rec}", joints), joints)
    session.step()
    session.step()
    con = Console(record=True, width=160, force_terminal=True, file=io.StringIO())
    view = LiveView(con)
    con.print(view.renderable(session))
    text = con.export_text()
    done, total, _, _ = session.source.progress  # type: ignore[attr-defined]
    first = text.splitlines()[0]
    assert first.startswith("replay ") and "━" in first
    assert session.samples == BLOCK_ROWS  # two reads of up to 2000 rows: the first block
    assert (
        f"{100 * done / total:3.0f}%  {done / 1e6:.1f} of {total / 1e6:.1f} MB, {session.samples} rows"
        in first
    )
    assert "left_shoulder_pitch" in text  # the table below it
    session.source.close()
