"""``robocal health`` commands: watch a robot's readings live for calibration faults (issue 30)."""

from __future__ import annotations

import pathlib
from typing import TYPE_CHECKING, Annotated

import typer

from . import _common
from ._options import LeRobotCalibrationDir, LeRobotId

if TYPE_CHECKING:
    from ..core.health import HealthFlag

app = typer.Typer(
    help="Calibration health: watch a robot's readings live for a calibration that has gone wrong.",
    no_args_is_help=True,
)


@app.command()
def watch(
    lerobot_port: Annotated[
        str | None,
        typer.Option(
            "--lerobot-port", help="A LeRobot arm's serial port ('sim': a simulated arm), with --robot."
        ),
    ] = None,
    robot: Annotated[
        str | None,
        typer.Option(
            "--robot",
            help="so101_follower | so101_leader | so100_… | koch_… (the LeRobot robot profiles; or a profile "
            "file); with --source, the robot profile (default: recognised from the URDF).",
        ),
    ] = None,
    robot_id: LeRobotId = None,
    calibration_dir: LeRobotCalibrationDir = None,
    source: Annotated[
        str | None,
        typer.Option(
            "--source",
            help="can:<interface>:<channel>[,<channel>…] (Robstride joints), sim:lite or replay:<file>; with "
            "--urdf and --calibration.",
        ),
    ] = None,
    urdf: Annotated[
        pathlib.Path | None, typer.Option("--urdf", help="--source: the URDF (the joints' stops).")
    ] = None,
    calibration: Annotated[
        pathlib.Path | None,
        typer.Option(
            "--calibration",
            "--file",
            help="--source: the calibration file (any format robocal reads); --lerobot-port: LeRobot's JSON "
            "(instead of --id).",
        ),
    ] = None,
    margin_deg: Annotated[
        float, typer.Option("--margin-deg", help="How far past a stop a reading may go, degrees.")
    ] = 2.0,
    max_speed_deg_s: Annotated[
        float,
        typer.Option("--max-speed-deg-s", help="Fastest a joint moves, °/s (faster changes are steps)."),
    ] = 360.0,
    max_accel_deg_s2: Annotated[
        float,
        typer.Option(
            "--max-accel-deg-s2",
            help="Fastest a reading's speed changes, °/s² (2865 °/s² = 50 rad/s², a brisk hand).",
        ),
    ] = 2865.0,
    seconds: Annotated[
        float | None, typer.Option("--seconds", help="Stop after this long (default: until Ctrl-C).")
    ] = None,
    rate_hz: Annotated[float, typer.Option("--rate-hz", help="Readings per second of an arm's bus.")] = 60.0,
    leader_port: Annotated[
        str | None,
        typer.Option(
            "--leader-port",
            help="Teleoperation: the leader arm's port; its readings are watched too and a follower joint pinned "
            "while its leader goes on is flagged (not the gripper).",
        ),
    ] = None,
    leader_robot: Annotated[
        str | None,
        typer.Option("--leader-robot", help="--leader-port: the leader's profile (so101_leader, ...)."),
    ] = None,
    leader_id: Annotated[
        str | None,
        typer.Option("--leader-id", help="--leader-port: the leader's calibration id (<id>.json)."),
    ] = None,
    leader_file: Annotated[
        pathlib.Path | None,
        typer.Option(
            "--leader-file", help="--leader-port: the leader's calibration JSON (instead of --leader-id)."
        ),
    ] = None,
) -> None:
    """Watch a robot's joint readings live, read-only, and print each calibration fault as it happens.

    A reading past its stops (+ margin), a step its speed cannot explain (an encoder zero lost, a horn that jumped a tooth), a reading a whole turn off (Robstride), a follower pinned while its leader goes on (--leader-port). Exit 0 nothing flagged, 1 flagged, 2 bad input, 3 device failure; Ctrl-C ends it (130). docs/health.md.
    """
    from ..workflows.health import WatchRequest
    from ..workflows.health import watch as run

    request = WatchRequest(
        lerobot_port=lerobot_port,
        robot=robot,
        robot_id=robot_id,
        calibration_dir=calibration_dir,
        calibration_file=calibration,
        source=source,
        urdf=urdf,
        margin_deg=margin_deg,
        max_speed_deg_s=max_speed_deg_s,
        max_accel_deg_s2=max_accel_deg_s2,
        seconds=seconds,
        rate_hz=rate_hz,
        leader_port=leader_port,
        leader_robot=leader_robot,
        leader_id=leader_id,
        leader_file=leader_file,
    )
    flags: list[HealthFlag] = []

    def on_flag(flag: HealthFlag) -> None:
        flags.append(flag)
        _common.console.print(f"{flag.t_s:10.3f} s  {flag.message}", markup=False)

    def on_start(names: tuple[str, ...], where: str) -> None:
        until = f"for {seconds:g} s" if seconds is not None else "until Ctrl-C"
        text = f"watching {len(names)} joints of {where} {until}: {', '.join(names)}"
        _common.err_console.print(text, markup=False)

    try:
        result = run(request, on_flag, on_start=on_start)
    except KeyboardInterrupt:
        _common.err_console.print(f"{len(flags)} flag(s) before the interruption", markup=False)
        raise
    _common.console.print(
        f"watched {len(result.joint_names)} joints, {result.ticks} readings over {result.seconds:.1f} s: "
        f"{len(result.flags)} flag(s)",
        markup=False,
    )
    raise typer.Exit(_common.exit_code_for(result.flags))
