"""``robocal demo`` as one workflow (robocal.workflows.demo.job) rendered by a thin CLI (robocal.cli.demo)."""

from __future__ import annotations

from pathlib import Path

import pytest

from robocal.cli.demo import render
from robocal.cli.main import main
from robocal.errors import UsageError
from robocal.workflows.demo.job import (
    DEMO_ROBOTS,
    JOBS,
    MODE_ROBOTS,
    DemoResult,
    DemoSection,
    TruthTable,
    demo_folder,
    prepare_demo,
    run_demo,
)

UR10E_DEMO_HASH = "calib_8779175261365510310"  # nominal UR10e DH + ur_calibration's test set 3 deltas


def test_ur_demo_in_a_temporary_folder_is_removed_and_says_its_progress() -> None:
    said: list[str] = []
    result = run_demo("UR10e ", None, say=said.append)
    assert (result.robot, result.job, result.temporary, result.exit_code) == ("ur10e", "ur", True, 0)
    assert not result.folder.exists()  # removed when the demo returned
    assert result.lines[0] == f"hash: {UR10E_DEMO_HASH}"
    assert result.lines[1].endswith("ur10e_calibration.yaml (temporary folder, removed on exit)")
    assert said[0].startswith("[bold]UR demo[/]: simulated ur10e controller on 127.0.0.1:")
    assert said[1].startswith(
        "controller DH: d2 = 439.141 m, d3 = -446.027 m (the split DH of a real UR10e's calibration, upstream "
        "ur_calibration's test set 3: joints 2 and 3 are nearly parallel, so their common normal lies far away; "
        "docs/ur.md) → corrected (d2 = d3 = 0) forearm x = "
    )
    reports = result.detail
    assert isinstance(reports, list) and reports and all(r.file_hash == r.dh_hash for r in reports)


def test_ur_demo_keeps_its_files_in_the_given_folder(tmp_path: Path) -> None:
    result = run_demo("ur5e", tmp_path)
    assert result.folder == tmp_path and not result.temporary
    assert "\nkinematics:\n" in (tmp_path / "ur5e_calibration.yaml").read_text()
    assert result.lines[1] == f"wrote {tmp_path / 'ur5e_calibration.yaml'}"


def test_every_robot_and_mode_has_a_job() -> None:
    assert set(DEMO_ROBOTS.values()) <= set(JOBS)
    assert MODE_ROBOTS["identify"] == ("so101", "koch")


def test_prepare_demo_refuses_bad_requests_before_anything_runs(tmp_path: Path) -> None:
    with pytest.raises(UsageError, match="unknown demo robot 'atlas'; valid: lite, so101"):
        prepare_demo("atlas", None)
    with pytest.raises(UsageError, match=r"--identify works with so101, koch, not 'lite'"):
        prepare_demo("lite", None, "identify")
    with pytest.raises(UsageError, match="unknown demo mode 'dance'"):
        prepare_demo("lite", None, "dance")
    f = tmp_path / "file"
    f.write_text("x")
    with pytest.raises(UsageError, match="is a file"):
        prepare_demo("lite", f)
    nested = tmp_path / "a" / "b"
    assert prepare_demo(" Koch", nested) == "koch" and nested.is_dir()
    with pytest.raises(UsageError, match="unknown demo robot"):
        run_demo("atlas")


def test_demo_folder_is_temporary_only_without_out(tmp_path: Path) -> None:
    with demo_folder(None, "sweep") as (folder, temporary):
        assert temporary and folder.is_dir() and folder.name.startswith("robocal-demo-sweep-")
        (folder / "x").write_text("x")
    assert not folder.exists()
    with demo_folder(tmp_path, "sweep") as (kept, temporary):
        (kept / "x").write_text("x")
    assert not temporary and (tmp_path / "x").exists()


def test_render_prints_sections_lines_and_warnings(
    capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    table = TruthTable(
        "true vs recovered", ("joint", "true", "recovered", "status"), (("j1", "+1", "+1", "ok"),)
    )
    result = DemoResult(
        "lite",
        "sweep",
        tmp_path,
        False,
        1,
        sections=(DemoSection(table, ("wrote A",)),),
        lines=("largest error",),
        warnings=("j1: offset_large: beyond ±π",),
    )
    assert render(result) == 1
    out, err = capsys.readouterr()
    assert (
        out.index("true vs recovered") < out.index("j1") < out.index("wrote A") < out.index("largest error")
    )
    assert err == "warning: j1: offset_large: beyond ±π\n"


def test_cli_demo_identify_refuses_a_robot_without_it(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["demo", "--robot", "ur10e", "--identify"]) == 2
    err = capsys.readouterr().err
    assert err == "error: --identify works with so101, koch, not 'ur10e'\n"


def test_demo_auto_is_a_job_for_the_lite_and_refuses_other_robots_in_its_own_words(tmp_path: Path) -> None:
    assert MODE_ROBOTS["auto"] == ("lite", "so101", "koch", "openarm") and set(MODE_ROBOTS) <= set(JOBS)
    assert prepare_demo("LITE", None, "auto") == "lite"
    with pytest.raises(
        UsageError,
        match=r"^demo --auto simulates the lite \(14 Robstride joints\), so101 or koch \(LeRobot followers\) or "
        r"openarm \(8 Damiao motors\); 'ur10e' is not available$",
    ):
        run_demo("ur10e", tmp_path, mode="auto")
    assert list(tmp_path.iterdir()) == []  # refused before anything ran


def test_render_prints_the_auto_table_before_the_truth_table(
    capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    from robocal.workflows.autocal.model import AutoCalResult
    from robocal.workflows.autocal.sweep import AutoSweepOutcome

    outcome = AutoSweepOutcome(AutoCalResult((), 12.5), None, None, "robocal", None, 0)  # type: ignore[arg-type]
    table = TruthTable("true vs recovered homing_offset (rad)", ("joint", "true"), (("j1", "+0.1000"),))
    result = DemoResult("lite", "auto", tmp_path, False, 1, outcome, (DemoSection(table),), ("largest error",))
    assert render(result) == 1
    out = capsys.readouterr().out
    assert out.index("automatic hard-stop calibration (12.5 s)") < out.index("true vs recovered") < out.index(
        "largest error"
    )


@pytest.mark.slow
def test_demo_auto_job_recovers_the_simulated_zeros_and_hands_its_urdf_to_the_view(tmp_path: Path) -> None:
    from robocal.workflows.autocal.sweep import AutoSweepOutcome

    urdfs: list[Path] = []
    started: list[str] = []

    class View:
        def joint_start(self, name: str, cap_nm: float, speed_rad_s: float) -> None:
            started.append(name)

        def sample(self, *args: object) -> None:
            pass

        def joint_done(self, outcome: object) -> None:
            pass

    def view_for(urdf: Path) -> View:
        urdfs.append(urdf)
        return View()

    said: list[str] = []
    result = run_demo("lite", tmp_path, mode="auto", say=said.append, view_for=view_for)
    assert (result.job, result.exit_code, result.temporary) == ("auto", 0, False)
    assert urdfs == [tmp_path / "lite_bimanual.urdf"] and len(started) == 14
    assert said[0].startswith("robocal demo --auto: simulated Lite, 14 Robstride joints")
    assert isinstance(result.detail, AutoSweepOutcome) and result.detail.out == tmp_path / "calibration.yaml"
    table = result.sections[0].table
    assert table.columns == ("joint", "true", "recovered", "error °") and len(table.rows) == 14
    assert all(abs(float(row[3])) <= 0.5 for row in table.rows)  # degrees, the demo's tolerance
    assert result.lines[0].startswith("largest error ") and result.lines[0].endswith("sweep_report.json")
