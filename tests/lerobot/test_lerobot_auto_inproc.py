"""``lerobot calibrate --auto --port 'sim?transport=inproc'``: the simulated arm behind an in-process port.

The same simulated arm, SDK and packets as ``--port sim`` (a pseudo-terminal), without the pty: the same seed
writes the same calibration file (to the tick: tests/autocal/test_acceptance_servo.py shows the packets are the
same byte for byte; here the pty's SDK keeps its 100 ms wall-clock timeout, and a retry on a loaded machine may
move a stop by a tick).
"""

from __future__ import annotations

from pathlib import Path

import pytest

from robocal.cli.main import main
from robocal.lerobot import read_calibration

from .conftest import calibrate_args

pytestmark = pytest.mark.timeout(600)


@pytest.mark.slow
@pytest.mark.parametrize(
    ("robot", "folder", "joints"),
    [
        ("so101_follower", "so_follower", "shoulder_pan,gripper"),
        ("koch_follower", "koch_follower", "gripper"),
    ],
)
def test_inproc_port_writes_what_the_pty_writes(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], robot: str, folder: str, joints: str
) -> None:
    paths = {}
    for transport, port in (("pty", "sim?seed=5"), ("inproc", "sim?seed=5&transport=inproc")):
        args = calibrate_args(
            tmp_path / transport, "--auto", "--yes", "--joints", joints, robot=robot, port=port
        )
        assert main(args) == 0
        out = capsys.readouterr().out
        path = tmp_path / transport / "robots" / folder / "arm1.json"
        assert f"calibration saved to {path} and written to the motors" in out
        paths[transport] = path
    pty, inproc = read_calibration(paths["pty"]), read_calibration(paths["inproc"])
    assert list(inproc) == list(pty)
    for name in joints.split(","):
        a, b = inproc[name], pty[name]
        assert (a.id, a.drive_mode) == (b.id, b.drive_mode)
        assert abs(a.homing_offset - b.homing_offset) <= 1
        assert abs(a.range_min - b.range_min) <= 2 and abs(a.range_max - b.range_max) <= 2
        assert a.range_max - a.range_min > 500  # a real range was found


def test_unknown_transport_exit_2_nothing_written(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(calibrate_args(tmp_path, "--auto", "--yes", port="sim?transport=tcp")) == 2
    err = capsys.readouterr().err
    assert err.count("error:") == 1 and "transport 'tcp': expected one of pty, inproc" in err
    assert "Traceback" not in err
    assert not (tmp_path / "robots").exists()
