"""The CLI's last line of defence: a bug is one ``error:`` line, a saved traceback and exit 70, never exit 1.

Run through a real subprocess (the exit code and the streams are what a script sees). The bug is provoked by
replacing the function ``robocal convert`` calls with one that raises, in the child process only.
"""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
EXAMPLES = ROOT / "examples" / "lite"


def _run(
    tmp_path: Path, raise_stmt: str, env: dict[str, str] | None = None
) -> subprocess.CompletedProcess[str]:
    code = (
        "import sys\n"
        "import robocal.workflows.files.job as files\n"  # robocal.cli.files imports it when convert runs
        "def boom(*args, **kwargs):\n"
        f"    {raise_stmt}\n"
        "files.convert_file = boom\n"
        "from robocal.cli.main import run\n"
        "sys.argv = ['robocal', 'convert', 'in.json', 'out.yaml']\n"
        "run()\n"
    )
    full_env = {**os.environ, "PYTHONPATH": str(ROOT / "src"), **(env or {})}
    return subprocess.run(
        [sys.executable, "-c", code], cwd=tmp_path, capture_output=True, text=True, env=full_env, check=False
    )


def test_unexpected_exception_is_exit_70_with_a_saved_traceback(tmp_path: Path) -> None:
    r = _run(
        tmp_path, "raise ZeroDivisionError('division by zero')", {"XDG_STATE_HOME": str(tmp_path / "state")}
    )
    assert r.returncode == 70
    assert r.stdout == ""
    m = re.fullmatch(
        r"error: internal error, a bug in robocal \(ZeroDivisionError: division by zero\); "
        r"the traceback is in (\S+\.log); please report it\n",
        r.stderr,
    )
    assert m, r.stderr
    log = Path(m.group(1))
    assert log.parent == tmp_path / "state" / "robocal"
    text = log.read_text()
    assert text.startswith("robocal ")
    assert "command: robocal convert in.json out.yaml\n" in text
    assert "Traceback (most recent call last):" in text and "in boom" in text
    assert text.rstrip().endswith("ZeroDivisionError: division by zero")


def test_log_falls_back_to_the_temporary_folder(tmp_path: Path) -> None:
    blocker = tmp_path / "not-a-folder"
    blocker.write_text("")
    tmp = tmp_path / "tmp"
    tmp.mkdir()
    r = _run(tmp_path, "raise RuntimeError('x')", {"XDG_STATE_HOME": str(blocker), "TMPDIR": str(tmp)})
    assert r.returncode == 70
    assert f"the traceback is in {tmp}/robocal-crash-" in r.stderr
    assert len(list(tmp.glob("robocal-crash-*.log"))) == 1


@pytest.mark.slow
def test_keyboard_interrupt_stays_130_and_calib_errors_keep_their_code(tmp_path: Path) -> None:
    r = _run(tmp_path, "raise KeyboardInterrupt", {"XDG_STATE_HOME": str(tmp_path / "state")})
    assert (r.returncode, r.stderr) == (130, "error: interrupted\n")
    r = _run(tmp_path, "from robocal.errors import DeviceError; raise DeviceError('bus off')")
    assert (r.returncode, r.stderr) == (3, "error: bus off\n")
    assert not (tmp_path / "state").exists()


def test_closed_output_pipe_is_quiet(tmp_path: Path) -> None:
    """``robocal check ... | head -1``: the reader goes away; no traceback, no bug report, exit 141."""
    env = {**os.environ, "PYTHONPATH": str(ROOT / "src"), "XDG_STATE_HOME": str(tmp_path / "state")}
    p = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "robocal",
            "check",
            "--calibration",
            str(EXAMPLES / "calibration.yaml"),
            "--urdf",
            str(EXAMPLES / "lite_bimanual.urdf"),
        ],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        env=env,
    )
    assert p.stdout is not None and p.stderr is not None
    p.stdout.close()  # before robocal writes its table
    err = p.stderr.read().decode()
    assert p.wait(timeout=60) == 141
    assert "Traceback" not in err and "internal error" not in err and "BrokenPipeError" not in err
    assert not (tmp_path / "state").exists()


@pytest.mark.parametrize("args", [["--help"]])
def test_exit_codes_are_documented_in_help(args: list[str]) -> None:
    r = subprocess.run(
        [sys.executable, "-m", "robocal", *args],
        capture_output=True,
        text=True,
        env={**os.environ, "PYTHONPATH": str(ROOT / "src"), "COLUMNS": "200"},
        check=False,
    )
    assert r.returncode == 0
    assert "70 internal error, a bug in robocal" in r.stdout and "130 interrupted" in r.stdout


def test_names_and_paths_over_the_system_limits_are_usage_errors(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from robocal.cli.main import main

    cal = str(EXAMPLES / "calibration.yaml")
    long_name = tmp_path / ("n" * 300 + ".json")
    assert main(["convert", cal, str(long_name)]) == 2
    assert capsys.readouterr().err.endswith(
        ".json: the file name is 305 bytes, longer than the file system's limit of 255\n"
    )
    deep = tmp_path.joinpath(*(["d" * 200] * 25), "x.json")
    assert main(["convert", cal, str(deep)]) == 2
    assert "longer than the system's limit of 4095" in capsys.readouterr().err
    assert main(["convert", str(long_name), str(tmp_path / "o.json")]) == 2
    assert "cannot read (File name too long)" in capsys.readouterr().err
    root = tmp_path / ("r" * 300)
    assert main(["dataset", "inspect", str(root), "--calibration", cal]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: ") and err.endswith(
        "("
        + str(len(str(root).encode()))
        + " bytes): file name too long (a name may have at most 255 bytes, "
        "a path at most 4095)\n"
    )
    assert sorted(p.name for p in tmp_path.iterdir()) == []


@pytest.mark.parametrize("args", [["check", "--calibration", "c.yaml", "--urdf", "r.urdf"], ["--help"]])
def test_ctrl_c_while_the_command_line_is_parsed_prints_the_line(
    args: list[str], monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """typer turns a KeyboardInterrupt while parsing into a silent exit 130; robocal prints its one line."""
    import typer.core

    from robocal.cli.main import main

    def interrupted(*_: object, **__: object) -> None:
        raise KeyboardInterrupt

    monkeypatch.setattr(typer.core._TyperParameter, "process_value", interrupted)
    assert main(args) == 130
    captured = capsys.readouterr()
    assert (captured.err, captured.out) == ("error: interrupted\n", "")
