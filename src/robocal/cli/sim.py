"""``robocal sim``: the simulated robots as standalone devices any program can drive.

``robocal sim so101_follower|so101_leader|koch_follower|koch_leader`` serves a simulated LeRobot arm on a
pseudo-terminal until Ctrl-C. The operator moves its joints from the live view (keys) or through the control
socket (line-delimited JSON, see :mod:`robocal.backends.sim.control`).
"""

from __future__ import annotations

import contextlib
import signal
import sys
import threading
from collections.abc import Callable, Iterator
from types import FrameType
from typing import Any

import typer

from ..errors import UsageError
from . import _common

app = typer.Typer(
    help="Simulated robots as standalone devices: LeRobot arms on a pseudo-terminal (more to come).",
    no_args_is_help=True,
)

LinkOpt = typer.Option(None, "--link", help="Also make this symlink to the port (removed on exit).")
SeedOpt = typer.Option(
    None, "--seed", help="Vary the arm's joint ranges reproducibly (default: the stock arm)."
)
ControlOpt = typer.Option(
    None, "--control", help="Control socket path (default: <link>.control, or a temporary folder)."
)
ViewOpt = typer.Option(
    None, "--view/--no-view", help="Live view with keys (default: when stdin and stdout are a terminal)."
)


@contextlib.contextmanager
def _until_signal() -> Iterator[threading.Event]:
    """An event set by SIGINT or SIGTERM (both end the simulator cleanly)."""
    stop = threading.Event()

    def handler(signum: int, frame: FrameType | None) -> None:
        stop.set()

    old = {s: signal.signal(s, handler) for s in (signal.SIGINT, signal.SIGTERM)}
    try:
        yield stop
    finally:
        for s, h in old.items():
            signal.signal(s, h)


def _serve(
    title: str,
    lines: list[str],
    session: Any,
    view: bool | None,
    attach: Callable[[list[str] | None], object] | None,
) -> None:
    use_view = view if view is not None else (sys.stdin.isatty() and sys.stdout.isatty())
    if use_view and not sys.stdin.isatty():
        raise UsageError("--view needs a terminal on standard input (use --no-view in scripts)")
    if not use_view:  # the live view shows these lines itself
        for line in lines:
            _common.console.print(line, markup=False)
        sys.stdout.flush()
    with _until_signal() as stop:
        if use_view:
            from ._sim_view import run_view

            run_view(session.operator, title, "\n".join(lines), stop, attach)
        else:
            while not stop.wait(0.2):
                pass
    _common.err_console.print("simulator stopped")


def _arm(
    robot: str,
    link: str | None,
    seed: int | None,
    control: str | None,
    view: bool | None,
    noise: int,
    factory: bool,
) -> None:
    from ..backends.sim.lerobot_arms import ArmHands, SimArm, seeded_truth
    from ..backends.sim.serve import Session

    if noise < 0:
        raise UsageError(f"--noise {noise}: must be ≥ 0 ticks")
    arm = SimArm(robot, truth=seeded_truth(robot, seed), noise_ticks=noise, seed=seed or 0, factory=factory)
    if factory:
        arm.bus.attach(())
    names = list(arm.spec.motor_names)

    def attach(joints: list[str] | None) -> list[str]:
        arm.bus.attach(None if joints is None else [arm.servo(j).motor_id for j in joints])
        return [n for n in names if arm.servo(n).attached]

    def attach_cmd(req: dict[str, Any]) -> dict[str, Any]:
        joints = req.get("joints", req.get("joint", "all"))
        if isinstance(joints, str):
            joints = None if joints == "all" else [joints]
        if not isinstance(joints, list | type(None)) or any(j not in names for j in joints or []):
            raise UsageError(f"attach: joints must be 'all' or names among {', '.join(names)}")
        return {"attached": attach(joints)}

    with (
        arm,
        Session(
            ArmHands(arm), robot, arm.port, link=link, control=control, extra={"attach": attach_cmd}
        ) as session,
    ):
        lines = [f"port: {arm.port}"]
        if session.link is not None:
            lines.append(f"link: {session.link} -> {arm.port}")
        lines.append(f"control: {session.control_path}")
        lines.append(
            f"simulated {robot} ({arm.spec.vendor}, {len(names)} servos"
            + (", factory state: nothing plugged in" if factory else "")
            + "); Ctrl-C stops it"
        )
        _serve(f"{robot} on {arm.port}", lines, session, view, attach)


def _arm_command(robot: str) -> Callable[..., None]:
    def command(
        link: str | None = LinkOpt,
        seed: int | None = SeedOpt,
        control: str | None = ControlOpt,
        view: bool | None = ViewOpt,
        noise: int = typer.Option(0, "--noise", help="Read noise on Present_Position, ± ticks."),
        factory: bool = typer.Option(
            False,
            "--factory",
            help="Servos as shipped (all id 1, vendor baud, no calibration), none plugged in.",
        ),
    ) -> None:
        _arm(robot, link, seed, control, view, noise, factory)

    command.__doc__ = (
        f"Serve a simulated {robot} on a pseudo-terminal until Ctrl-C; prints its port and control socket."
    )
    return command


for _robot in ("so101_follower", "so101_leader", "koch_follower", "koch_leader"):
    app.command(_robot)(_arm_command(_robot))
