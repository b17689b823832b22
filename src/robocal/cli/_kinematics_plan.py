"""``robocal kinematics plan``: poses to measure (points, touch, gauge) or to photograph (tag)."""

from __future__ import annotations

import math
from pathlib import Path
from typing import TYPE_CHECKING, Annotated

import typer

from ..errors import UsageError
from ._common import EXIT_OK, console, print_warnings
from ._kinematics_options import (
    BaseLinkOption,
    CameraInfoOption,
    CameraOnToolOption,
    TipLinkOption,
    ToolXyzOption,
    UrdfOption,
    parse_numbers,
    parse_xyz,
)

if TYPE_CHECKING:
    from ..workflows.kinematics.plan_images import ImagePlanRequest

__all__ = ["plan"]

_TAG_ONLY = ("--camera", "--target", "--camera-pose", "--target-pose", "--look-at", "--camera-on-tool",
             "--refine-intrinsics", "--noise-px")  # fmt: skip


def plan(
    urdf: UrdfOption,
    out: Annotated[Path, typer.Option("--out", help="CSV of joint targets to write.")],
    poses: Annotated[
        int | None, typer.Option("--poses", help="How many poses (default 50; tag: 40).")
    ] = None,
    base_link: BaseLinkOption = None,
    tip_link: TipLinkOption = None,
    tool_xyz: ToolXyzOption = "0,0,0",
    kind: Annotated[
        str,
        typer.Option(
            "--kind",
            help="points (free poses), touch or gauge (poses on --touch-points), tag (camera images).",
        ),
    ] = "points",
    touch_points: Annotated[
        str | None,
        typer.Option(
            "--touch-points", help="touch: fixed points, gauge: sockets A;B; x,y,z in metres, ';' between."
        ),
    ] = None,
    frame: Annotated[
        str, typer.Option("--frame", help="base: points in the base frame; tracker: in an unknown frame.")
    ] = "base",
    criterion: Annotated[
        str, typer.Option("--criterion", help="i: smallest average prediction variance; d: largest O1.")
    ] = "i",
    prior: Annotated[
        bool,
        typer.Option(
            "--prior", help="Plan for a fit with the URDF tolerance prior (identify --prior; criterion i; tag too)."
        ),
    ] = False,
    noise_mm: Annotated[float, typer.Option("--noise-mm", help="Tracker noise per axis, mm.")] = 0.5,
    candidates: Annotated[
        int,
        typer.Option(
            "--candidates",
            help="Random candidate poses inside the joint limits (tag: where the camera sees it).",
        ),
    ] = 2000,
    candidates_file: Annotated[
        Path | None,
        typer.Option(
            "--candidates-file", help="Choose among these poses (a joint CSV) instead of random ones."
        ),
    ] = None,
    seed: Annotated[int, typer.Option("--seed", help="Seed of the random candidates.")] = 0,
    camera: CameraInfoOption = None,
    target: Annotated[
        str | None,
        typer.Option(
            "--target", help="tag: apriltag:<family>:<id>:<size_mm> or charuco:<c>x<r>:<sq_mm>:<mk_mm>."
        ),
    ] = None,
    camera_pose: Annotated[
        str | None,
        typer.Option(
            "--camera-pose",
            help="tag: camera x,y,z,roll,pitch,yaw (m, rad; OpenCV axes, z forward) in the base frame "
            "(--camera-on-tool: in the tip link), or x,y,z with --look-at.",
        ),
    ] = None,
    look_at: Annotated[
        str | None,
        typer.Option("--look-at", help="tag: the point the fixed camera looks at, x,y,z (m, base frame)."),
    ] = None,
    target_pose: Annotated[
        str,
        typer.Option(
            "--target-pose",
            help="tag: target x,y,z,roll,pitch,yaw (m, rad) on the tip link (--camera-on-tool: in the base frame).",
        ),
    ] = "0,0,0,0,0,0",
    camera_on_tool: CameraOnToolOption = False,
    refine_intrinsics: Annotated[
        bool, typer.Option("--refine-intrinsics", help="tag: plan for a fit that refines fx, fy, cx, cy.")
    ] = False,
    noise_px: Annotated[
        float, typer.Option("--noise-px", help="tag: corner noise per axis, pixels (predicted σ).")
    ] = 0.3,
    validation_poses: Annotated[
        int,
        typer.Option(
            "--validation-poses",
            help="Also write <out>_validation.csv: random held-out poses to record apart (identify --validate-data).",
        ),
    ] = 0,
) -> None:
    """Choose poses inside the joint limits that identify the arm best (greedy I- or D-optimal)."""
    from ..core.kinematic_problem import ALL_KINDS, check_kind

    kind = check_kind(kind.strip().lower(), ALL_KINDS)
    if kind == "tag":
        if validation_poses:
            raise UsageError("--validation-poses applies to points, touch and gauge; images use --validate-fraction")
        not_tag = {
            "--tool-xyz (the target's place is --target-pose)": tool_xyz != "0,0,0",
            "--touch-points": touch_points is not None,
            "--frame": frame.strip().lower() != "base",
            "--criterion d": criterion.strip().lower() != "i",
        }
        wrong = [f for f, on in not_tag.items() if on]
        if wrong:
            raise UsageError(f"{', '.join(wrong)}: not for --kind tag")
        if camera is None or target is None or camera_pose is None:
            raise UsageError("--kind tag needs --camera (intrinsics), --target and --camera-pose")
        if look_at is not None and camera_on_tool:
            raise UsageError(
                "--look-at places a fixed camera; with --camera-on-tool give --camera-pose with six numbers"
            )
        from ..workflows.kinematics import plan_images as tag_wf

        T_camera = tag_wf.frame_from_pose(
            parse_numbers(camera_pose, "--camera-pose", "0.1,0,0.5,3.1416,0,0"),
            "--camera-pose",
            None if look_at is None else parse_xyz(look_at, "--look-at"),
        )
        T_target = tag_wf.frame_from_pose(
            parse_numbers(target_pose, "--target-pose", "0,0,0,0,0,0"), "--target-pose"
        )
        raise typer.Exit(_plan_tag(tag_wf.ImagePlanRequest(
            urdf, out, camera=camera, target=target, T_camera=T_camera, T_target=T_target,
            camera_on_tool=camera_on_tool, refine_intrinsics=refine_intrinsics, poses=40 if poses is None else poses,
            base_link=base_link, tip_link=tip_link, noise_px=noise_px, candidates=candidates,
            candidates_file=candidates_file, seed=seed, prior=prior,
        )))  # fmt: skip
    given = {
        "--camera": camera is not None, "--target": target is not None, "--camera-pose": camera_pose is not None,
        "--look-at": look_at is not None, "--target-pose": target_pose != "0,0,0,0,0,0",
        "--camera-on-tool": camera_on_tool, "--refine-intrinsics": refine_intrinsics, "--noise-px": noise_px != 0.3,
    }  # fmt: skip
    wrong = [f for f in _TAG_ONLY if given[f]]
    if wrong:
        raise UsageError(
            f"{', '.join(wrong)} {'apply' if len(wrong) > 1 else 'applies'} to --kind tag (camera images)"
        )
    from ..workflows.kinematics import plan as plan_wf

    result = plan_wf.plan(
        plan_wf.PlanRequest(
            urdf,
            out,
            poses=50 if poses is None else poses,
            base_link=base_link,
            tip_link=tip_link,
            tool_xyz_m=parse_xyz(tool_xyz),
            kind=kind,
            frame=frame.strip().lower(),
            criterion=criterion.strip(),
            prior=prior,
            noise_m=noise_mm * 1e-3,
            candidates=candidates,
            candidates_file=candidates_file,
            seed=seed,
            touch_points_m=[parse_xyz(p, "--touch-points") for p in (touch_points or "").split(";") if p.strip()],
            validation_poses=validation_poses,
        )
    )
    ident = result.identifiability
    obs = ident.observability
    console.print(
        f"{len(result.q_rad)} poses ({result.criterion}-optimal of {result.candidates} candidates) for "
        f"{', '.join(result.joint_names)}: rank {ident.rank}, condition number {obs.condition:.1f}, "
        f"O1 {obs.O1:.3g}, O3 {obs.O3:.3g}"
        + (
            f"; predicted tool-point σ {result.prediction_sigma_m * 1e3:.3f} mm (RMS over the candidates, "
            f"{noise_mm:g} mm tracker noise)"
            if math.isfinite(result.prediction_sigma_m)
            else ""
        )
    )
    warnings = [
        f"{u.name}: {u.reason}" for u in ident.unidentifiable if u.reason.startswith("the marker is on")
    ]
    console.print(
        f"wrote {result.out}; move the arm to each pose and "
        + ("add x,y,z columns as you measure" if kind == "points" else "touch the point it names")
    )
    if result.validation_out is not None:
        console.print(
            f"wrote {result.validation_out} ({validation_poses} random held-out poses): record them as a session "
            "of their own and give it to identify with --validate-data, so that every planned pose is fitted"
        )
    raise typer.Exit(print_warnings(warnings))


def _plan_tag(request: ImagePlanRequest) -> int:
    """``plan --kind tag``: run the request, print and return the exit code."""
    from ..workflows.kinematics import plan_images as tag_wf

    result = tag_wf.plan_images(request)
    ident = result.identifiability
    obs = ident.observability
    what = "camera's centre in the target frame" if request.camera_on_tool else "target's centre in the camera frame"
    console.print(
        f"{len(result.q_rad)} images ({'Bayesian ' if request.prior else ''}I-optimal of {result.candidates} poses where the camera sees the target, "
        f"from {result.drawn} tried) for {', '.join(result.joint_names)}: rank {ident.rank} of "
        f"{len(ident.names)} unknowns, condition number {obs.condition:.1f}, O1 {obs.O1:.3g}, O3 {obs.O3:.3g}"
    )
    if math.isfinite(result.prediction_sigma_m):
        console.print(
            f"predicted σ of the {what} after identification {result.prediction_sigma_m * 1e3:.3f} mm "
            f"(RMS over the candidates, {request.noise_px:g} px corner noise"
            + (", with the tolerance prior)" if request.prior else ")")
        )
    console.print(
        f"wrote {result.out}; move the arm to each pose and take the picture "
        "(robocal kinematics record --kind tag --plan shows them one by one)"
    )
    return EXIT_OK
