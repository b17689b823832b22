"""Ctrl-C at every step of ``sweep --auto`` on the simulated Lite over the wire (issue 11).

At the clear-workspace question, in every phase of a stop search (approach, press, back-off,
the second touch), in every move between searches (the transit to the second stop, the park, a held pose) and
while the files are written (tests/autocal/test_autocal_contract.py): the run ends with ``KeyboardInterrupt``,
every simulated motor is in reset mode (the firmware applies no torque at all) and the calibration file is
unchanged, byte for byte. Through the CLI the exit code is 130 with one ``error:`` line.
"""

from __future__ import annotations

from collections.abc import Generator
from pathlib import Path
from typing import Any

import pytest

pytest.importorskip("can")

import robocal.workflows.autocal.joint as autocal_joint
from robocal.backends.sim.lite import lite_urdf_text
from robocal.cli.main import main
from robocal.core.stop_search import StopSample
from robocal.workflows.autocal.sim import SimAutoLite, sim_opener
from robocal.workflows.autocal.sweep import SweepAutoRequest, run_sweep_auto

pytestmark = pytest.mark.timeout(600)

JOINTS = ["left_wrist_roll", "left_wrist_pitch"]
PRIOR = "left_wrist_roll:\n  id: 16\n  direction: -1\n  homing_offset: 0.25\n"
PROFILE = Path(__file__).resolve().parents[2] / "src" / "robocal" / "data" / "profiles" / "bhl_arms.yaml"


@pytest.fixture
def urdf(tmp_path: Path) -> Path:
    p = tmp_path / "lite.urdf"
    p.write_text(lite_urdf_text())
    return p


@pytest.fixture
def second_touch(tmp_path: Path) -> Path:
    """bhl_arms with every stop touched twice."""
    text = PROFILE.read_text()
    assert "\nauto_calibration:\n" in text
    p = tmp_path / "bhl_arms_twice.yaml"
    p.write_text(text.replace("\nauto_calibration:\n", "\nauto_calibration:\n  second_touch: true\n", 1))
    return p


class _CtrlCAt:
    """A live view that raises KeyboardInterrupt at the ``nth`` sample of (side, phase); records what it saw."""

    def __init__(self, side: str, phase: str, nth: int = 1, skip: int = 0) -> None:
        self.want, self.nth, self.skip = (side, phase), nth, skip
        self.seen: list[tuple[str, str]] = []
        self.count = 0
        self.entries = 0

    def joint_start(self, name: str, cap_nm: float, speed_rad_s: float) -> None:
        pass

    def sample(self, name: str, phase: str, side: str, sample: StopSample) -> None:
        key = (side, phase)
        if not self.seen or self.seen[-1] != key:
            self.seen.append(key)
            if key == self.want:
                self.entries += 1
        if key == self.want and self.entries > self.skip:
            self.count += 1
            if self.count == self.nth:
                raise KeyboardInterrupt

    def joint_done(self, outcome: Any) -> None:
        pass


def _run_interrupted(
    urdf: Path, out: Path, view: Any, source: str = "sim:lite?seed=2", robot: Any = "bhl_arms"
) -> SimAutoLite:
    out.write_text(PRIOR)
    before = out.read_bytes()
    holder: list[SimAutoLite] = []
    with pytest.raises(KeyboardInterrupt):
        run_sweep_auto(
            SweepAutoRequest(
                urdf,
                source,
                out,
                robot=robot,
                joints=JOINTS,
                report=out.with_suffix(".json"),
            ),
            view=view,
            open_drivers_fn=sim_opener(holder),
        )  # fmt: skip
    assert out.read_bytes() == before
    assert not out.with_suffix(".json").exists()
    sim = holder[0]
    assert all(m.mode == 0 for m in sim.motors.values())  # reset mode on every motor
    assert all(m.drive().tau_max_nm == 0.0 for m in sim.motors.values())
    return sim


@pytest.mark.parametrize(
    ("side", "phase", "nth"),
    [
        ("lower", "approach", 1),  # the first reading
        ("lower", "approach", 40),  # moving
        ("lower", "press", 3),  # pressed into the stop
        ("lower", "backoff", 2),
        ("upper", "approach", 5),
        ("upper", "press", 3),
        ("upper", "backoff", 2),
    ],
)
def test_ctrl_c_in_every_phase_of_a_search(
    urdf: Path, tmp_path: Path, side: str, phase: str, nth: int
) -> None:
    view = _CtrlCAt(side, phase, nth)
    _run_interrupted(urdf, tmp_path / "cal.yaml", view)
    assert view.count == nth and view.seen[-1] == (side, phase)


def test_ctrl_c_at_the_second_touch(urdf: Path, tmp_path: Path, second_touch: Path) -> None:
    # the second approach to the lower stop (after its first press and back-off)
    view = _CtrlCAt("lower", "approach", 5, skip=1)
    _run_interrupted(urdf, tmp_path / "cal.yaml", view, robot=str(second_touch))
    assert view.seen[:4] == [
        ("lower", "approach"),
        ("lower", "press"),
        ("lower", "backoff"),
        ("lower", "approach"),
    ]


@pytest.mark.slow
@pytest.mark.parametrize("move", [1, 2, 3])  # the transit to the upper stop, the park, the next joint's moves
def test_ctrl_c_in_a_move_between_searches(
    urdf: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch, move: int
) -> None:
    original = autocal_joint.move_steps
    moves: list[int] = []

    def interrupted_move(*args: Any, **kwargs: Any) -> Generator[Any, Any, Any]:
        moves.append(len(moves) + 1)
        steps = original(*args, **kwargs)
        cmd = next(steps)
        n = 0
        while True:
            n += 1
            if len(moves) == move and n == 10:
                raise KeyboardInterrupt
            reading = yield cmd
            try:
                cmd = steps.send(reading)
            except StopIteration as stop:
                return stop.value

    monkeypatch.setattr(autocal_joint, "move_steps", interrupted_move)
    _run_interrupted(urdf, tmp_path / "cal.yaml", None)
    assert len(moves) == move


def test_ctrl_c_at_the_question_moves_nothing(
    urdf: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    opened: list[Any] = []

    def ctrl_c(names: Any, caps: Any) -> bool:
        raise KeyboardInterrupt

    def opener(*args: Any) -> Any:
        opened.append(args)
        raise AssertionError("nothing may be opened before the answer")

    out = tmp_path / "cal.yaml"
    out.write_text(PRIOR)
    with pytest.raises(KeyboardInterrupt):
        run_sweep_auto(
            SweepAutoRequest(
                urdf,
                "sim:lite",
                out,
                robot="bhl_arms",
                joints=JOINTS,
            ),
            confirm_start=ctrl_c,
            open_drivers_fn=opener,
        )
    assert opened == [] and out.read_text() == PRIOR


def test_cli_ctrl_c_exit_130_one_error_line(
    urdf: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    import robocal.cli._autocal as cli_autocal

    monkeypatch.setattr(cli_autocal, "AutoLiveView", lambda: _CtrlCAt("lower", "press", 2))
    out = tmp_path / "cal.yaml"
    out.write_text(PRIOR)
    rc = main(
        ["sweep", "--auto", "--urdf", str(urdf), "--robot", "bhl_arms", "--source", "sim:lite?seed=2",
         "--out", str(out), "--report", str(tmp_path / "r.json"), "--joints", ",".join(JOINTS), "--yes"]
    )  # fmt: skip
    err = capsys.readouterr().err
    assert rc == 130
    assert "interrupted: every motor is limp; nothing was written" in err and err.count("error:") == 1
    assert out.read_text() == PRIOR and not (tmp_path / "r.json").exists()
