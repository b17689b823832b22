"""The README as a newcomer reads it (issue 27): its commands work exactly as written, its numbers are measured.

The blocks are read from README.md itself, so an edit to the README that breaks a command fails here.
"""

from __future__ import annotations

import importlib.util
import re
import shlex
import subprocess
import sys
from pathlib import Path
from types import ModuleType

import numpy as np
import pytest

from robocal.cli.main import main

ROOT = Path(__file__).resolve().parents[2]
README = (ROOT / "README.md").read_text(encoding="utf-8")


def readme_block(heading: str) -> list[str]:
    """The commands of the first ```bash block after ``heading``: one per line, comments and blanks dropped."""
    after = README.split(f"\n{heading}\n", 1)[1]
    block = after.split("```bash\n", 1)[1].split("\n```", 1)[0]
    lines = [re.sub(r"\s+#.*$", "", line).strip() for line in block.splitlines()]
    return [line for line in lines if line and not line.startswith("#")]


def commands(line: str) -> list[list[str]]:
    """The commands of a shell line joined by ``&&``, each split into words."""
    return [shlex.split(part) for part in line.split("&&")]


def load_runner() -> ModuleType:
    spec = importlib.util.spec_from_file_location("bench_runner", ROOT / "benchmarks" / "run.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules["bench_runner"] = module  # the dataclass looks its module up
    spec.loader.exec_module(module)
    return module


# -- benchmarks ---------------------------------------------------------------------------------------------------


def test_benchmark_runner_refuses_unknown_names_before_running_anything() -> None:
    r = subprocess.run(
        [sys.executable, str(ROOT / "benchmarks" / "run.py"), "jointmap", "all", "nosuch"],
        capture_output=True,
        text=True,
        timeout=120,
        check=False,
    )
    assert (r.returncode, r.stdout) == (2, "")  # not even jointmap ran
    assert r.stderr == (
        "error: unknown benchmarks 'all', 'nosuch'; valid: jointmap, lerobot, ur, sweep, kinematics, dataset, "
        "replay, view, health_live, scaling, kinematics_tag_prior, autocal, autocal_wire, autocal_servo, health, "
        "openarm, health_verify, faults (--list shows what each measures and how long it takes)\n"
    )


def test_every_benchmark_file_is_listed_with_its_set_and_duration() -> None:
    run = load_runner()
    files = {p.stem.removeprefix("bench_") for p in (ROOT / "benchmarks").glob("bench_*.py")}
    assert set(run.BY_NAME) == files
    long = {b.name for b in run.BENCHMARKS if b.long}
    assert long == {
        "scaling",
        "kinematics_tag_prior",
        "autocal",
        "autocal_wire",
        "autocal_servo",
        "health",
        "openarm",
        "health_verify",
        "faults",
    }
    r = subprocess.run(
        [sys.executable, str(ROOT / "benchmarks" / "run.py"), "--list"],
        capture_output=True,
        text=True,
        timeout=120,
        check=False,
    )
    assert r.returncode == 0 and r.stderr == ""
    assert re.search(r"\n  autocal_servo +~65 min  long, by name only +auto-calibration on the servo", r.stdout)
    assert re.search(r"\n  jointmap +~5 s  fast set  ", r.stdout)


def test_a_run_without_names_is_the_fast_set(monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]) -> None:
    run = load_runner()
    ran: list[str] = []
    monkeypatch.setattr(run, "_run", lambda name: ran.append(name))
    assert run.main([]) == 0
    assert ran == ["jointmap", "lerobot", "ur", "sweep", "kinematics", "dataset", "replay", "view", "health_live"]
    out = capsys.readouterr().out
    assert "the long runs only by name: scaling (~65 min), kinematics_tag_prior (~15 min), autocal (~5 min)" in out
    ran.clear()
    monkeypatch.setattr(run, "_run", lambda name: ran.append(name) or ("below target" if name == "ur" else None))
    assert run.main(["ur", "jointmap", "ur"]) == 1  # a failed one does not stop the others; each runs once
    assert ran == ["ur", "jointmap"]
    assert capsys.readouterr().err == "FAILED ur: below target\n"


def test_readme_benchmark_commands_work_as_written_on_a_fresh_clone() -> None:
    run = load_runner()
    lines = readme_block("## Benchmarks")
    first = commands(lines[0])
    # the block makes the environment its commands use (a fresh clone has no .venv)
    assert first[0] == ["python3", "-m", "venv", ".venv"]
    assert first[1] == [".venv/bin/pip", "install", "-e", ".[test]"]
    for line in lines[1:]:
        for argv in commands(line):
            assert argv[:2] == [".venv/bin/python", "benchmarks/run.py"], line
            names = [a for a in argv[2:] if not a.startswith("-")]
            assert set(names) <= set(run.BY_NAME), line
    assert "python benchmarks/run.py" not in README.replace(".venv/bin/python benchmarks/run.py", "")
    section = " ".join(README.split("\n## Benchmarks\n", 1)[1].split())
    for b in run.BENCHMARKS:
        if b.long:  # each long run named with how long it takes
            assert f"`{b.name}` ({b.duration})" in section, b.name


# -- tests --------------------------------------------------------------------------------------------------------


def ci_commands() -> list[list[str]]:
    """The commands of ``.ci/run`` that make the environment and run Python (``timed LABEL`` and pip's -q aside)."""
    out = []
    for line in (ROOT / ".ci" / "run").read_text().splitlines():
        if line.startswith("timed "):
            line = shlex.join(shlex.split(line)[2:])
        if line.startswith(("python3 ", ".venv/")):
            out += [[w for w in argv if w != "-q"] for argv in commands(line)]
    return out


def test_readme_test_command_is_what_ci_runs_and_says_what_ci_adds() -> None:
    block = next(b for b in README.split("```bash\n")[1:] if "-m pytest" in b.split("\n```")[0])
    readme = [argv for line in block.split("\n```")[0].splitlines() if line.strip() for argv in commands(line)]
    assert readme[-1] == [".venv/bin/python", "-m", "pytest"]  # the whole suite
    ci = iter(ci_commands())
    assert all(argv in ci for argv in readme), (readme, ci_commands())  # the README's, in CI's order
    intro = README[: README.index("```bash\n" + block)].rstrip().rsplit("\n\n", 1)[1]
    assert re.search(r"test suite.*\(about \d+ minutes on 2 cores\)", intro), intro  # says how long it takes
    assert "CI (`.ci/run`) runs these same commands on a fresh clone" in README
    assert "it installs the\ndistribution's Chromium" in README


# -- convert ------------------------------------------------------------------------------------------------------

ROBOT_URDF = """<?xml version="1.0"?>
<robot name="leg">
  <link name="base"/><link name="thigh"/><link name="shin"/><link name="foot"/>
  <joint name="hip" type="revolute"><parent link="base"/><child link="thigh"/><axis xyz="0 1 0"/>
    <limit lower="-1.0" upper="1.0" effort="10" velocity="10"/></joint>
  <joint name="knee" type="revolute"><parent link="thigh"/><child link="shin"/><axis xyz="0 1 0"/>
    <limit lower="0.0" upper="2.0" effort="10" velocity="10"/></joint>
  <joint name="ankle" type="revolute"><parent link="shin"/><child link="foot"/><axis xyz="0 1 0"/>
    <limit lower="-0.5" upper="0.5" effort="10" velocity="10"/></joint>
  <ros2_control name="leg" type="system">
    <hardware><param name="can_interface">can0</param></hardware>
    <joint name="hip"><param name="can_id">1</param><param name="direction">1</param></joint>
    <joint name="knee"><param name="can_id">2</param><param name="direction">-1</param></joint>
    <joint name="ankle"><param name="can_id">3</param><param name="direction">1</param></joint>
  </ros2_control>
</robot>
"""

CALIBRATION_YAML = """hip:
  id: 1
  direction: 1
  homing_offset: 0.25
knee:
  id: 2
  direction: -1
  homing_offset: -0.5
ankle:
  id: 3
  direction: 1
  homing_offset: 0.125
"""


def test_readme_convert_examples_run_as_written(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """Every line of "Calibration files: convert and check" on a robot no profile knows (robot.urdf)."""
    (tmp_path / "robot.urdf").write_text(ROBOT_URDF)
    (tmp_path / "calibration.yaml").write_text(CALIBRATION_YAML)
    monkeypatch.chdir(tmp_path)
    lines = readme_block("### Calibration files: convert and check")
    assert len(lines) == 4
    for line in lines:
        argv = shlex.split(line)
        assert argv[0] == "robocal"
        assert main(argv[1:]) == 0, (line, capsys.readouterr())
    offsets = (tmp_path / "offsets.yaml").read_text()
    # in the order --joints gave (the robot's code reads them by index); berkeley's q = direction·raw − offset
    assert "\n# joint order: hip, knee, ankle\n" in offsets
    assert "\nposition_offsets: [0.25, 0.5, 0.125]\n" in offsets
    assert (tmp_path / "calibration.json").is_file()
    assert "<transmission" in (tmp_path / "robot.urdf").read_text()


# -- the identification numbers -----------------------------------------------------------------------------------


def demo_nominal_error_mm(robot: str, seed: int) -> float:
    """The mean error (mm) of the nominal model at ``demo --identify``'s 500 new poses for the draw ``seed``.

    The arm is built as ``kinematics simulate`` builds it (hidden errors drawn first from the seed), the poses as
    the demo draws them (seed 1); ``tests/kinematics/test_kinematics_cli.py::test_demo_identify`` checks this
    against what the Koch demo prints.
    """
    from robocal.backends.sim.kinematic_arm import SimulatedKinematicArm, hidden_errors
    from robocal.core.kinematic_errors import ErrorModel
    from robocal.formats.urdf import read_urdf
    from robocal.formats.urdf_chain import chain_from_urdf
    from robocal.workflows.kinematics.sim import SIM_ROBOTS, shipped_urdf, tool_frame

    spec = SIM_ROBOTS[robot]
    chain = chain_from_urdf(read_urdf(str(shipped_urdf(robot))), tip_link=spec.tip_link)
    model = ErrorModel(chain, T_tip_tool=tool_frame(spec.marker_off_axis_m))
    arm = SimulatedKinematicArm(model, hidden_errors(model, np.random.default_rng(seed)), ticks_per_turn=4096)
    q = arm.sample_q(500, np.random.default_rng(1))
    return float(np.linalg.norm(model.points(arm.read(q)) - arm.true_points(q), axis=1).mean() * 1e3)


def test_readme_error_before_identification_is_the_demos() -> None:
    seed0 = demo_nominal_error_mm("so101", 0)
    draws = [demo_nominal_error_mm("so101", s) for s in range(20)]
    assert round(seed0, 1) == 8.4
    text = " ".join(README.split())
    assert f"drops from {seed0:.1f} mm mean to 0.34 mm" in text
    assert f"starts at {min(draws):.1f}–{max(draws):.0f} mm mean ({np.mean(draws):.1f} mm on average)" in text
