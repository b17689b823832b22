"""``robocal view``: the URDF robot in the browser, posed by live or recorded joints through a calibration."""

from __future__ import annotations

import time
from pathlib import Path

import typer

from . import _common
from ._options import DEFAULT_TOPIC, LeRobotCalibrationDir, LeRobotId, ReplayTopic

HELP_SOURCE = "sim:lite[?options] | can:<interface>:<channel>[,…] | replay:<file.csv|rosbag2>"


def view(
    urdf: Path = typer.Option(..., "--urdf", help="The robot description (URDF)."),
    source: str | None = typer.Option(None, "--source", help=HELP_SOURCE),
    lerobot_port: str | None = typer.Option(
        None, "--lerobot-port", help="Serial port of a LeRobot arm (or 'sim'), instead of --source."
    ),
    robot: str | None = typer.Option(
        None,
        "--robot",
        help="With --lerobot-port: so101_follower | so101_leader | koch_follower | koch_leader.",
    ),
    robot_id: LeRobotId = None,
    calibration_dir: LeRobotCalibrationDir = None,
    ur_host: str | None = typer.Option(
        None, "--ur-host", help="UR controller HOST[:PORT], instead of --source."
    ),
    calibration: Path | None = typer.Option(
        None,
        "--calibration",
        help="Calibration file the robot is posed through (default: none, direction·raw).",
    ),
    compare: str | None = typer.Option(
        None, "--compare", help="Second calibration file drawn as a ghost, or 'none' for no calibration."
    ),
    package_path: list[str] = typer.Option(
        [],
        "--package-path",
        metavar="NAME=DIR",
        help="Where package://NAME/ meshes are (repeatable).",
    ),
    frame: str | None = typer.Option(
        None, "--frame", help="Replay positions are identity (direction·raw, default) or motor (raw)."
    ),
    topic: ReplayTopic = DEFAULT_TOPIC,
    host: str = typer.Option(
        "127.0.0.1", "--host", help="Interface to serve on (0.0.0.0: every one; warns that the page is exposed)."
    ),
    allow_origin: list[str] = typer.Option(
        [],
        "--allow-origin",
        metavar="ORIGIN",
        help="Also accept the page from this origin, e.g. http://proxy:8080 (repeatable; * for any).",
    ),
    port: int = typer.Option(8080, "--port", help="TCP port of the page (0: any free port)."),
    rate: float = typer.Option(30.0, "--rate", help="Page updates per second."),
    speed: float = typer.Option(1.0, "--speed", help="Replay speed (recording seconds per second)."),
    open_browser: bool = typer.Option(False, "--open", help="Open the page in the default browser."),
    duration: float | None = typer.Option(
        None, "--duration", help="Stop after this many seconds (default: until Ctrl-C)."
    ),
) -> None:
    """Serve a web page showing the robot posed by live joint positions through a calibration.

    The page shows each joint's raw and calibrated value against its URDF limits (red outside them); with
    --compare a translucent ghost shows the same readings through a second calibration; with
    --source replay:FILE a time slider plays the recording. Nothing is written.
    """
    from ..viewer.session import ViewOptions

    opts = ViewOptions(
        urdf=urdf,
        source=source,
        lerobot_port=lerobot_port,
        robot=robot,
        robot_id=robot_id,
        calibration_dir=calibration_dir,
        ur_host=ur_host,
        calibration=calibration,
        compare=compare,
        package_paths=tuple(package_path),
        frame=frame,
        topic=topic,
        host=host,
        port=port,
        rate_hz=rate,
        speed=speed,
        keep_moving=True,
        allowed_origins=tuple(allow_origin),
    )
    raise typer.Exit(serve(opts, open_browser=open_browser, duration_s=duration))


def serve(opts: object, *, open_browser: bool = False, duration_s: float | None = None) -> int:
    """Open the view, print its URL, serve until Ctrl-C (or ``duration_s``); return the exit code.

    A source that fails while serving is reported once as an ``error:`` line; the page keeps the last pose and
    shows the message; the exit code is then the error's (3 for a device).
    """
    from ..errors import UsageError
    from ..viewer.session import ViewOptions, open_view

    if not isinstance(opts, ViewOptions):
        raise TypeError("serve needs ViewOptions")
    if duration_s is not None and not duration_s > 0:
        raise UsageError(f"--duration {duration_s}: expected a positive number of seconds")
    session = open_view(opts)
    reported = False
    try:
        try:  # Ctrl-C anywhere from here on is the normal way to stop: close cleanly, exit 0
            for w in session.warnings:
                _common.print_warning(w)
            _common.console.print(f"robocal view: serving {session.app.url}  (Ctrl-C to stop)", markup=False)
            if open_browser:
                import webbrowser

                webbrowser.open(session.app.url)
            end = None if duration_s is None else time.monotonic() + duration_s
            while end is None or time.monotonic() < end:
                session.app.wait(0.2 if end is None else max(0.0, min(0.2, end - time.monotonic())))
                err = session.feed.error
                if err is not None and not reported:
                    reported = True
                    _common.print_error(f"{err} (the page keeps the last pose; Ctrl-C to stop)")
        except KeyboardInterrupt:
            pass
    finally:
        session.close()
    err = session.feed.error
    return err.exit_code if err is not None else 0


def register(app: typer.Typer) -> None:
    """Add ``view`` to the root app."""
    app.command("view")(view)
