"""Bad input to the kinematics commands.

Too few images for the unknowns, a new ``--out`` folder, the kinds identify takes, a point touched once,
unreadable or cut images.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from robocal.cli.main import main
from robocal.core.kinematic_images import ImageProblem
from robocal.errors import UsageError
from robocal.workflows.kinematics.fit import fit
from robocal.workflows.kinematics.vision_sim import SIM_CAMERA_K

from .test_intrinsics import _session


@pytest.mark.slow
@pytest.mark.parametrize(("images", "ok"), [(3, False), (4, False), (6, True)])
def test_an_image_fit_needs_more_target_poses_than_unknowns(images: int, ok: bool) -> None:
    """Each image shows the target's pose (6 numbers) whatever its corner count: 3 or 4 images cannot settle the
    26 identifiable unknowns of the SO-101 with a fixed camera, even though their 24 or 32 corner equations
    outnumber what those few images could identify (their own rank)."""
    obs, model, _ = _session(SIM_CAMERA_K, n=images)
    problem = ImageProblem(model, obs, tuple(range(model.n_params)), np.zeros(model.n_params))
    if ok:
        assert fit(problem).success
        return
    with pytest.raises(UsageError) as err:
        fit(problem)
    assert str(err.value) == (
        f"too few images: {images} fitted images show {6 * images} numbers (the target's pose in each), not more "
        "than the 26 unknowns the images could identify; take at least 6 images to fit (20 or more for a useful "
        "result)"
    )


@pytest.mark.slow
def test_simulate_creates_a_new_out_folder_but_not_its_parents(tmp_path: Path, capsys) -> None:
    code = main(["kinematics", "simulate", "--out", str(tmp_path / "sim"), "--poses", "20"])
    assert code == 0, capsys.readouterr()
    assert sorted(p.name for p in (tmp_path / "sim").iterdir()) == ["points.csv", "so101.urdf", "truth.json"]
    code = main(["kinematics", "simulate", "--out", str(tmp_path / "a" / "b"), "--poses", "20"])
    assert code == 2
    assert f"error: --out {tmp_path / 'a' / 'b'}: folder {tmp_path / 'a'} does not exist" in capsys.readouterr().err
    assert not (tmp_path / "a").exists()


@pytest.mark.parametrize(
    ("option", "error"),
    [
        (("--kind", "foo"), "error: --kind 'foo'; valid: points, touch, gauge, tag\n"),
        (("--frame", "camera"), "error: --frame 'camera'; valid: base, tracker\n"),
    ],
)
def test_identify_names_every_choice_it_takes(
    tmp_path: Path, capsys, option: tuple[str, str], error: str
) -> None:
    urdf = tmp_path / "x.urdf"
    urdf.write_text("<robot name='x'/>")
    code = main(["kinematics", "identify", "--urdf", str(urdf), "--data", str(tmp_path / "d.csv"), *option])
    assert code == 2
    assert capsys.readouterr().err == error  # one error line, no traceback


@pytest.mark.slow
def test_a_point_touched_once_is_a_warning(tmp_path: Path, capsys) -> None:
    assert main(["kinematics", "simulate", "--out", str(tmp_path), "--kind", "touch", "--poses", "14"]) == 0
    rows = (tmp_path / "touch.csv").read_text().splitlines()
    lonely = rows[-1].rsplit(",", 1)[0] + ",P9"  # the last contact relabelled: a point touched once
    (tmp_path / "once.csv").write_text("\n".join([*rows[:-1], lonely]) + "\n")
    capsys.readouterr()
    code = main(
        ["kinematics", "identify", "--urdf", str(tmp_path / "so101.urdf"), "--data", str(tmp_path / "once.csv"),
         "--kind", "touch", "--tip-link", "gripper_link", "--tool-xyz", "0.0121,0,-0.0981"]
    )  # fmt: skip
    assert code == 1
    assert "warning: point P9 is touched once: one contact says nothing" in capsys.readouterr().err


@pytest.mark.parametrize(
    ("name", "cut", "message"),
    [
        ("empty.png", lambda png, jpg: b"", "empty file"),
        ("cut.png", lambda png, jpg: png[: len(png) // 2], "truncated PNG (no IEND chunk at its end)"),
        ("cut.jpg", lambda png, jpg: jpg[: len(jpg) // 2], "truncated JPEG (no end-of-image marker)"),
        ("text.png", lambda png, jpg: b"hello\n", "not an image OpenCV can read"),
    ],
)
def test_unreadable_or_cut_images_are_refused(tmp_path: Path, name: str, cut, message: str) -> None:
    cv2 = pytest.importorskip("cv2")
    from robocal.backends.vision import read_image
    from robocal.errors import FileFormatError

    picture = np.zeros((96, 128), np.uint8)
    picture[20:60, 30:90] = 255
    png = cv2.imencode(".png", picture)[1].tobytes()
    jpg = cv2.imencode(".jpg", picture)[1].tobytes()
    for whole, suffix in ((png, ".png"), (jpg, ".jpg")):  # the whole files read
        (tmp_path / f"whole{suffix}").write_bytes(whole)
        assert read_image(tmp_path / f"whole{suffix}").shape == (96, 128)
    (tmp_path / name).write_bytes(cut(png, jpg))
    with pytest.raises(FileFormatError) as err:
        read_image(tmp_path / name)
    assert str(err.value) == f"image {tmp_path / name}: {message}"
    with pytest.raises(FileFormatError, match="no such file"):
        read_image(tmp_path / "missing.png")


@pytest.mark.slow
@pytest.mark.parametrize(("sep", "name"), [(";", "semicolons"), ("\t", "tabs")])
def test_a_session_separated_by_semicolons_or_tabs_is_named(tmp_path: Path, capsys, sep: str, name: str) -> None:
    """A spreadsheet saved in a comma-decimal locale writes semicolons: the error says so, not "missing columns"."""
    assert main(["kinematics", "simulate", "--poses", "30", "--out", str(tmp_path)]) == 0
    capsys.readouterr()
    text = (tmp_path / "points.csv").read_text()
    bad = tmp_path / "excel.csv"
    bad.write_text(text.replace(",", sep))
    args = ["kinematics", "identify", "--urdf", str(tmp_path / "so101.urdf"), "--data", str(bad)]
    assert main([*args, "--tip-link", "gripper_link", "--report", str(tmp_path / "r.json")]) == 2
    assert capsys.readouterr().err == (
        f"error: {bad}: the header separates its columns with {name}; robocal reads comma-separated CSV (save the "
        "file with commas, and '.' as the decimal point)\n"
    )
    assert not (tmp_path / "r.json").exists()
