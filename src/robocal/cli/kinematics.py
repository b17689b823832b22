"""``robocal kinematics`` commands: identify, simulate."""

from __future__ import annotations

import math
from pathlib import Path
from typing import TYPE_CHECKING, Annotated

import typer

from ..errors import UsageError
from ._common import EXIT_INTERRUPTED, EXIT_OK, console, err_console, print_warning, print_warnings
from ._kinematics_options import (
    BaseLinkOption,
    CameraInfoOption,
    CameraOnToolOption,
    KindOption,
    TipLinkOption,
    ToolXyzOption,
    UrdfOption,
    parse_xyz,
)
from ._kinematics_plan import plan
from ._kinematics_print import print_identification, print_images
from ._options import LeRobotCalibrationDir, LeRobotId

if TYPE_CHECKING:
    from ..core.arrays import FloatArray
    from ..workflows.kinematics import job as wf
    from ..workflows.kinematics import sim as sim_wf

app = typer.Typer(
    help="Kinematic identification: measure an arm, identify its URDF errors, export a corrected URDF.",
    no_args_is_help=True,
)


def _prior(on: bool, mm: float | None, deg: float | None, offset_deg: float | None) -> bool | wf.PriorSigmas:
    """``--prior`` and its σ options (any σ option switches the prior on)."""
    from ..workflows.kinematics import job as wf

    if mm is None and deg is None and offset_deg is None:
        return on
    d = wf.PriorSigmas()
    for flag, v, top in (("--prior-mm", mm, 1000.0), ("--prior-deg", deg, 180.0), ("--prior-offset-deg", offset_deg, 180.0)):
        if v is not None and not (math.isfinite(v) and v > 0):
            raise UsageError(f"{flag} must be a positive number, got {v}")
        if v is not None and not 1e-6 <= v <= top:
            raise UsageError(f"{flag} must be from 1e-06 to {top:g}, got {v:g}")
    return wf.PriorSigmas(
        length_m=d.length_m if mm is None else mm * 1e-3,
        angle_rad=d.angle_rad if deg is None else math.radians(deg),
        offset_rad=d.offset_rad if offset_deg is None else math.radians(offset_deg),
    )


@app.command("identify")
def identify(
    urdf: UrdfOption,
    data: Annotated[
        Path, typer.Option("--data", help="Measurement CSV (joints…, x, y, z | group | socket).")
    ],
    kind: KindOption = "points",
    base_link: BaseLinkOption = None,
    tip_link: TipLinkOption = None,
    tool_xyz: ToolXyzOption = "0,0,0",
    frame: Annotated[
        str,
        typer.Option(
            "--frame", help="points measured in the 'base' link frame or an unknown 'tracker' frame."
        ),
    ] = "base",
    validate_fraction: Annotated[
        float | None,
        typer.Option("--validate-fraction", help="Share of poses held out for validation (default 0.25)."),
    ] = None,
    validate_data: Annotated[
        Path | None,
        typer.Option("--validate-data", help="Separate CSV of held-out poses (same columns); all of --data is fitted."),
    ] = None,
    huber: Annotated[
        float | None, typer.Option("--huber", help="Huber loss scale in mm (robust to outliers).")
    ] = None,
    prior: Annotated[
        bool,
        typer.Option("--prior", help="Gaussian prior around nominal (the URDF's tolerance); estimates every parameter."),
    ] = False,
    prior_mm: Annotated[
        float | None, typer.Option("--prior-mm", help="Prior σ of origins and tool point, mm (default 1; implies --prior).")
    ] = None,
    prior_deg: Annotated[
        float | None, typer.Option("--prior-deg", help="Prior σ of axis tilts, degrees (default 0.5; implies --prior).")
    ] = None,
    prior_offset_deg: Annotated[
        float | None,
        typer.Option("--prior-offset-deg", help="Prior σ of joint zero offsets, degrees (default 2; implies --prior)."),
    ] = None,
    gauge_mm: Annotated[
        float | None, typer.Option("--gauge-mm", help="Distance between gauge sockets A and B, mm.")
    ] = None,
    dh: Annotated[
        bool, typer.Option("--dh", help="Also fit a DH-like model and show its error floor.")
    ] = False,
    out: Annotated[Path | None, typer.Option("--out", help="Corrected URDF to write.")] = None,
    report: Annotated[Path | None, typer.Option("--report", help="JSON report to write.")] = None,
    seed: Annotated[int, typer.Option("--seed", help="Seed of the validation split.")] = 0,
    ticks: Annotated[
        int, typer.Option("--ticks", help="Encoder ticks per turn: readings on the same tick are one pose; 0: exact.")
    ] = 4096,
    noise_mm: Annotated[
        float | None,
        typer.Option("--noise-mm", help="Marker noise per axis, mm: a residual far above it is a warning naming the poses."),
    ] = None,
    max_correction_mm: Annotated[
        float, typer.Option("--max-correction-mm", help="Largest plausible length correction, mm; beyond it: refused.")
    ] = 20.0,
    max_correction_deg: Annotated[
        float, typer.Option("--max-correction-deg", help="Largest plausible angle correction, degrees; beyond it: refused.")
    ] = 10.0,
    joint_map: Annotated[
        Path | None,
        typer.Option("--joint-map", help="Joint map the readings went through (lerobot export-urdf output)."),
    ] = None,
    robot: Annotated[
        str | None, typer.Option("--robot", help="LeRobot arm whose calibration made the readings (no --joint-map).")
    ] = None,
    robot_id: LeRobotId = None,
    calibration_dir: LeRobotCalibrationDir = None,
    calibration_file: Annotated[
        Path | None, typer.Option("--calibration-file", help="LeRobot calibration JSON (instead of --id).")
    ] = None,
    joint_map_out: Annotated[
        Path | None,
        typer.Option("--joint-map-out", help="Joint map with the identified zero offsets (export-urdf format)."),
    ] = None,
    ur_yaml: Annotated[
        Path | None, typer.Option("--ur-yaml", help="ur_description kinematics YAML of the corrected UR chain.")
    ] = None,
    ur_hash: Annotated[
        str | None, typer.Option("--ur-hash", help="calib_<number> written into --ur-yaml (your robot's).")
    ] = None,
    camera: CameraInfoOption = None,
    target: Annotated[
        str | None,
        typer.Option("--target", help="--kind tag: apriltag:<family>:<id>:<size_mm> or charuco:<c>x<r>:<sq_mm>:<mk_mm>."),
    ] = None,
    camera_on_tool: CameraOnToolOption = False,
    refine_intrinsics: Annotated[
        bool, typer.Option("--refine-intrinsics", help="--kind tag: estimate fx, fy, cx, cy with the kinematics.")
    ] = False,
) -> None:
    """Identify the arm's geometric errors from measurements; write a corrected URDF and a report."""
    from ..core.kinematic_problem import ALL_KINDS, check_kind
    from ..workflows.kinematics import job as wf

    check_kind(kind.strip().lower(), ALL_KINDS)
    jm, ids = wf.identify_joint_map(joint_map, robot, robot_id, calibration_dir, calibration_file)
    outputs = wf.IdentifyOutputs(out, report, jm, joint_map_out, ids, ur_yaml, ur_hash)
    for flag, on in (("--camera-on-tool", camera_on_tool), ("--refine-intrinsics", refine_intrinsics)):
        if on and kind.strip().lower() != "tag":
            raise UsageError(f"{flag} applies to --kind tag (camera images)")
    if kind.strip().lower() == "tag":
        if camera is None or target is None:
            raise UsageError("--kind tag needs --camera (intrinsics from camera-calibrate) and --target")
        if validate_data is not None:
            raise UsageError("--validate-data applies to points, touch and gauge sessions; images use --validate-fraction")
        from ..workflows.kinematics import vision as vis_wf

        img = vis_wf.identify_images(vis_wf.ImageIdentifyRequest(
            urdf, data, camera=camera, target=target, base_link=base_link, tip_link=tip_link,
            validate_fraction=wf.DEFAULT_VALIDATE_FRACTION if validate_fraction is None else validate_fraction,
            huber_px=huber, seed=seed, camera_on_tool=camera_on_tool, refine_intrinsics=refine_intrinsics,
            prior=wf.as_prior(_prior(prior, prior_mm, prior_deg, prior_offset_deg)), ticks_per_turn=ticks,
            outputs=outputs,
        ))  # fmt: skip
        raise typer.Exit(print_images(img))
    result = wf.identify(
        wf.IdentifyRequest(
            urdf,
            data,
            kind=kind.strip().lower(),
            base_link=base_link,
            tip_link=tip_link,
            tool_xyz_m=parse_xyz(tool_xyz),
            frame=frame.strip().lower(),
            validate_fraction=validate_fraction,
            validate_data=validate_data,
            huber_m=None if huber is None else huber * 1e-3,
            prior=_prior(prior, prior_mm, prior_deg, prior_offset_deg),
            gauge_distance_m=None if gauge_mm is None else gauge_mm * 1e-3,
            dh=dh,
            seed=seed,
            ticks_per_turn=ticks,
            noise_m=None if noise_mm is None else noise_mm * 1e-3,
            max_correction_mm=max_correction_mm,
            max_correction_deg=max_correction_deg,
            outputs=outputs,
        )
    )
    raise typer.Exit(print_identification(result))


def _command(sim: sim_wf.SimulationResult, kind: str, gauge_mm: float) -> str:
    tool = ",".join(f"{v:g}" for v in sim.tool_xyz_m)
    extra = f" --gauge-mm {gauge_mm:g}" if kind == "gauge" else ""
    if sim.validation is not None:
        extra += f" --validate-data {sim.validation}"
    return (
        f"robocal kinematics identify --urdf {sim.urdf} --data {sim.data} --kind {kind} "
        f"--tip-link {sim.tip_link} --tool-xyz {tool}{extra}"
    )


@app.command("simulate")
def simulate(
    out: Annotated[Path, typer.Option("--out", help="Folder for <robot>.urdf, <kind>.csv and truth.json.")],
    robot: Annotated[str, typer.Option("--robot", help="so101 or koch.")] = "so101",
    kind: KindOption = "points",
    poses: Annotated[int, typer.Option("--poses", help="Poses (touch: per point; gauge: per socket).")] = 50,
    noise_mm: Annotated[float, typer.Option("--noise-mm", help="Marker noise per axis, mm (points).")] = 0.5,
    seed: Annotated[int, typer.Option("--seed", help="Seed of errors, poses and noise.")] = 0,
    on_axis: Annotated[
        bool, typer.Option("--on-axis", help="Put the marker on the wrist-roll axis.")
    ] = False,
    random_poses: Annotated[
        bool, typer.Option("--random-poses", help="Random poses (tag: random ones the camera sees) instead of the plan.")
    ] = False,
    gauge_mm: Annotated[float, typer.Option("--gauge-mm", help="Gauge socket distance, mm.")] = 50.0,
    camera_on_tool: CameraOnToolOption = False,
    validation_poses: Annotated[
        int,
        typer.Option("--validation-poses", help="Also write <kind>_validation.csv: random held-out poses (not tag)."),
    ] = 0,
    ticks: Annotated[
        int, typer.Option("--ticks", help="Encoder ticks per turn the joint readings are rounded to; 0: exact.")
    ] = 4096,
) -> None:
    """Simulate a measurement session on an arm with hidden errors (1 mm, 0.5°, 2° σ; --ticks joint readings)."""
    if out.exists() and not out.is_dir():
        raise UsageError(f"--out {out} is a file; give a folder")
    from ..core.kinematic_problem import ALL_KINDS, check_kind
    from ..workflows.kinematics import sim as sim_wf

    kind = check_kind(kind.strip().lower(), ALL_KINDS)
    if not (math.isfinite(gauge_mm) and gauge_mm > 0):
        raise UsageError(f"--gauge-mm must be a positive number, got {gauge_mm}")
    if camera_on_tool and kind != "tag":
        raise UsageError("--camera-on-tool applies to --kind tag (camera images)")
    if validation_poses and kind == "tag":
        raise UsageError("--validation-poses applies to points, touch and gauge; tag images are held out by a share")
    if kind == "tag":
        from ..workflows.kinematics import vision as vis_wf

        img = vis_wf.simulate_images(vis_wf.SimImagesRequest(
            robot.strip().lower(), out, poses=poses, seed=seed, camera_on_tool=camera_on_tool, plan=not random_poses,
            ticks_per_turn=ticks,
        ))  # fmt: skip
        console.print(
            f"wrote {img.urdf}, {img.data} ({poses} images of {img.target}), {len(img.calibration_images)} "
            f"calibration images of {img.board} in {out / 'calibration'}, {img.truth}"
        )
        console.print(
            f"next: robocal kinematics camera-calibrate {out / 'calibration'}/*.png --board {img.board} "
            f"--out {out / 'camera.yaml'}"
        )
        console.print(
            f"then: robocal kinematics identify --kind tag --urdf {img.urdf} --data {img.data} --camera "
            f"{out / 'camera.yaml'} --target {img.target} --tip-link {img.tip_link}"
            + (" --camera-on-tool" if camera_on_tool else "")
        )
        raise typer.Exit(EXIT_OK)
    sim = sim_wf.simulate(
        sim_wf.SimulationRequest(
            robot.strip().lower(),
            out,
            kind=kind,
            poses=poses,
            noise_m=noise_mm * 1e-3,
            seed=seed,
            on_axis=on_axis,
            plan=not random_poses,
            gauge_distance_m=gauge_mm * 1e-3,
            validation_poses=validation_poses,
            ticks_per_turn=ticks,
        )
    )
    held = ""
    if sim.validation is not None and sim.validation_measurements is not None:
        held = f", {sim.validation} ({sim.validation_measurements.n_poses} held-out poses)"
    console.print(f"wrote {sim.urdf}, {sim.data} ({sim.measurements.n_poses} poses){held}, {sim.truth}")
    console.print(f"next: {_command(sim, kind, gauge_mm)}")
    raise typer.Exit(EXIT_OK)


app.command("plan")(plan)


@app.command("camera-calibrate")
def camera_calibrate(
    images: Annotated[list[Path], typer.Argument(help="Images of a ChArUco board (PNG, JPEG, ...).")],
    board: Annotated[
        str, typer.Option("--board", help="charuco:<cols>x<rows>:<square_mm>:<marker_mm>[:<dictionary>].")
    ],
    out: Annotated[Path, typer.Option("--out", help="Camera intrinsics to write (ROS camera_info YAML).")],
) -> None:
    """Calibrate a camera's intrinsics from ChArUco board images (OpenCV) for identify --kind tag."""
    from ..workflows.kinematics import vision as vis_wf

    result = vis_wf.camera_calibrate(images, board, out)
    K = result.camera.K
    console.print(
        f"{result.used} of {len(images)} images: fx {K[0, 0]:.2f}, fy {K[1, 1]:.2f}, cx {K[0, 2]:.2f}, "
        f"cy {K[1, 2]:.2f} px; distortion {', '.join(f'{v:.4g}' for v in result.camera.distortion)}; "
        f"RMS reprojection {result.camera.rms_px:.3f} px"
    )
    console.print(f"wrote {result.out}")
    raise typer.Exit(print_warnings(result.warnings))


def _stdin_ask(prompt: str) -> str:
    """Show ``prompt`` on stderr and read one line from stdin (EOFError at the end of input)."""
    import sys

    err_console.print(prompt + ": ", end="")
    line = sys.stdin.readline()
    if line == "":
        raise EOFError
    return line.rstrip("\n")


@app.command("record")
def record(
    out: Annotated[Path, typer.Option("--out", help="Session CSV to write (what identify --data reads).")],
    urdf: Annotated[
        Path | None, typer.Option("--urdf", help="Expanded URDF (default for --robot so101_*/koch_*: shipped).")
    ] = None,
    base_link: BaseLinkOption = None,
    tip_link: TipLinkOption = None,
    kind: Annotated[str, typer.Option("--kind", help="points, touch, gauge or tag.")] = "points",
    lerobot_port: Annotated[
        str | None, typer.Option("--lerobot-port", help="Serial port of a LeRobot arm (torque is switched off).")
    ] = None,
    robot: Annotated[
        str | None, typer.Option("--robot", help="LeRobot arm: so101_follower, so101_leader, koch_follower, ...")
    ] = None,
    robot_id: LeRobotId = None,
    calibration_dir: LeRobotCalibrationDir = None,
    file: Annotated[Path | None, typer.Option("--file", help="LeRobot calibration JSON (instead of --id).")] = None,
    source: Annotated[
        str | None, typer.Option("--source", help="Any robocal source: sim:lite, can:<if>:<ch>, replay:<file>.")
    ] = None,
    joint_map: Annotated[
        Path | None,
        typer.Option(
            "--joint-map",
            help="Raw → URDF joint map (lerobot export-urdf output, or any calibration file for --source).",
        ),
    ] = None,
    poses: Annotated[int | None, typer.Option("--poses", help="Stop after this many poses.")] = None,
    image_pattern: Annotated[
        str, typer.Option("--image-pattern", help="Default image per pose (tag), e.g. shots/pose_{pose:03d}.png.")
    ] = "pose_{pose:03d}.png",
    plan: Annotated[
        Path | None, typer.Option("--plan", help="Poses to show one by one (kinematics plan output).")
    ] = None,
) -> None:
    """Record a session: move the arm by hand, press Enter per pose, give the measurement; writes the CSV."""
    from ..workflows.kinematics import record as rec_wf

    if (lerobot_port is None) == (source is None):
        raise UsageError("give either --lerobot-port (with --robot) or --source")
    kind = kind.strip().lower()
    from ..workflows.kinematics.record_arm import ArmSource, check_session, open_reader

    arm = ArmSource(
        urdf=urdf,
        base_link=base_link,
        tip_link=tip_link,
        lerobot_port=lerobot_port,
        robot=robot,
        robot_id=robot_id,
        calibration_dir=calibration_dir,
        calibration_file=file,
        source=source,
        joint_map=joint_map,
    )
    check_session(kind, out, arm, plan)  # before the port opens: a LeRobot arm goes limp then
    reader, chain = open_reader(arm)
    try:
        targets: FloatArray | None = None
        labels: tuple[str, ...] = ()
        if plan is not None:
            targets, labels = rec_wf.plan_targets(plan, chain)
        err_console.print(
            f"recording {kind} poses of {', '.join(chain.joint_names)} (chain {chain.base_link} → {chain.tip_link})"
        )
        session = rec_wf.RecordRequest(
            out, kind=kind, poses=poses, image_pattern=image_pattern, targets=targets, target_labels=labels
        )
        result = rec_wf.record(
            reader, chain, session, ask=_stdin_ask, say=lambda m: err_console.print(m, markup=False)
        )
    finally:
        reader.close()
    console.print(f"wrote {result.out} ({result.measurements.n_poses} poses)")
    if result.interrupted:
        print_warning(f"interrupted: the {result.measurements.n_poses} poses recorded so far were written")
        raise typer.Exit(EXIT_INTERRUPTED)
    raise typer.Exit(print_warnings(result.skipped))


__all__ = ["app", "print_identification"]
