"""Starting ``robocal`` stays cheap: the help pages import no job and no heavy library.

Every start of the program builds the whole command tree, and the test suite starts it hundreds of times, so the
command modules import their jobs inside the command functions (``robocal.cli._catalog`` holds the few values the
help pages show). These tests pin that, and pin each copied value to its home.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys

import typer

from robocal.backends.replay import DEFAULT_TOPIC as REPLAY_TOPIC
from robocal.cli import _catalog
from robocal.cli.main import app
from robocal.core.ur import UR_MODELS
from robocal.formats.calibration import FORMATS
from robocal.formats.profiles import builtin_profile_names
from robocal.workflows.sweep.job import DEFAULT_TOPIC as SWEEP_TOPIC
from robocal.workflows.sweep.session import DEFAULT_DIRECTION_STEP_S

HEAVY = ("numpy", "ruamel", "lxml", "scipy", "trimesh", "cv2", "pyarrow", "matplotlib", "can", "serial")
HEAVY += ("pydantic",)  # typer coerces values with it: a help page has none
"""Libraries a help page must not import (each costs tens to hundreds of milliseconds of CPU per start)."""
JOB_PACKAGES = (
    "robocal.backends",
    "robocal.dataset",
    "robocal.formats",
    "robocal.health",
    "robocal.lerobot",
    "robocal.viewer",
    "robocal.workflows.",
)
LIGHT_JOBS = frozenset(
    {
        "robocal.workflows.written",
        "robocal.workflows.demo",
        "robocal.workflows.demo.job",
        "robocal.workflows.sim",
        "robocal.workflows.sim.job",
    }
)
"""Modules of a job that import the standard library alone (they name the demo and simulator robots)."""


def test_help_pages_import_no_job_and_no_heavy_library() -> None:
    """``--help`` of the program and of each command and group (one fresh interpreter; every page builds the
    whole command tree): no heavy library, no robocal module beyond the light ones."""
    paths = [[], *([name] for name in sorted(typer.main.get_command(app).commands))]  # type: ignore[attr-defined]
    code = (
        "import io, json, sys, contextlib\n"
        "from robocal.cli.main import main\n"
        f"codes = []\n"
        f"for path in {paths!r}:\n"
        "    with contextlib.redirect_stdout(io.StringIO()):\n"
        "        codes.append(main([*path, '--help']))\n"
        "print(json.dumps({'codes': codes, 'modules': sorted(sys.modules)}))\n"
    )
    env = {**os.environ, "COLUMNS": "120"}
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300, env=env)
    assert proc.returncode == 0, proc.stderr
    seen = json.loads(proc.stdout.splitlines()[-1])
    assert seen["codes"] == [0] * len(paths)
    modules = seen["modules"]
    assert [m for m in modules if m.split(".")[0] in HEAVY] == []
    jobs = sorted(m for m in modules if m.startswith(JOB_PACKAGES) and m not in LIGHT_JOBS)
    # import them inside the command function; values a help page shows come from robocal.cli._catalog
    assert jobs == []


def test_copied_values_match_their_homes() -> None:
    """A new calibration format, UR model or default: copy it into robocal/cli/_catalog.py as well."""
    assert _catalog.DEFAULT_TOPIC == REPLAY_TOPIC == SWEEP_TOPIC
    assert _catalog.DEFAULT_DIRECTION_STEP_S == DEFAULT_DIRECTION_STEP_S
    assert tuple(FORMATS) == _catalog.FORMAT_NAMES, (
        "the help of convert --from/--to lists _catalog.FORMAT_NAMES"
    )
    assert tuple(UR_MODELS) == _catalog.UR_MODEL_NAMES, "the help of ur --model lists _catalog.UR_MODEL_NAMES"
    assert _catalog.robot_profile_names() == builtin_profile_names()
    assert len(_catalog.robot_profile_names()) == 12


def test_an_option_not_given_is_coerced_as_typer_does() -> None:
    """robocal builds typer's coercion of a parameter when a value comes (typer: on the first parse, importing
    pydantic); for None (an option not given) it gives what typer's own coercion gives."""
    from typer._coercion import build_runtime_param

    from robocal.cli.main import _command

    def params(command: object) -> list[object]:
        found = list(getattr(command, "params", []))
        for sub in (getattr(command, "commands", None) or {}).values():
            found += params(sub)
        return found

    checked = 0
    for param in params(_command()):
        ours = param.get_runtime_param()  # type: ignore[attr-defined]
        typers = build_runtime_param(param.type_descriptor)  # type: ignore[attr-defined]
        assert ours.coerce(None, param=param, ctx=None) == typers.coerce(None, param=param, ctx=None)
        checked += 1
    assert checked > 300
