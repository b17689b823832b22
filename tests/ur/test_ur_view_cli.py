"""``robocal ur view`` (without a browser: the page's numbers, the CLI's serving and its errors) and ``verify --q``."""

from __future__ import annotations

import json
import os
import re
import signal
import subprocess
import sys
import time
import urllib.request
from pathlib import Path

import numpy as np
import pytest
from tests.net import busy_port, free_port

from robocal.backends.sim.ur_controller import SimUrController
from robocal.cli.main import main
from robocal.core.dh import fk_dh
from robocal.core.ur import TEST_SET_3_DELTAS, nominal_dh
from robocal.errors import UsageError
from robocal.formats.ur_kinematics import read_dh
from robocal.viewer.ur_page import UrViewModel, UrViewPage, format_error_m, parse_q

DH_FILE = Path(__file__).resolve().parents[1] / "fixtures" / "ur" / "dh_ur_calibration_docs.yaml"


def test_model_error_is_tool0_difference_and_nominal_is_exact() -> None:
    dh = read_dh(DH_FILE)
    view = UrViewModel(dh)  # the closest nominal model
    assert view.model == "ur10e"
    q = (0.1, -1.0, 1.2, 0.3, 0.5, 0.7)
    c = view.at(q)
    expected = fk_dh(dh, np.array([q]))[0, :3, 3] - fk_dh(nominal_dh("ur10e"), np.array([q]))[0, :3, 3]
    np.testing.assert_allclose(c.error_m, expected, atol=1e-12)
    np.testing.assert_allclose(c.frames_calibrated_m[-1], fk_dh(dh, np.array([q]))[0, :3, 3], atol=1e-12)
    # Every link frame of the corrected arm is within a metre and a half of the base (no split-DH frames).
    assert float(np.max(np.linalg.norm(c.frames_calibrated_m, axis=1))) < 1.5
    assert format_error_m(c.error_norm_m) == "0.00265"
    # The nominal model against itself: zero everywhere.
    same = UrViewModel(nominal_dh("ur5e"), "ur5e")
    assert same.at(q).error_norm_m < 1e-12
    assert same.verify_number(samples=50) < 1e-9


def test_parse_q() -> None:
    assert parse_q(None) == (0.0,) * 6
    assert parse_q("0, -1.5,1.5 0 0 0.25") == (0.0, -1.5, 1.5, 0.0, 0.0, 0.25)
    for bad, msg in (
        ("1,2,3", "expected 6"),
        ("a,b,c,d,e,f", "six numbers"),
        ("0,0,0,0,0,nan", "finite"),
        ("7,0,0,0,0,0", "within"),
    ):
        with pytest.raises(UsageError, match=msg):
            parse_q(bad)


@pytest.mark.slow
def test_verify_q_prints_the_error_at_that_pose(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    cal = tmp_path / "cal.yaml"
    assert main(["ur", "correct", "--dh", str(DH_FILE), "--out", str(cal)]) == 0
    capsys.readouterr()
    assert main(["ur", "verify", str(cal), "--model", "ur10e", "--q", "0.1,-1,1.2,0.3,0.5,0.7"]) == 1
    row = next(line for line in capsys.readouterr().out.splitlines() if "kinematics YAML" in line)
    assert row.split()[-4:-2] == ["1", "0.00265"]
    assert main(["ur", "verify", str(cal), "--model", "ur10e", "--q", "0,0,0"]) == 2
    assert "--q: expected 6 joint positions" in capsys.readouterr().err


def _start_cli(*args: str) -> tuple[subprocess.Popen[str], str]:
    proc = subprocess.Popen(
        [sys.executable, "-m", "robocal", "ur", "view", *args],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env={**os.environ, "COLUMNS": "200"},
    )
    assert proc.stdout is not None
    line = proc.stdout.readline()
    m = re.search(r"(http://\S+)", line)
    if m is None:
        proc.kill()
        raise AssertionError(f"no URL printed: {line!r} {proc.communicate()}")
    return proc, m.group(1)


def _page_status(url: str) -> str:
    with urllib.request.urlopen(url, timeout=30) as r:  # the page itself (viser's client) is served
        return r.read(2000).decode("utf-8", "replace")


@pytest.mark.slow
def test_cli_serves_and_stops_on_ctrl_c() -> None:
    proc, url = _start_cli("--dh", str(DH_FILE), "--view-port", "0", "--q", "0.1,-1,1.2,0.3,0.5,0.7")
    try:
        assert proc.stdout is not None
        summary = proc.stdout.readline()
        assert "ur10e: Δp at q = 0.00265 m; max Δp over 1000 samples = 0.00374 m" in summary
        assert "<html" in _page_status(url).lower()
    finally:
        proc.send_signal(signal.SIGINT)
        _out, err = proc.communicate(timeout=60)
    assert proc.returncode == 0, err
    assert "Traceback" not in err


@pytest.mark.slow
def test_cli_reads_the_dh_from_a_controller() -> None:
    dh = nominal_dh("ur10e") + TEST_SET_3_DELTAS
    with SimUrController(dh) as sim:
        host, port = sim.address
        page = None
        try:
            from robocal.workflows.ur.job import read_controller_dh

            got, warnings = read_controller_dh(host, port=port, timeout_s=5.0)
            assert warnings == []
            page = UrViewPage(UrViewModel(got), source=f"controller {host}:{port}", port=0).start()
            status = page.status()
            assert status["model"] == "ur10e"
            assert status["source"] == f"controller {host}:{port}"
            expected = (
                fk_dh(dh, np.zeros((1, 6)))[0, :3, 3] - fk_dh(nominal_dh("ur10e"), np.zeros((1, 6)))[0, :3, 3]
            )
            assert status["error_m"] == pytest.approx(float(np.linalg.norm(expected)), abs=1e-9)
            assert json.loads(json.dumps(status)) == status  # plain JSON
        finally:
            if page is not None:
                page.stop()


@pytest.mark.parametrize(
    ("args", "message"),
    [
        ([], "give either --dh FILE or --host HOST"),
        (["--dh", str(DH_FILE), "--host", "127.0.0.1"], "give either --dh FILE or --host HOST"),
        (["--dh", str(DH_FILE), "--q", "1,2"], "--q: expected 6 joint positions"),
        (["--dh", str(DH_FILE), "--model", "ur99"], "unknown UR model"),
        (["--dh", str(DH_FILE), "--arrow-scale", "-1"], "--arrow-scale"),
        (["--dh", "/nonexistent/dh.yaml"], "/nonexistent/dh.yaml"),
    ],
)
def test_cli_bad_input_is_one_error_line(
    args: list[str], message: str, capsys: pytest.CaptureFixture[str]
) -> None:
    assert main(["ur", "view", *args, "--view-port", "0"]) == 2
    err = capsys.readouterr().err
    assert message in err
    assert err.count("error:") == 1 and "Traceback" not in err


def test_cli_port_in_use_is_an_error(capsys: pytest.CaptureFixture[str]) -> None:
    with busy_port() as port:
        assert main(["ur", "view", "--dh", str(DH_FILE), "--view-port", str(port)]) == 2
    err = capsys.readouterr().err
    assert f"127.0.0.1:{port}" in err and err.count("error:") == 1


def test_unreachable_controller_is_one_error_line(capsys: pytest.CaptureFixture[str]) -> None:
    port = free_port()  # a port nobody listens on
    t0 = time.monotonic()
    code = main(
        ["ur", "view", "--host", "127.0.0.1", "--port", str(port), "--timeout", "2", "--view-port", "0"]
    )
    assert code != 0 and time.monotonic() - t0 < 60
    err = capsys.readouterr().err
    assert err.count("error:") == 1 and "Traceback" not in err
