"""The simulated robots as standalone devices (``robocal sim``): open one, say how to reach it, close it.

Each ``serve_*`` context manager starts a simulator from :mod:`robocal.backends.sim` on its real transport (a
pseudo-terminal, CAN interfaces other processes share, a TCP port) and yields a :class:`ServedDevice`: the lines
that tell a person or a script where it is, and what the CLI's live view needs. Leaving the context stops it.
"""

from __future__ import annotations

import contextlib
import os
import pathlib
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass, field
from typing import Any

from ...errors import DeviceError, UsageError

__all__ = [
    "ARM_ROBOTS",
    "LITE_CHANNELS",
    "OPENARM_BUSES",
    "SOCKETCAND_PORT",
    "UR_PORT_OFFSETS",
    "UR_STANDARD_BASE_PORT",
    "ServedDevice",
    "serve_arm",
    "serve_lite",
    "serve_openarm",
    "serve_ur",
]

ARM_ROBOTS: tuple[str, ...] = ("so101_follower", "so101_leader", "koch_follower", "koch_leader")
"""LeRobot arms ``robocal sim`` serves on a pseudo-terminal."""

LITE_CHANNELS = {
    "socketcand": "can0,can1",
    "socketcan": "vcan0,vcan1",
    "udp_multicast": "239.74.163.2,239.74.163.3",
}
"""Default channels (can0, can1) per interface (socketcand: the bus names its clients open)."""

SOCKETCAND_PORT = 29536
"""The socketcand daemon's default TCP port, where ``robocal sim lite --interface socketcand`` listens."""


@dataclass(frozen=True)
class ServedDevice:
    """A simulated robot being served.

    Attributes:
        title: Title of the live view.
        lines: Where the device is and how to stop it, one line each (printed, or shown by the live view).
        operator: The hands the live view moves the joints with (None: no live view, e.g. the UR controller).
        attach: Plugs servos in / out (``attach(None)``: all; a list of joint names: those), returning the
            attached joints; None when the device has no such thing.
        warnings: Warnings about the inputs (e.g. a DH file's).
    """

    title: str
    lines: tuple[str, ...]
    operator: Any = None
    attach: Callable[[list[str] | None], object] | None = None
    warnings: tuple[str, ...] = field(default_factory=tuple)
    usb: Callable[[], bool] | None = None
    """Unplugs / plugs back the simulated USB cable (the ``--link`` vanishes and returns); returns whether it is
    plugged in now. None without a link."""


@contextlib.contextmanager
def serve_arm(
    robot: str,
    *,
    link: str | None = None,
    seed: int | None = None,
    control: str | None = None,
    noise_ticks: int = 0,
    factory: bool = False,
) -> Iterator[ServedDevice]:
    """Serve a simulated LeRobot arm on a pseudo-terminal, with its control socket.

    Args:
        robot: One of :data:`ARM_ROBOTS`.
        link: Also make this symlink to the port (removed on exit).
        seed: Vary the arm's joint ranges reproducibly (None: the stock arm).
        control: Control socket path (default: ``<link>.control`` or a temporary folder).
        noise_ticks: Read noise on ``Present_Position``, ± ticks.
        factory: Servos as shipped (all id 1, vendor baud, no calibration), none plugged in.

    Raises:
        UsageError: Negative noise or an unknown robot.
    """
    from ...backends.sim.lerobot_arms import ArmHands, SimArm, seeded_truth
    from ...backends.sim.serve import Session
    from ..lerobot import robot_spec

    if noise_ticks < 0:
        raise UsageError(f"--noise {noise_ticks}: must be ≥ 0 ticks")
    arm = SimArm(
        robot_spec(robot),
        truth=seeded_truth(robot, seed),
        noise_ticks=noise_ticks,
        seed=seed or 0,
        factory=factory,
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

    before_unplug: list[int] = []

    def usb(plugged: bool) -> None:
        """The USB cable: out, no servo answers; back in, the servos plugged in before answer again."""
        if not plugged:
            before_unplug[:] = [arm.servo(n).motor_id for n in names if arm.servo(n).attached]
            arm.bus.attach(())
        else:
            arm.bus.attach(list(before_unplug))

    with (
        arm,
        Session(
            ArmHands(arm),
            robot,
            arm.port,
            link=link,
            control=control,
            extra={"attach": attach_cmd},
            on_usb=usb,
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

        def toggle_usb() -> bool:
            session.set_plugged(not session.plugged)
            return session.plugged

        yield ServedDevice(
            f"{robot} on {arm.port}",
            tuple(lines),
            session.operator,
            attach,
            usb=toggle_usb if session.link is not None else None,
        )


def lite_search_caps_nm() -> dict[str, float]:
    """Joint → the search torque of the shipped ``bhl_arms`` profile (the standalone Lite's friction scale)."""
    from ...formats.profiles import load_profile

    auto = load_profile("bhl_arms").auto
    if auto is None:  # pragma: no cover - the shipped profile has its auto section
        return {}
    return {j.name: j.torque_cap_nm for j in auto.joints}


@contextlib.contextmanager
def serve_lite(
    *,
    interface: str | None = None,
    channels: Sequence[str] | None = None,
    seed: int = 0,
    noise_rad: float = 3e-4,
    control: str | None = None,
    port: int | None = None,
    physics: bool = True,
) -> Iterator[ServedDevice]:
    """Serve the simulated Lite's 14 Robstride motors on CAN interfaces other processes share.

    With ``physics`` (the default) every joint has the plant of ``sim:lite``'s ``--auto``, in real time: MIT
    commands move it into its hard stops, so ``robocal sweep --auto`` against it finds them; the friction is scaled
    to the shipped ``bhl_arms`` profile's search torques. Without, the joints move only by hand (control socket).

    Args:
        interface: ``socketcand`` (a socketcand server on loopback TCP: needs nothing from the kernel),
            ``socketcan`` (a vcan pair) or ``udp_multicast``; default socketcan when ``vcan0`` exists, else
            socketcand.
        channels: The two channels for can0 and can1 (default: :data:`LITE_CHANNELS`; socketcand: the bus names
            clients open).
        seed: Seed of the factory zeros, power-on pose and noise (as ``sim:lite``).
        noise_rad: Encoder noise (standard deviation), rad.
        control: Control socket path.
        port: socketcand's TCP port on 127.0.0.1 (default :data:`SOCKETCAND_PORT`; 0: any free port).
        physics: Joint physics in real time (see above).

    Raises:
        UsageError: Unknown interface, not two different channels, a missing vcan interface, bad noise, a port
            without socketcand.
        DeviceError: The socketcand port cannot be listened on (e.g. busy).
    """
    from ...backends.sim.lite import LiteHands, SimLite
    from ...backends.sim.serve import Session

    if interface is None:
        interface = "socketcan" if pathlib.Path("/sys/class/net/vcan0").exists() else "socketcand"
    if interface not in LITE_CHANNELS:
        raise UsageError(f"--interface {interface!r}: expected socketcand, socketcan or udp_multicast")
    if port is not None and interface != "socketcand":
        raise UsageError(f"--port applies to --interface socketcand, not {interface}")
    if port is not None and not 0 <= port <= 65535:
        raise UsageError(f"--port {port}: expected 0 (any free port) or 1..65535")
    chans = list(channels) if channels is not None else LITE_CHANNELS[interface].split(",")
    if len(chans) != 2 or chans[0] == chans[1]:
        raise UsageError(f"--channel {','.join(chans)!r}: expected two different channels, for can0 and can1")
    if interface == "socketcan":
        missing = [c for c in chans if not os.path.exists(f"/sys/class/net/{c}")]
        if missing:
            raise UsageError(
                f"no CAN interface {', '.join(missing)}: create it (ip link add {missing[0]} type vcan && "
                f"ip link set {missing[0]} up) or use --interface socketcand"
            )
    if not (noise_rad >= 0 and noise_rad < 1):
        raise UsageError(f"--noise {noise_rad}: expected 0 ≤ noise < 1 rad")
    extra: tuple[str, ...] = ()
    caps = lite_search_caps_nm() if physics else None
    with contextlib.ExitStack() as stack:
        if interface == "socketcand":
            from ...backends.sim.socketcand import SocketcandServer

            robot = SimLite(seed, noise_rad=noise_rad, physics_cap_nm=caps)  # in-process channels, bridged over TCP
            server = SocketcandServer(
                {chans[0]: robot.channels["can0"], chans[1]: robot.channels["can1"]},
                port=SOCKETCAND_PORT if port is None else port,
            )
            stack.callback(server.stop)  # also when the robot fails to start
            where = f"{server.host}:{server.port}"
            source = f"can:socketcand:{chans[0]},{chans[1]}?port={server.port}"
            extra = (
                f"python-can: can.Bus(interface='socketcand', channel='{chans[0]}', host='{server.host}', "
                f"port={server.port})",
            )
        else:
            robot = SimLite(
                seed, noise_rad=noise_rad, interface=interface, channels={"can0": chans[0], "can1": chans[1]},
                physics_cap_nm=caps,
            )  # fmt: skip
            where, source = "", f"can:{interface}:{chans[0]},{chans[1]}"
        stack.enter_context(robot)
        if interface == "socketcand":
            server.start()
        session = stack.enter_context(Session(LiteHands(robot), "lite", source, control=control))
        lines = (
            f"source: {source}",
            f"channels: can0={chans[0]} (ids 11-17), can1={chans[1]} (ids 21-27) on {interface} {where}".rstrip(),
            *extra,
            f"control: {session.control_path}",
            "simulated Lite (14 Robstride motors"
            + ("; joint physics in real time: sweep --auto finds its stops" if physics else "; joints move by hand")
            + "); Ctrl-C stops it",
        )
        yield ServedDevice(f"Lite on {interface}", lines, session.operator)


OPENARM_BUSES = {"right": "can0", "left": "can1"}
"""The socketcand bus name of each simulated OpenArm arm (openarm_can's defaults: can0 right, can1 left)."""


@contextlib.contextmanager
def serve_openarm(
    *,
    side: str = "both",
    seed: int = 0,
    zeroed: bool = False,
    host: str = "127.0.0.1",
    port: int | None = None,
    control: str | None = None,
) -> Iterator[ServedDevice]:
    """Serve simulated OpenArm v10 arms (8 Damiao motors each, in real time) behind a loopback socketcand server.

    Args:
        side: ``"both"``, ``"right"`` or ``"left"``; the right arm is bus ``can0``, the left ``can1``.
        seed: Seed of the hidden motor mounts and factory zeros (the left arm uses ``seed + 1``).
        zeroed: The motors hold the zero a perfect calibration writes (default: factory zeros).
        host: Address to listen on.
        port: TCP port (None: :data:`SOCKETCAND_PORT`, socketcand's 29536, as ``robocal sim lite``'s; 0: any
            free port).
        control: Control socket path (default: in a new temporary folder); the hands move the joints by the
            OpenArm profiles' joint names (``openarm_right_joint1`` …).

    Raises:
        UsageError: Unknown side, a negative seed.
        DeviceError: The address cannot be listened on.
    """
    from ...backends.damiao.openarm import SimOpenArm
    from ...backends.damiao.openarm_hands import OpenArmHands
    from ...backends.sim.serve import Session
    from ...backends.sim.socketcand import SocketcandServer

    sides = {"both": ("right", "left"), "right": ("right",), "left": ("left",)}.get(side)
    if sides is None:
        raise UsageError(f"--side {side!r}: expected both, right or left")
    if seed < 0:
        raise UsageError(f"--seed {seed}: expected a number >= 0")
    arms = [
        SimOpenArm(
            f"robocal-sim-openarm-{os.getpid()}-{s}",
            side="right" if s == "right" else "left",
            seed=seed + (s == "left"),
            zeroed=zeroed,
            realtime=True,
        )
        for s in sides
    ]
    buses = {OPENARM_BUSES[a.side]: a.channel for a in arms}
    server = SocketcandServer(buses, host=host, port=SOCKETCAND_PORT if port is None else port)
    with contextlib.ExitStack() as stack:
        for arm in arms:
            stack.enter_context(arm)
        stack.enter_context(server)
        names = ",".join(buses)
        where = f"host={server.host}&port={server.port}"
        source = f"can:socketcand:{names}?{where}"
        hands = OpenArmHands(arms)
        session = stack.enter_context(
            Session(hands, "openarm", source, control=control, extra={"attach": hands.attach})
        )
        lines = (
            f"source: {source}",
            "buses: " + ", ".join(f"{OPENARM_BUSES[a.side]} = {a.side} arm" for a in arms)
            + " (ids 0x01-0x08, replies 0x11-0x18)",
            f"python-can: can.Bus(interface='socketcand', channel='{next(iter(buses))}', host='{server.host}', "
            f"port={server.port})",
            f"LeRobot: can_interface='socketcand', port='{next(iter(buses))}', with CAN_CONFIG="
            f"'{{\"host\": \"{server.host}\", \"port\": {server.port}}}' in the environment",
            f"socketcand: {server.host}:{server.port}",
            f"control: {session.control_path}",
            "simulated OpenArm v10 ("
            + ("factory zeros" if not zeroed else "calibrated zeros")
            + ", real time); Ctrl-C stops it",
        )
        yield ServedDevice(f"OpenArm on socketcand {server.host}:{server.port}", lines, session.operator)


UR_PORT_OFFSETS: tuple[tuple[str, int], ...] = (
    ("dashboard", 0),
    ("primary", 2),
    ("secondary", 3),
    ("real-time", 4),
    ("rtde", 5),
)
"""A UR controller's ports as offsets from the dashboard's: 29999, 30001, 30002, 30003, 30004 from base 29999."""

UR_STANDARD_BASE_PORT = 29999
"""The dashboard's port on a real controller."""


@contextlib.contextmanager
def serve_ur(
    *,
    port: int = 30001,
    host: str = "127.0.0.1",
    dh: str | None = None,
    model: str | None = None,
    deltas: str | None = None,
    base_port: int | None = None,
) -> Iterator[ServedDevice]:
    """Serve a simulated UR controller on TCP: its primary interface, or all its ports.

    Without ``dh``, ``model`` and ``deltas`` it is a UR10e with a factory calibration (the UR demo's).

    Args:
        port: Primary interface port when ``base_port`` is None (0: any free port).
        host: Address to listen on.
        dh: DH YAML the controller reports.
        model: UR model (its nominal DH, plus ``deltas``).
        deltas: Calibration deltas added to ``model``'s DH.
        base_port: Serve every port of :data:`UR_PORT_OFFSETS` (dashboard, primary, secondary, real-time, RTDE) at
            ``base_port`` + offset (29999: the standard ports; 0: each on any free port).

    Raises:
        DeviceError: An address cannot be listened on.
        UsageError, FileFormatError: Bad DH inputs, or a base port whose last port passes 65535.
    """
    from ...backends.sim.ur_arm_state import UrArmState
    from ...backends.sim.ur_controller import SimUrController
    from ...backends.sim.ur_dashboard import SimUrDashboard
    from ...backends.sim.ur_realtime import SimUrRealtime
    from ...backends.sim.ur_rtde import SimUrRtde
    from ...core.ur import TEST_SET_3_DELTAS, nominal_dh
    from ..ur.job import load_dh_input

    last = UR_PORT_OFFSETS[-1][1]
    if base_port is not None and not 0 <= base_port <= 65535 - last:
        raise UsageError(f"--base-port {base_port}: expected 0 (any free ports) or 1..{65535 - last}")
    warnings: list[str] = []
    if dh is None and model is None and deltas is None:
        params = nominal_dh("ur10e") + TEST_SET_3_DELTAS
        what = "UR10e with a factory calibration (the deltas of robocal's UR demo)"
        model = "ur10e"
    else:
        params = load_dh_input(dh, model, deltas, warnings=warnings)
        what = (
            f"DH from {dh}" if dh is not None else f"{model} nominal DH" + (f" + {deltas}" if deltas else "")
        )
    arm = UrArmState(model=(model or "ur10e").upper().removesuffix("E"))
    makers: dict[str, Callable[[int], Any]] = {
        "dashboard": lambda p: SimUrDashboard(arm, host=host, port=p),
        "primary": lambda p: SimUrController(params, host=host, port=p, arm=arm),
        "secondary": lambda p: SimUrController(params, host=host, port=p, arm=arm),
        "real-time": lambda p: SimUrRealtime(params, arm, host=host, port=p),
        "rtde": lambda p: SimUrRtde(params, arm, host=host, port=p),
    }
    wanted = (
        [("primary", port)]
        if base_port is None
        else [(name, base_port + off if base_port else 0) for name, off in UR_PORT_OFFSETS]
    )
    with contextlib.ExitStack() as stack:
        served: dict[str, tuple[str, int]] = {}
        for name, p in wanted:
            try:
                server = makers[name](p)
            except OSError as exc:
                raise DeviceError(f"cannot listen on {host}:{p} ({exc.strerror or exc})") from None
            stack.enter_context(server)
            served[name] = server.address
        bound_host, bound_port = served["primary"]
        lines = [f"{name}: {h}:{p}" for name, (h, p) in served.items() if name != "primary"]
        ports = "primary interface" if base_port is None else "dashboard, primary, secondary, real-time and RTDE"
        lines += [
            f"address: {bound_host}:{bound_port}",
            f"simulated UR controller, {ports} ({what}); Ctrl-C stops it",
            f"try: robocal ur extract --host {bound_host} --port {bound_port} --out kinematics.yaml",
        ]
        yield ServedDevice(
            f"UR controller on {bound_host}:{bound_port}", tuple(lines), warnings=tuple(warnings)
        )
