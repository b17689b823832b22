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

import typer

from ..errors import UsageError
from ..workflows.sim.job import (
    ARM_ROBOTS,
    UR_STANDARD_BASE_PORT,
    ServedDevice,
    serve_arm,
    serve_lite,
    serve_openarm,
    serve_ur,
)
from . import _common

app = typer.Typer(
    help="Simulated robots as standalone devices: LeRobot arms (pty), the Lite and the OpenArm (CAN), a UR "
    "controller (TCP).",
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


def _serve(device: ServedDevice, view: bool | None) -> None:
    """Print the device's lines (or show them in the live view) and wait for Ctrl-C / SIGTERM."""
    for w in device.warnings:
        _common.print_warning(w)
    use_view = device.operator is not None and (
        view if view is not None else (sys.stdin.isatty() and sys.stdout.isatty())
    )
    if use_view and not sys.stdin.isatty():
        raise UsageError("--view needs a terminal on standard input (use --no-view in scripts)")
    if not use_view:  # the live view shows these lines itself
        for line in device.lines:
            _common.console.print(line, markup=False)
        sys.stdout.flush()
    with _until_signal() as stop:
        if use_view:
            from ._sim_view import run_view

            run_view(device.operator, device.title, "\n".join(device.lines), stop, device.attach, device.usb)
        else:
            while not stop.wait(0.2):
                pass
    _common.err_console.print("simulator stopped")


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
        with serve_arm(
            robot, link=link, seed=seed, control=control, noise_ticks=noise, factory=factory
        ) as device:
            _serve(device, view)

    command.__doc__ = (
        f"Serve a simulated {robot} on a pseudo-terminal until Ctrl-C; prints its port and control socket."
    )
    return command


for _robot in ARM_ROBOTS:
    app.command(_robot)(_arm_command(_robot))


@app.command("lite")
def lite(
    interface: str | None = typer.Option(
        None,
        "--interface",
        help="socketcand (a socketcand server on 127.0.0.1, python-can's socketcand interface), socketcan (a vcan "
        "pair) or udp_multicast; default socketcan when vcan0 exists, else socketcand.",
    ),
    channel: str | None = typer.Option(
        None,
        "--channel",
        help="The two channels for can0,can1 (default can0,can1 for socketcand, vcan0,vcan1, or "
        "239.74.163.2,239.74.163.3).",
    ),
    port: int | None = typer.Option(
        None, "--port", help="socketcand's TCP port on 127.0.0.1 (default 29536, the daemon's; 0: any free port)."
    ),
    seed: int = typer.Option(
        0, "--seed", help="Seed of the factory zeros, power-on pose and noise (as sim:lite)."
    ),
    noise: float = typer.Option(
        3e-4, "--noise", help="Encoder noise (standard deviation), rad (as sim:lite)."
    ),
    physics: bool = typer.Option(
        True,
        "--physics/--no-physics",
        help="Joint physics in real time (MIT commands move the joints into their hard stops: sweep --auto finds "
        "them), as sim:lite's; --no-physics: the joints move only by hand (control socket).",
    ),
    control: str | None = ControlOpt,
    view: bool | None = ViewOpt,
) -> None:
    """Serve the simulated Lite's 14 Robstride motors on a CAN interface other processes share, until Ctrl-C."""
    chans = _common.parse_csv_list(channel or None, "--channel")
    with serve_lite(
        interface=interface, channels=chans, seed=seed, noise_rad=noise, control=control, port=port,
        physics=physics,
    ) as device:  # fmt: skip
        _serve(device, view)


@app.command("openarm")
def openarm(
    side: str = typer.Option("both", "--side", help="both, right or left (right arm: bus can0, left: can1)."),
    seed: int = typer.Option(0, "--seed", help="Seed of the hidden motor mounts and factory zeros."),
    zeroed: bool = typer.Option(
        False, "--zeroed", help="Motors hold the zero a perfect calibration writes (default: factory zeros)."
    ),
    port: int | None = typer.Option(
        None, "--port", min=0, max=65535, help="socketcand TCP port (default 29536; 0: any free port)."
    ),
    host: str = typer.Option("127.0.0.1", "--host", help="Address to listen on (loopback by default)."),
    control: str | None = ControlOpt,
    view: bool | None = ViewOpt,
) -> None:
    """Serve simulated OpenArm v10 arms (8 Damiao motors each, real time) on a loopback socketcand server, until Ctrl-C."""
    with serve_openarm(side=side, seed=seed, zeroed=zeroed, host=host, port=port, control=control) as device:
        _serve(device, view)


@app.command("ur")
def ur(
    port: int | None = typer.Option(
        None, "--port", min=0, max=65535, help="Primary interface port alone (0: any free port; default 30001)."
    ),
    host: str = typer.Option("127.0.0.1", "--host", help="Address to listen on (loopback by default)."),
    dh: str | None = typer.Option(None, "--dh", help="DH YAML the controller reports."),
    model: str | None = typer.Option(None, "--model", help="UR model: its nominal DH (+ --deltas)."),
    deltas: str | None = typer.Option(None, "--deltas", help="Calibration deltas added to --model's DH."),
    standard_ports: bool = typer.Option(
        False,
        "--standard-ports",
        help="Serve all ports as a controller does: dashboard 29999, primary 30001, secondary 30002, real-time 30003, RTDE 30004.",
    ),
    base_port: int | None = typer.Option(
        None,
        "--base-port",
        help="Serve all ports at these offsets from N: dashboard N, primary N+2, secondary N+3, real-time N+4, RTDE N+5 "
        "(0: each on any free port).",
    ),
) -> None:
    """Serve a simulated UR controller on TCP until Ctrl-C: its primary interface, or with --standard-ports / --base-port all its ports (default: a calibrated UR10e, as the UR demo)."""
    chosen = [o for o, given in (("--port", port is not None), ("--standard-ports", standard_ports),
                                 ("--base-port", base_port is not None)) if given]  # fmt: skip
    if len(chosen) > 1:
        raise UsageError(f"give one of --port, --standard-ports and --base-port, not {' and '.join(chosen)}")
    base = UR_STANDARD_BASE_PORT if standard_ports else base_port
    with serve_ur(
        port=30001 if port is None else port, host=host, dh=dh, model=model, deltas=deltas, base_port=base
    ) as device:
        _serve(device, view=False)
