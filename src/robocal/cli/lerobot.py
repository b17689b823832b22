"""``robocal lerobot`` commands: calibrate, configure, check, migrate, show, export-urdf."""

from __future__ import annotations

import pathlib
from typing import TYPE_CHECKING, Annotated, Any

import typer
from rich.table import Table

from ..errors import UsageError
from . import _common
from ._left_changed import offer_restore
from ._lerobot_render import (
    ConsoleOperator,
    interrupted,
    print_calibration,
    print_range_warnings,
    status,
    sweep_renderer,
)
from ._options import (
    LeRobotCalibrationDir,
    LeRobotCompat,
    LeRobotId,
    LeRobotModes,
    LeRobotPhysical,
    LeRobotUseDegrees,
)

if TYPE_CHECKING:
    from ..core.lerobot import RobotSpec
    from ..core.lerobot.calibration import MotorCalibration

app = typer.Typer(
    help="LeRobot arms: calibrate, configure, check, migrate, show, export-urdf.", no_args_is_help=True
)

ROBOT_HELP = (
    "so100_follower | so100_leader | so101_follower | so101_leader | koch_follower | koch_leader "
    "(the LeRobot robot profiles; or a profile file)"
)
Robot = Annotated[str, typer.Option("--robot", help=ROBOT_HELP)]
ArmPort = Annotated[str, typer.Option("--port", help="Serial port of the arm, or 'sim'.")]
CalFile = Annotated[pathlib.Path | None, typer.Option("--file", help="Calibration JSON (instead of --id).")]


def _modes(spec: RobotSpec, use_degrees: bool | None, modes: str | None) -> tuple[str, ...]:
    from ..workflows.lerobot import norm_modes

    return norm_modes(spec, use_degrees=use_degrees, overrides=_common.parse_assignments(modes, "--modes"))


def _spec(robot: str) -> RobotSpec:
    from ..workflows.lerobot import robot_spec

    return robot_spec(robot)


def _scaled(
    robot: str,
    use_degrees: bool | None,
    modes_opt: str | None,
    robot_id: str | None,
    calibration_dir: pathlib.Path | None,
    file: pathlib.Path | None,
) -> tuple[RobotSpec, tuple[str, ...], dict[str, MotorCalibration]]:
    """The arm, its norm modes (a bad ``--modes`` is refused before any file or bus I/O) and its calibration."""
    spec = _spec(robot)
    modes = _modes(spec, use_degrees, modes_opt)
    _path, cals = _read_cal_file(spec, robot_id, calibration_dir, file)
    return spec, modes, cals


def _cal_file(
    spec: RobotSpec,
    robot_id: str | None,
    calibration_dir: pathlib.Path | None,
    file: pathlib.Path | None,
    *,
    reading: bool = True,
) -> pathlib.Path:
    """The calibration file (the workflow's choice); warns when LeRobot's pre-v0.4.3 folder is used."""
    from ..workflows.lerobot import calibration_file

    path, note = calibration_file(spec, robot_id, calibration_dir, file, reading=reading)
    if note is not None:
        _common.print_warning(note)
    return path


def _read_cal_file(
    spec: RobotSpec, robot_id: str | None, calibration_dir: pathlib.Path | None, file: pathlib.Path | None
) -> tuple[pathlib.Path, dict[str, MotorCalibration]]:
    """The calibration file (:func:`_cal_file`) and what it holds, per motor."""
    from ..workflows.lerobot import read_calibration_file

    path = _cal_file(spec, robot_id, calibration_dir, file)
    return path, read_calibration_file(path)


def _web_view(robot: str, spec: Any, inner: Any, port: int) -> Any:
    """``--view``: the page drawing the recorded ranges on the arm (robocal.viewer.sweep_page); URL printed."""
    from ..viewer.lerobot_sweep_page import open_lerobot_sweep_page

    web = open_lerobot_sweep_page(robot, spec.motor_names, inner=inner, port=port)
    _common.err_console.print(f"calibration view: {web.app.url}")
    return web


@app.command()
def calibrate(
    robot: Robot,
    port: str = typer.Option(..., "--port", help="Serial port, or 'sim' for the simulated arm."),
    robot_id: str = typer.Option(..., "--id", help="Robot id: the file is <id>.json."),
    calibration_dir: LeRobotCalibrationDir = None,
    home_after_sweep: bool = typer.Option(
        False, "--home-after-sweep", help="Sweep first, then centre homing."
    ),
    sweep_full_turn: bool = typer.Option(
        False, "--sweep-full-turn", help="Also sweep wrist_roll (and Koch shoulder_pan) instead of 0..4095."
    ),
    use_file: bool = typer.Option(False, "--use-file", help="Write the existing file to the motors instead."),
    web_view: bool = typer.Option(
        False, "--view", help="Also draw the recorded ranges on the arm in the browser (robocal[view])."
    ),
    view_port: int = typer.Option(8080, "--view-port", help="TCP port of the --view page (0: any)."),
    auto: bool = typer.Option(
        False,
        "--auto",
        help="The joints find their own hard stops (low torque, bounded travel and time); --port "
        "'sim?missing=gripper&seed=3' for a simulated arm with faults. docs/auto_calibration.md.",
    ),
    joints: str | None = typer.Option(None, "--joints", help="--auto: only these joints (comma-separated)."),
    partial: bool = typer.Option(
        False, "--partial", help="--auto: write the joints that passed although others failed (exit 1)."
    ),
    yes: bool = typer.Option(False, "--yes", help="--auto: skip the clear-workspace question (scripts)."),
    urdf: pathlib.Path | None = typer.Option(
        None,
        "--urdf",
        help="--auto: the arm's URDF with <inertial> masses; its gravity model corrects the stops "
        "(default with --port sim: the simulated arm's shipped URDF).",
    ),
    verify: bool = typer.Option(
        False,
        "--verify",
        help="--auto: touch the stops again and report per joint how far the stored calibration (--id) has "
        "drifted, degrees ± uncertainty; nothing is written; exit 1 past --tolerance-deg.",
    ),
    tolerance_deg: float = typer.Option(
        2.0, "--tolerance-deg", help="--verify: drift above which a joint is flagged, degrees."
    ),
) -> None:
    """Calibrate a LeRobot arm (mid pose, then sweep every joint, or --auto) and write LeRobot's JSON."""
    from ._lerobot_auto import auto_request, calibrate_auto, check_auto_options, verify_auto

    check_auto_options(
        auto=auto,
        joints=joints,
        partial=partial,
        yes=yes,
        use_file=use_file,
        home_after_sweep=home_after_sweep,
        web_view=web_view,
        urdf=urdf,
        verify=verify,
    )
    from ..workflows.lerobot import (
        CalibrateRequest,
        CalibrationNotSavedError,
        calibration_json,
        check_calibration_writable,
        open_arm,
        read_calibration_file,
        restore,
        sim_operator,
    )
    from ..workflows.lerobot import calibrate as run

    spec = _spec(robot)
    path = _cal_file(spec, robot_id, calibration_dir, None, reading=use_file or verify)
    if verify:
        verify_auto(robot, spec, port, path, joints=joints, yes=yes, tolerance_deg=tolerance_deg, urdf=urdf)
    if use_file:
        cals = read_calibration_file(path)
        beyond = print_range_warnings(spec, cals)
        with open_arm(spec, port) as (bus, _arm):
            offer_restore(bus, spec, port, _arm)
            try:
                restore(bus, spec, cals, on_status=status, snapshot_port=port if _arm is None else None)
            except KeyboardInterrupt as exc:
                raise interrupted(exc, "the motors' previous EEPROM was written back") from None
        print_calibration(cals)
        _common.console.print(f"wrote {path} to the motors")
        raise typer.Exit(_common.exit_code_for(beyond))
    # the calibration folder must be writable before the port is even opened (the workflow checks again)
    check_calibration_writable(path)
    if auto:
        request = auto_request(
            robot, spec, port, path, joints=joints, partial=partial, sweep_full_turn=sweep_full_turn, urdf=urdf
        )
        calibrate_auto(request, robot, port, yes=yes, view_port=view_port if web_view else None)
    update, close = sweep_renderer()
    web = _web_view(robot, spec, update, view_port) if web_view else None
    with open_arm(spec, port) as (bus, arm):
        offer_restore(bus, spec, port, arm)
        operator: object = sim_operator(arm) if arm is not None else ConsoleOperator()

        def status_line(message: str) -> None:
            close()  # the live table ends before the first status line
            status(message)

        try:
            result = run(
                bus,
                CalibrateRequest(
                    spec,
                    path=path,
                    home_after_sweep=home_after_sweep,
                    sweep_full_turn=sweep_full_turn,
                    snapshot_port=port if arm is None else None,
                ),
                operator,  # type: ignore[arg-type]
                on_sweep=update if web is None else web,
                on_status=status_line,
            )
        except KeyboardInterrupt as exc:
            close()
            raise interrupted(
                exc,
                "every motor's EEPROM was restored and no file was written",
                "; no file was written",
            ) from None
        except CalibrationNotSavedError as exc:
            close()
            _common.console.print(calibration_json(exc.calibration), markup=False)
            raise UsageError(
                f"{exc}; the calibration is printed above as LeRobot JSON: save it and write it to the motors "
                "with `robocal lerobot calibrate --use-file`"
            ) from None
        finally:
            close()
            if web is not None:
                web.app.stop()
    print_calibration(result.calibration)
    for note in result.notes:
        _common.print_warning(note)
    _common.console.print(f"calibration saved to {result.path}")
    raise typer.Exit(_common.exit_code_for(result.notes))


@app.command()
def configure(
    robot: Robot,
    port: ArmPort,
    robot_id: str | None = typer.Option(None, "--id", help="Robot id (Koch leader: gripper trigger)."),
    calibration_dir: LeRobotCalibrationDir = None,
    file: CalFile = None,
    gripper_open_pos: float = typer.Option(
        50.0, "--gripper-open-pos", min=0.0, max=100.0, help="Koch leader trigger goal, 0..100 (LeRobot: 50)."
    ),
) -> None:
    """Apply LeRobot's motor presets: return delay, acceleration, PID, operating modes, gripper limits/trigger."""
    from ..workflows.lerobot import configure as run
    from ..workflows.lerobot import open_arm

    spec = _spec(robot)
    warnings: list[str] = []
    cals = None
    if spec.name == "koch_leader":
        if robot_id is None and file is None:
            warnings.append(
                "gripper trigger not set: give --id or --file (its goal is a calibrated position)"
            )
        else:
            _path, cals = _read_cal_file(spec, robot_id, calibration_dir, file)
    with open_arm(spec, port) as (bus, arm):
        offer_restore(bus, spec, port, arm)
        if arm is not None and cals is not None:
            from ..workflows.lerobot import restore

            restore(bus, spec, cals)
        try:
            written = run(
                bus,
                spec,
                calibration=cals,
                gripper_open_pos=gripper_open_pos,
                on_status=status,
                snapshot_port=port if arm is None else None,
            )
        except KeyboardInterrupt as exc:
            raise interrupted(
                exc, "every motor is limp and every register written so far was written back"
            ) from None
    t = Table(title=f"{spec.name}: registers written")
    t.add_column("motor")
    t.add_column("registers")
    per_motor: dict[str, list[str]] = {}
    for name, register, value in written:
        per_motor.setdefault(name, []).append(f"{register}={value}")
    for name, regs in per_motor.items():
        t.add_row(name, ", ".join(regs))
    _common.console.print(t)
    if any(r == "Goal_Position" for _n, r, _v in written):
        _common.console.print(f"gripper trigger: torque on, held at {gripper_open_pos:g} % open")
    raise typer.Exit(_common.print_warnings(warnings))


@app.command()
def check(
    robot: Robot,
    port: str = typer.Option(..., "--port", help="Serial port of the arm, or 'sim' for a simulated arm."),
    robot_id: str | None = typer.Option(None, "--id", help="Robot id."),
    calibration_dir: LeRobotCalibrationDir = None,
    file: CalFile = None,
) -> None:
    """Compare the motors' EEPROM with the calibration file, naming each motor and field that differs."""
    from ..workflows.lerobot import check as run
    from ..workflows.lerobot import open_arm

    spec = _spec(robot)
    path, cals = _read_cal_file(spec, robot_id, calibration_dir, file)
    beyond = print_range_warnings(spec, cals)
    with open_arm(spec, port) as (bus, _arm):
        offer_restore(bus, spec, port, _arm)
        diffs = run(bus, spec, cals)
    for d in diffs:
        _common.console.print(f"differs: {d}")
    if not diffs:
        _common.console.print(f"EEPROM matches {path}")
    raise typer.Exit(_common.exit_code_for([*diffs, *beyond]))


_LEGACY_DATASET_NOTE_OTHER = (
    "old datasets (legacy degrees): key = name.removeprefix('main_') + '.pos'; convert the values exactly with "
    "`robocal dataset recalibrate --old LEGACY.json --new CURRENT.json`"
)
_LEGACY_DATASET_NOTES = {
    "feetech": (  # the SO-100/SO-101 family (Feetech)
        "old SO-100/SO-101 datasets (legacy degrees) → current DEGREES, LeRobot's documented transform: "
        "key = name.removeprefix('main_') + '.pos'; shoulder_lift_new = -(old - 90); "
        "elbow_flex_new = old - 90; other joints unchanged"
    ),
    "dynamixel": (  # Koch arms (Dynamixel)
        "old Koch datasets (legacy degrees): LeRobot documents no value transform for Koch arms (its "
        "documented one is for SO-100/SO-101 only); key = name.removeprefix('main_') + '.pos'; convert the "
        "values exactly with `robocal dataset recalibrate --old LEGACY.json --new CURRENT.json`"
    ),
}
"""What ``lerobot migrate`` says about the old datasets of each vendor's arms (LeRobot's documented transforms)."""


@app.command()
def migrate(
    legacy_file: Annotated[
        pathlib.Path, typer.Argument(help="Legacy LeRobot calibration JSON (parallel arrays).")
    ],
    vendor: str = typer.Option(..., "--vendor", help="feetech | dynamixel"),
    out: Annotated[
        pathlib.Path | None, typer.Option("--out", help="Current-format JSON to write (default: print).")
    ] = None,
    ids: str | None = typer.Option(None, "--ids", help="Motor ids in file order, e.g. 1,2,3 (default 1..n)."),
) -> None:
    """Convert a legacy calibration to LeRobot's current JSON and print the dataset degree transform."""
    from ..workflows.lerobot import calibration_json, migrate_file

    id_list = None
    if ids is not None:
        items = _common.parse_csv_list(ids, "--ids") or []
        try:
            id_list = [int(i) for i in items]
        except ValueError:
            raise UsageError(f"--ids {ids!r}: expected comma-separated integers") from None
    cals, warnings = migrate_file(legacy_file, vendor, id_list, out)
    if out is not None:
        _common.console.print(f"wrote {out}")
    else:
        _common.console.print(calibration_json(cals), markup=False)
    _common.console.print(_LEGACY_DATASET_NOTES.get(vendor, _LEGACY_DATASET_NOTE_OTHER), markup=False)
    raise typer.Exit(_common.print_warnings(warnings))


@app.command()
def show(
    robot: Robot,
    port: ArmPort,
    robot_id: LeRobotId = None,
    calibration_dir: LeRobotCalibrationDir = None,
    file: CalFile = None,
    samples: int = typer.Option(1, "--samples", min=1, max=100000, help="Readings to print."),
    compat: LeRobotCompat = "lerobot",
    use_degrees: LeRobotUseDegrees = None,
    modes_opt: LeRobotModes = None,
    physical: LeRobotPhysical = False,
) -> None:
    """Print live normalised positions (LeRobot's units) of every motor."""
    from ..core.lerobot import parse_compat
    from ..workflows.lerobot import open_arm, read_positions, require_motors, restore

    compat_mode = parse_compat(compat)
    spec, modes, cals = _scaled(robot, use_degrees, modes_opt, robot_id, calibration_dir, file)
    require_motors(spec, cals)
    print_range_warnings(spec, cals)
    with open_arm(spec, port) as (bus, arm):
        if arm is not None:  # the simulated arm starts uncalibrated: give it this calibration
            restore(bus, spec, cals)
        _common.console.print("reading  " + "  ".join(spec.motor_names))
        rows = read_positions(
            bus,
            spec,
            cals,
            modes,
            samples=samples,
            compat=compat_mode,
            convention="physical" if physical else "lerobot",
        )
        for k, values in enumerate(rows):
            _common.console.print(f"{k:>7}  " + "  ".join(f"{v:9.3f}" for v in values))


@app.command("export-urdf")
def export_urdf(
    out: Annotated[
        pathlib.Path, typer.Option("--out", help="Canonical joint map YAML (robocal format) to write.")
    ],
    robot: Robot,
    robot_id: LeRobotId = None,
    calibration_dir: LeRobotCalibrationDir = None,
    file: CalFile = None,
    sign: str | None = typer.Option(None, "--sign", help="URDF sign per joint: name=-1,..."),
    offset_deg: str | None = typer.Option(None, "--offset-deg", help="URDF offset per joint: name=90,..."),
    compat: LeRobotCompat = "lerobot",
    use_degrees: LeRobotUseDegrees = None,
    modes_opt: LeRobotModes = None,
    physical: LeRobotPhysical = False,
) -> None:
    """Write the exact per-joint q_urdf = sign·q + offset map of the DEGREES joints."""
    from ..core.lerobot import parse_compat
    from ..workflows.lerobot import check_joint_map_out, export_joint_map, write_joint_map

    compat_mode = parse_compat(compat)
    check_joint_map_out(out, file)
    signs = _common.parse_typed_assignments(sign, "--sign", int, "expected -1 or 1")
    offsets = _common.parse_typed_assignments(
        offset_deg, "--offset-deg", float, "expected a number of degrees"
    )
    spec, modes, cals = _scaled(robot, use_degrees, modes_opt, robot_id, calibration_dir, file)
    beyond = print_range_warnings(spec, cals)
    rc, skipped = export_joint_map(
        spec,
        cals,
        signs=signs,
        offsets_deg=offsets,
        compat=compat_mode,
        modes=modes,
        convention="physical" if physical else "lerobot",
    )
    ids = {n: cals[n].id for n in rc.joint_names}
    write_joint_map(out, rc, ids)
    _common.console.print(f"wrote {out} ({len(rc.joint_names)} joints)")
    if skipped:
        _common.print_warning(f"not exported (range modes, no angle): {', '.join(skipped)}")
    raise typer.Exit(_common.exit_code_for([*skipped, *beyond]))


@app.command("restore-previous")
def restore_previous(robot: Robot, port: ArmPort) -> None:
    """Write back the registers a run that did not finish left changed (kept in robocal's state folder)."""
    from ._left_changed import restore_previous as run

    run(robot, port)
