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
    help="Simulated robots as standalone devices: LeRobot arms (pty), the Lite (CAN), a UR controller (TCP).",
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
    from ..workflows.lerobot import robot_spec

    if noise < 0:
        raise UsageError(f"--noise {noise}: must be ≥ 0 ticks")
    arm = SimArm(
        robot_spec(robot), truth=seeded_truth(robot, seed), noise_ticks=noise, seed=seed or 0, factory=factory
    )
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


LITE_CHANNELS = {"socketcan": "vcan0,vcan1", "udp_multicast": "239.74.163.2,239.74.163.3"}
"""Default channels (can0, can1) per interface."""


@app.command("lite")
def lite(
    interface: str | None = typer.Option(
        None,
        "--interface",
        help="socketcan (a vcan pair) or udp_multicast; default socketcan when vcan0 exists, else udp_multicast.",
    ),
    channel: str | None = typer.Option(
        None,
        "--channel",
        help="The two channels for can0,can1 (default vcan0,vcan1 or 239.74.163.2,239.74.163.3).",
    ),
    seed: int = typer.Option(
        0, "--seed", help="Seed of the factory zeros, power-on pose and noise (as sim:lite)."
    ),
    noise: float = typer.Option(
        3e-4, "--noise", help="Encoder noise (standard deviation), rad (as sim:lite)."
    ),
    control: str | None = ControlOpt,
    view: bool | None = ViewOpt,
) -> None:
    """Serve the simulated Lite's 14 Robstride motors on a CAN interface other processes share, until Ctrl-C."""
    import os
    import pathlib

    from ..backends.sim.lite import LiteHands, SimLite
    from ..backends.sim.serve import Session

    if interface is None:
        interface = "socketcan" if pathlib.Path("/sys/class/net/vcan0").exists() else "udp_multicast"
    if interface not in LITE_CHANNELS:
        raise UsageError(f"--interface {interface!r}: expected socketcan or udp_multicast")
    chans = _common.parse_csv_list(channel or LITE_CHANNELS[interface], "--channel") or []
    if len(chans) != 2 or chans[0] == chans[1]:
        raise UsageError(f"--channel {channel!r}: expected two different channels, for can0 and can1")
    if interface == "socketcan":
        missing = [c for c in chans if not os.path.exists(f"/sys/class/net/{c}")]
        if missing:
            raise UsageError(
                f"no CAN interface {', '.join(missing)}: create it (ip link add {missing[0]} type vcan && "
                f"ip link set {missing[0]} up) or use --interface udp_multicast"
            )
    if not (noise >= 0 and noise < 1):
        raise UsageError(f"--noise {noise}: expected 0 ≤ noise < 1 rad")
    robot = SimLite(seed, noise_rad=noise, interface=interface, channels={"can0": chans[0], "can1": chans[1]})
    source = f"can:{interface}:{chans[0]},{chans[1]}"
    with robot, Session(LiteHands(robot), "lite", source, control=control) as session:
        lines = [
            f"source: {source}",
            f"channels: can0={chans[0]} (ids 11-17), can1={chans[1]} (ids 21-27) on {interface}",
            f"control: {session.control_path}",
            "simulated Lite (14 Robstride motors); Ctrl-C stops it",
        ]
        _serve(f"Lite on {interface}", lines, session, view, None)


@app.command("ur")
def ur(
    port: int = typer.Option(30001, "--port", min=0, max=65535, help="TCP port (0: any free port)."),
    host: str = typer.Option("127.0.0.1", "--host", help="Address to listen on (loopback by default)."),
    dh: str | None = typer.Option(None, "--dh", help="DH YAML the controller reports."),
    model: str | None = typer.Option(None, "--model", help="UR model: its nominal DH (+ --deltas)."),
    deltas: str | None = typer.Option(None, "--deltas", help="Calibration deltas added to --model's DH."),
) -> None:
    """Serve a simulated UR controller's primary interface on TCP until Ctrl-C (default: a calibrated UR10e, as the UR demo)."""
    from ..backends.sim.ur_controller import SimUrController
    from ..core.ur import TEST_SET_3_DELTAS, nominal_dh
    from ..errors import DeviceError
    from ..workflows.ur import load_dh_input

    warnings: list[str] = []
    if dh is None and model is None and deltas is None:
        params = nominal_dh("ur10e") + TEST_SET_3_DELTAS
        what = "UR10e with a factory calibration (the deltas of robocal's UR demo)"
    else:
        params = load_dh_input(dh, model, deltas, warnings=warnings)
        what = (
            f"DH from {dh}" if dh is not None else f"{model} nominal DH" + (f" + {deltas}" if deltas else "")
        )
    for w in warnings:
        _common.print_warning(w)
    try:
        controller = SimUrController(params, host=host, port=port)
    except OSError as exc:
        raise DeviceError(f"cannot listen on {host}:{port} ({exc.strerror or exc})") from None
    with controller:
        bound_host, bound_port = controller.address
        for line in (
            f"address: {bound_host}:{bound_port}",
            f"simulated UR controller, primary interface ({what}); Ctrl-C stops it",
            f"try: robocal ur extract --host {bound_host} --port {bound_port} --out kinematics.yaml",
        ):
            _common.console.print(line, markup=False)
        sys.stdout.flush()
        with _until_signal() as stop:
            while not stop.wait(0.2):
                pass
    _common.err_console.print("simulator stopped")
