"""Help text a person and a log can read: flags without ``<bool>``, positionals as ``SRC DST``, every command
and option explained, no upstream issue numbers, defaults that say what really happens."""

from __future__ import annotations

import os
import re
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
import typer

from robocal.cli.main import app, main

ROOT = Path(__file__).resolve().parents[2]


def _help(capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch, *args: str) -> str:
    monkeypatch.setenv("COLUMNS", "250")
    assert main([*args, "--help"]) == 0
    return capsys.readouterr().out


def _commands(command: Any, path: tuple[str, ...] = ()) -> Iterator[tuple[tuple[str, ...], Any]]:
    yield path, command
    for name, sub in (getattr(command, "commands", None) or {}).items():
        yield from _commands(sub, (*path, name))


ALL = [path for path, _ in _commands(typer.main.get_command(app))]


@pytest.mark.parametrize("path", ALL, ids=lambda p: " ".join(p) or "robocal")
def test_every_help_page(
    capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch, path: tuple[str, ...]
) -> None:
    text = _help(capsys, monkeypatch, *path)
    assert "<bool>" not in text  # flags take no value
    assert not re.search(r"\{[a-z_]+\}", text), text  # positionals are SRC, not {src}
    assert not re.search(r"#\d{3,}", text), text  # upstream issue numbers belong in the docs
    assert "--help" in text and "Show this message and exit." in text


def test_every_command_and_option_has_help() -> None:
    missing = []
    for path, command in _commands(typer.main.get_command(app)):
        for name, sub in (getattr(command, "commands", None) or {}).items():
            if not sub.get_short_help_str(limit=200).strip():
                missing.append(" ".join((*path, name)))
        missing += [
            f"{' '.join(path)} {p.opts or p.name}" for p in command.params if not getattr(p, "help", None)
        ]
    assert missing == []


def test_positionals_flags_and_version(
    capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    text = _help(capsys, monkeypatch, "convert")
    assert "Usage: robocal convert [OPTIONS] SRC DST" in text
    assert re.search(r"\*\s+SRC\s+<path>\s+Calibration file to read\.", text)
    root = _help(capsys, monkeypatch)
    assert re.search(r"--version\s+Print the version and exit\.", root)
    assert main(["--version", "true"]) == 2
    assert capsys.readouterr().err == "error: --version takes no value and no other arguments (got 'true')\n"
    assert main(["--version"]) == 0
    assert capsys.readouterr().out.startswith("robocal ")
    sweep = _help(capsys, monkeypatch, "sweep")
    assert re.search(r"--direction-check\s+Guided", sweep)


def test_group_help_names_every_command(
    capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    text = _help(capsys, monkeypatch, "ur")
    assert "(extract, correct, defaults, verify, plot, view)" in text
    for name in ("extract", "correct", "defaults", "verify", "plot", "view"):
        assert re.search(rf"│ {name}\s+\S", text), name  # each command has a help line
    root = _help(capsys, monkeypatch)
    assert "(extract, correct, defaults, verify, plot, view)" in root


def test_specific_option_texts(capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch) -> None:
    for cmd in ("show", "export-urdf"):
        assert re.search(
            r"--id\s+<str>\s+Robot id: the calibration is <id>\.json\.",
            _help(capsys, monkeypatch, "lerobot", cmd),
        )
    assert "Write the exact per-joint q_urdf = sign·q + offset map of the DEGREES joints." in _help(
        capsys, monkeypatch, "lerobot", "export-urdf"
    )
    assert re.search(
        r"--port\s+<str>\s+Serial port of the arm, or 'sim' for a simulated arm\.",
        _help(capsys, monkeypatch, "lerobot", "check"),
    )
    sweep = _help(capsys, monkeypatch, "sweep")
    assert "lite-yaml or lite-json (default: from --out's extension, .json is lite-json)." in sweep
    # the official Lite URDFs have no <ros2_control>: the sweep takes directions and ids from the profile
    assert "URDF with <ros2_control>" not in sweep
    assert re.search(
        r"--urdf\s+<path>\s+The robot's URDF \(expanded, not xacro\): joint names and limits; directions and CAN "
        r"ids from its <ros2_control> params when it has them, else from the calibration file or the robot "
        r"profile \(--robot, or recognised from the joint names; docs/profiles\.md\)\.",
        re.sub(r"[\s│]+", " ", sweep),
    )


def test_exit_codes_in_root_help_through_a_subprocess() -> None:
    r = subprocess.run(
        [sys.executable, "-m", "robocal", "--help"],
        capture_output=True,
        text=True,
        env={**os.environ, "PYTHONPATH": str(ROOT / "src"), "COLUMNS": "300"},
        check=False,
    )
    assert r.returncode == 0
    assert (
        "Exit codes: 0 success; 1 finished with warnings; 2 bad input or usage (nothing written); 3 device or "
        "communication failure; 70 internal error, a bug in robocal" in r.stdout
    )
