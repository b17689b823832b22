"""sweep --auto refuses bad input before anything moves or is written (UsageError naming what is wrong)."""

from __future__ import annotations

from pathlib import Path

import pytest

from robocal.backends.sim.lite import lite_urdf_text
from robocal.cli.main import main
from robocal.errors import UsageError
from robocal.workflows.autocal.sweep import SweepAutoRequest, run_sweep_auto


@pytest.fixture
def urdf(tmp_path: Path) -> Path:
    p = tmp_path / "lite.urdf"
    p.write_text(lite_urdf_text())
    return p


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"robot": "bhl_biped"}, "no joint"),  # the biped's joints are not in the arms' URDF
        ({"joints": ["nope"]}, "no auto-calibration entry for nope"),
        ({"source": "sim:lite?bogus=1"}, "unknown option 'bogus'"),
        ({"source": "sim:lite?missing=nope"}, "unknown joint(s) nope"),
        ({"source": "sim:lite?seed=x"}, "seed must be a non-negative integer"),
        ({"source": "sim:so101"}, "simulates sim:lite and sim:openarm only"),
        ({"fmt": "urdf"}, "--format 'urdf'"),
    ],
)
def test_refused_before_anything_moves(
    urdf: Path, tmp_path: Path, kwargs: dict[str, object], message: str
) -> None:
    args: dict[str, object] = {"robot": "bhl_arms", "source": "sim:lite"}
    args.update(kwargs)
    source = str(args.pop("source"))
    out = tmp_path / "c.yaml"
    with pytest.raises(Exception, match=message.replace("(", r"\(").replace(")", r"\)")) as info:
        run_sweep_auto(SweepAutoRequest(urdf, source, out, **args))  # type: ignore[arg-type]
    assert getattr(info.value, "exit_code", 2) == 2
    assert not out.exists()


def test_profile_without_auto_section(tmp_path: Path) -> None:
    prof = tmp_path / "p.yaml"
    prof.write_text(
        "format: robocal-robot-profile\nversion: 1\nname: p\nactuator: robstride\n"
        "joints:\n  - {name: left_wrist_roll, id: 16, direction: -1, model: rs-05}\n"
    )
    urdf = tmp_path / "lite.urdf"
    urdf.write_text(lite_urdf_text())
    with pytest.raises(UsageError, match="profile p has none"):
        run_sweep_auto(SweepAutoRequest(urdf, "sim:lite", tmp_path / "c.yaml", robot=str(prof)))


@pytest.mark.parametrize(
    ("extra", "message"),
    [
        (["--joints", "left_wrist_roll"], "--joints, --partial, --verify and --write-zero go with --auto"),
        (["--partial"], "--joints, --partial, --verify and --write-zero go with --auto"),
        (["--auto", "--prior", "x.yaml", "--yes"], "--prior, --threshold, --method"),
    ],
)
def test_cli_option_combinations(
    urdf: Path, tmp_path: Path, extra: list[str], message: str, capsys: pytest.CaptureFixture[str]
) -> None:
    rc = main(
        ["sweep", "--urdf", str(urdf), "--source", "sim:lite", "--out", str(tmp_path / "c.yaml"), *extra]
    )
    err = capsys.readouterr().err
    assert rc == 2
    assert message in err and err.count("error:") == 1
    assert not (tmp_path / "c.yaml").exists()
