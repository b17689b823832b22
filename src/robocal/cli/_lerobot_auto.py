"""``robocal lerobot calibrate --auto``: the arm finds its own hard stops (CLI side).

Parses the options, asks the clear-workspace question (:func:`robocal.cli._autocal.make_confirm_start`), shows
the live view (:class:`robocal.cli._autocal.AutoLiveView`, the observer the Robstride ``sweep --auto`` uses) and
prints the per-joint table and the calibration; the job is :func:`robocal.workflows.lerobot.auto.auto_calibrate`
on :func:`robocal.workflows.lerobot.auto_sim.open_auto_arm` (a real port or ``sim``/``sim?...``).
"""

from __future__ import annotations

import pathlib
from dataclasses import replace
from typing import TYPE_CHECKING, Any

import typer

from ..core.lerobot import RobotSpec
from ..errors import UsageError
from . import _common
from ._autocal import (
    AutoLiveView,
    auto_table,
    auto_web_view,
    make_confirm_start,
    print_drifts,
    searched_footer,
)
from ._left_changed import offer_restore
from ._lerobot_render import print_calibration, status

if TYPE_CHECKING:
    from ..workflows.lerobot.auto import AutoCalibrationRequest

__all__ = ["auto_request", "calibrate_auto", "check_auto_options", "verify_auto"]


def check_auto_options(
    *,
    auto: bool,
    joints: str | None,
    partial: bool,
    yes: bool,
    use_file: bool,
    home_after_sweep: bool,
    web_view: bool,
    urdf: pathlib.Path | None = None,
    verify: bool = False,
) -> None:
    """Refuse option combinations that mean nothing (before any file or port is touched).

    Raises:
        UsageError: ``--joints``/``--partial``/``--yes``/``--urdf`` without ``--auto``; ``--auto`` with ``--use-file``,
            ``--home-after-sweep`` (the auto homing is always centred on the found stops) or ``--view``.
    """
    if not auto:
        given = [
            flag
            for flag, on in (
                ("--joints", joints is not None),
                ("--partial", partial),
                ("--yes", yes),
                ("--urdf", urdf is not None),
                ("--verify", verify),
            )
            if on
        ]
        if given:
            raise UsageError(f"{', '.join(given)} only apply with --auto")
        return
    clash = [
        flag
        for flag, on in (
            ("--use-file", use_file),
            ("--home-after-sweep", home_after_sweep),
        )
        if on
    ]
    if verify and (partial or web_view):
        both = ", ".join(f for f, on in (("--partial", partial), ("--view", web_view)) if on)
        raise UsageError(f"--verify writes nothing: {both} cannot be combined with it")
    if clash:
        why = {
            "--use-file": "--use-file writes an existing file, --auto finds the stops",
            "--home-after-sweep": "--auto always centres the homing on the stops it finds",
        }
        raise UsageError(
            f"--auto cannot be combined with {', '.join(clash)}: {'; '.join(why[c] for c in clash)}"
        )


def auto_request(
    robot: str,
    spec: RobotSpec,
    port: str,
    path: pathlib.Path,
    *,
    joints: str | None,
    partial: bool,
    sweep_full_turn: bool,
    urdf: pathlib.Path | None = None,
) -> AutoCalibrationRequest:
    """The ``--auto`` run's request from the command's options, checked before the port opens.

    Raises:
        UsageError: No ``auto_calibration`` section, an empty ``--joints``, bad ``sim?...`` options, a bad
            ``--urdf``.
    """
    from ..workflows.lerobot.auto import AutoCalibrationRequest, auto_section
    from ..workflows.lerobot.auto_sim import auto_gravity_model, parse_sim_port

    section = auto_section(robot)
    names = _common.parse_csv_list(joints, "--joints") if joints is not None else None
    if joints is not None and not names:
        raise UsageError("--joints: give at least one joint name")
    parse_sim_port(port, spec)  # bad sim options are refused before the port opens
    return AutoCalibrationRequest(
        spec,
        section,
        path=path,
        joints=names,
        partial=partial,
        sweep_full_turn=sweep_full_turn,
        gravity_model=auto_gravity_model(spec, port, section, urdf),  # a bad --urdf too
    )


def calibrate_auto(
    request: AutoCalibrationRequest, robot: str, port: str, *, yes: bool, view_port: int | None = None
) -> None:
    """Run the automatic calibration ``request`` (:func:`auto_request`) on ``port``, print the tables, exit 0 / 1.

    Exit 1: ``--partial`` with a failed joint. Ctrl-C: every motor limp, every register restored, no file (exit
    130); a fault or a failed joint: exit 3 with one ``error:`` line (the CLI's error handler).
    """
    from ..workflows.lerobot.auto import auto_calibrate
    from ..workflows.lerobot.auto_sim import open_auto_arm
    from ._lerobot_render import interrupted

    spec = request.spec
    confirm = make_confirm_start(yes, what=spec.name)

    def page(inner: Any, page_port: int) -> Any:  # --view: the stop search drawn on the arm in the browser
        from ..viewer.lerobot_sweep_page import open_lerobot_auto_page

        return open_lerobot_auto_page(robot, spec.motor_names, inner=inner, port=page_port)

    with (
        auto_web_view(view_port, None, AutoLiveView(), "", page=page) as live,
        open_auto_arm(spec, port, request.section) as arm,
    ):
        offer_restore(arm.bus, spec, port, arm.sim)
        try:
            result = auto_calibrate(
                arm.bus,
                replace(request, snapshot_port=port if arm.sim is None else None),
                clock=arm.clock,
                confirm_start=confirm,
                view=live,
                on_status=status,
            )
        except KeyboardInterrupt as exc:
            raise interrupted(
                exc,
                "every motor is limp, every register the search changed was written back; no file was written",
                "; no file was written",
            ) from None
        if view_port is not None:
            live.finish(result.auto)
    _common.console.print(auto_table(result.auto, title=f"{spec.name}: automatic hard-stop calibration"))
    print_calibration(result.calibration)
    if result.kept:
        _common.console.print(
            f"kept the calibration their EEPROM holds: {', '.join(result.kept)}", markup=False
        )
    if result.auto.failed:
        _common.print_warning(f"written with --partial although {result.auto.failure_summary()}")
    _common.console.print(f"calibration saved to {result.path} and written to the motors", markup=False)
    raise typer.Exit(result.exit_code)


def verify_auto(
    robot: str,
    spec: RobotSpec,
    port: str,
    path: pathlib.Path,
    *,
    joints: str | None,
    yes: bool,
    tolerance_deg: float,
    urdf: pathlib.Path | None = None,
) -> None:
    """``--auto --verify``: search the stops again, print each joint's drift, exit 0 / 1 (past the tolerance).

    Nothing is written: every register the search changes is written back, no file. Ctrl-C: every motor limp,
    every register restored (exit 130); a failed search or a fault: exit 3.
    """
    from ..workflows.lerobot.auto import auto_section
    from ..workflows.lerobot.auto_sim import auto_gravity_model, open_auto_arm, parse_sim_port
    from ..workflows.lerobot.verify import VerifyRequest, check_stored, verify_calibration
    from ._lerobot_render import interrupted

    try:
        section = auto_section(robot)
    except UsageError:  # no auto_calibration section: an arm that cannot drive itself (a leader): by hand
        if joints is not None:
            raise UsageError(
                "--joints: a by-hand --verify (an arm without auto_calibration) checks every joint"
            ) from None
        _verify_by_hand(spec, port, path, tolerance_deg)
        return
    names = _common.parse_csv_list(joints, "--joints") if joints is not None else None
    if joints is not None and not names:
        raise UsageError("--joints: give at least one joint name")
    request = VerifyRequest(spec, section, path, joints=names, tolerance_deg=tolerance_deg)  # the tolerance
    check_stored(request)  # the file, before the port opens
    parse_sim_port(port, spec)
    gravity_model = auto_gravity_model(spec, port, section, urdf)
    confirm = make_confirm_start(yes, what=spec.name)
    with open_auto_arm(spec, port, section) as arm:
        offer_restore(arm.bus, spec, port, arm.sim)
        try:
            result = verify_calibration(
                arm.bus,
                replace(
                    request, gravity_model=gravity_model, snapshot_port=port if arm.sim is None else None
                ),
                clock=arm.clock,
                confirm_start=confirm,
                view=AutoLiveView(),
                on_status=status,
            )
        except KeyboardInterrupt as exc:
            raise interrupted(
                exc,
                "every motor is limp, every register the search changed was written back; nothing was written",
            ) from None
    title = f"{spec.name}: drift of {path} (tolerance {tolerance_deg:g}°)"
    print_drifts(result.joints, title, path, tolerance_deg, searched_footer(result.search_s))
    raise typer.Exit(result.exit_code)


def _verify_by_hand(spec: RobotSpec, port: str, path: pathlib.Path, tolerance_deg: float) -> None:
    """``--auto --verify`` on an arm that cannot drive itself: the operator pushes the joints into their stops."""
    from ..workflows.lerobot import open_arm, sim_operator
    from ..workflows.lerobot.verify import check_hand, verify_by_hand
    from ._lerobot_render import ConsoleOperator, interrupted, sweep_renderer

    check_hand(spec, path, tolerance_deg)  # before the port opens
    update, close = sweep_renderer()
    with open_arm(spec, port) as (bus, arm):
        operator: Any = sim_operator(arm) if arm is not None else ConsoleOperator()
        try:
            result = verify_by_hand(bus, spec, path, operator, tolerance_deg=tolerance_deg, on_sweep=update)
        except KeyboardInterrupt as exc:
            close()
            raise interrupted(exc, "nothing was written (the arm was only read)") from None
        finally:
            close()
    title = f"{spec.name}: drift of {path} by hand (tolerance {tolerance_deg:g}°)"
    footer = f"{result.readings} readings; nothing was written (the arm was only read)"
    print_drifts(result.joints, title, path, tolerance_deg, footer)
    raise typer.Exit(result.exit_code)
