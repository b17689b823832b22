"""Fuzz the wire readers with mutated valid packets: only CalibError may escape.

UR primary interface (sub-package parsers and the client over a real loopback TCP socket), Robstride CAN
frames (decoders and :class:`RobstrideBus` on python-can's ``virtual`` bus) and Feetech / Dynamixel status
packets (the unmodified vendor SDKs against a simulated servo on a pseudo-terminal whose replies are mutated).
"""

from __future__ import annotations

import itertools
import socket
import struct
import threading
from collections.abc import Callable
from typing import Any

import pytest
from fuzzlib import ODD_BYTES, byte_mutation, fuzz_settings
from hypothesis import given
from hypothesis import strategies as st

from robocal.backends.sim.ur_controller import build_robot_state, build_version_message
from robocal.backends.ur_primary import (
    KINEMATICS_INFO_SIZE,
    PrimaryClient,
    encode_kinematics_info,
    iter_subpackages,
    parse_kinematics_info,
    parse_pose_sample,
)
from robocal.core.ur import nominal_dh
from robocal.errors import CalibError


def calib_error_only(fn: Callable[[], object], what: str) -> CalibError | None:
    try:
        fn()
    except CalibError as exc:
        assert str(exc).strip(), f"{what}: {type(exc).__name__} with an empty message"
        return exc
    except Exception as exc:
        raise AssertionError(f"{what}: {type(exc).__name__} escaped (not a CalibError): {exc!r}") from exc
    return None


DH = nominal_dh("ur10e")
STATE = build_robot_state(DH, q_rad=(0.1, -1.2, 1.0, -0.5, 1.5, 0.3))
STATE_PAYLOAD = STATE[5:]
KIN = encode_kinematics_info(DH)
NONFINITE = [struct.pack(">d", x) for x in (float("nan"), float("inf"), float("-inf"), 1e308)]


def ur_mutation(data: st.DataObject, seed: bytes) -> bytes:
    """Byte mutations plus a non-finite double or an odd size field written at a random offset."""
    kind = data.draw(st.sampled_from(["bytes", "double", "size"]), label="ur")
    if kind == "bytes" or len(seed) < 8:
        return byte_mutation(data, seed)
    pos = data.draw(st.integers(0, len(seed) - 8), label="pos")
    if kind == "double":
        value = data.draw(st.sampled_from(NONFINITE), label="double")
    else:
        value = (
            struct.pack(
                ">I", data.draw(st.sampled_from([0, 1, 4, 5, 224, 226, 2**31, 2**32 - 1]), label="size")
            )
            * 2
        )
    return seed[:pos] + value + seed[pos + 8 :]


@pytest.mark.slow
@fuzz_settings(300)
@given(data=st.data())
def test_ur_subpackage_parsers_raise_only_calib_error(data: st.DataObject) -> None:
    payload = ur_mutation(data, STATE_PAYLOAD)
    kin = ur_mutation(data, KIN)

    def run() -> None:
        for sub_type, sub in iter_subpackages(payload):
            if sub_type == 5:
                parse_kinematics_info(sub)
        parse_pose_sample(payload)

    calib_error_only(run, "UR RobotState parsers")
    err = calib_error_only(lambda: parse_kinematics_info(kin), "UR KinematicsInfo parser")
    if err is None:
        _info, longer = parse_kinematics_info(kin)
        assert longer == (len(kin) > KINEMATICS_INFO_SIZE)


class OneShotServer:
    """A loopback TCP server that sends ``stream`` to each client, then closes (or stays silent)."""

    def __init__(self) -> None:
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
        self.sock.bind(("127.0.0.1", 0))
        self.sock.listen(8)
        self.sock.settimeout(5.0)
        self.port = self.sock.getsockname()[1]
        self.stream = b""
        self.hold_open = False
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)
        self._thread.start()

    def _run(self) -> None:
        while not self._stop.is_set():
            try:
                conn, _ = self.sock.accept()
            except OSError:
                continue
            with conn:
                try:
                    conn.sendall(self.stream)
                    if self.hold_open:
                        conn.settimeout(1.0)
                        conn.recv(1)
                except OSError:
                    pass

    def close(self) -> None:
        self._stop.set()
        self.sock.close()
        self._thread.join(timeout=6.0)


@pytest.fixture(scope="module")
def ur_server() -> Any:
    server = OneShotServer()
    yield server
    server.close()


@pytest.mark.slow
@fuzz_settings(60)
@given(data=st.data())
def test_ur_primary_client_raises_only_calib_error(ur_server: OneShotServer, data: st.DataObject) -> None:
    stream = build_version_message() + STATE + STATE
    ur_server.stream = ur_mutation(data, stream)
    ur_server.hold_open = data.draw(st.booleans(), label="hold open")
    what = data.draw(st.sampled_from(["kinematics", "poses"]), label="read")

    def run() -> None:
        with PrimaryClient("127.0.0.1", ur_server.port, timeout_s=0.3) as client:
            if what == "kinematics":
                client.read_kinematics()
            else:
                client.read_pose_samples(2)

    calib_error_only(run, f"UR primary client ({what})")


# ------------------------------------------------------------------------------------------------ Robstride
from robocal.backends.robstride import protocol as rs  # noqa: E402

ARB = st.one_of(st.integers(0, (1 << 29) - 1), st.sampled_from([-1, 1 << 29, 1 << 31, 2**64]))
PAYLOAD = st.one_of(st.binary(max_size=12), st.sampled_from([b"", bytes(8), b"\xff" * 8, *ODD_BYTES]))


@pytest.mark.slow
@fuzz_settings(400)
@given(arb=ARB, payload=PAYLOAD, model=st.sampled_from(["rs-00", "rs-02", "rs-05"]))
def test_robstride_decoders_raise_only_calib_error(arb: int, payload: bytes, model: str) -> None:
    limits = rs.model_limits(model)
    for name, fn in [
        ("split_id", lambda: rs.split_id(arb)),
        ("decode_feedback", lambda: rs.decode_feedback(arb, payload, limits)),
        ("decode_param_reply", lambda: rs.decode_param_reply(arb, payload)),
        ("decode_firmware_reply", lambda: rs.decode_firmware_reply(arb, payload)),
        ("decode_fault_report", lambda: rs.decode_fault_report(payload)),
        ("decode_mit_command", lambda: rs.decode_mit_command(arb, payload, limits)),
    ]:
        calib_error_only(fn, f"Robstride {name}")


_channels = itertools.count()


def robstride_replies(data: st.DataObject, host: int, motor: int) -> list[tuple[int, bytes]]:
    """Frames a (broken) motor might send: valid replies of each type, then mutated ids and payloads."""
    fb = rs.Feedback(
        motor_id=motor,
        host_id=host,
        mode=2,
        faults=0,
        position_rad=0.5,
        velocity_rad_s=0.0,
        torque_nm=0.0,
        temperature_c=30.0,
    )
    valid = [
        rs.encode_feedback(fb, rs.model_limits("rs-00")),
        rs.encode_param_reply(motor, host, int(rs.Param.MECH_POS), 1.25),
        rs.encode_param_reply(motor, host, int(rs.Param.ZERO_STA), 1),
        rs.encode_firmware_reply(motor, host, (1, 2, 3, 4)),
        (rs.make_id(0, motor, 0xFE), bytes(range(8))),
    ]
    out = []
    for _ in range(data.draw(st.integers(1, 4), label="frames")):
        arb, payload = data.draw(st.sampled_from(valid), label="frame")
        if data.draw(st.booleans(), label="mutate id"):
            arb ^= 1 << data.draw(st.integers(0, 28), label="id bit")
        if data.draw(st.booleans(), label="mutate data"):
            payload = byte_mutation(data, payload)[:8]
        out.append((arb, payload))
    return out


@pytest.mark.slow
@fuzz_settings(40)
@given(data=st.data())
def test_robstride_bus_raises_only_calib_error(data: st.DataObject) -> None:
    import can

    from robocal.backends.robstride.bus import MotorSpec, RobstrideBus

    channel = f"fuzz-rs-{next(_channels)}"
    peer = can.Bus(channel=channel, interface="virtual", receive_own_messages=False)
    try:
        with RobstrideBus(
            channel, [MotorSpec("j1", 11, "rs-00")], interface="virtual", timeout_s=0.02
        ) as bus:
            call = data.draw(
                st.sampled_from(
                    ["ping", "read_position", "read_zero_sta", "firmware", "zero_torque", "enable"]
                ),
                label="call",
            )
            for arb, payload in robstride_replies(data, bus.host_id, 11):
                peer.send(can.Message(arbitration_id=arb, data=payload, is_extended_id=True))
            fn = {
                "ping": lambda: bus.ping("j1"),
                "read_position": lambda: bus.read_position("j1"),
                "read_zero_sta": lambda: bus.read_zero_sta("j1"),
                "firmware": lambda: bus.read_firmware_version("j1"),
                "zero_torque": lambda: bus.zero_torque(),
                "enable": lambda: bus.enable("j1"),
            }[call]
            calib_error_only(fn, f"RobstrideBus.{call}")
    finally:
        peer.shutdown()


# ------------------------------------------------------------------------------------------- servo buses
from robocal.backends.sim.servo import SimServo, SimServoBus  # noqa: E402


class MutatingServoBus(SimServoBus):
    """The simulated servos, with each status packet passed through pre-drawn mutations."""

    def __init__(self, *args: Any, ops: list[tuple[str, int, int]], **kw: Any) -> None:
        super().__init__(*args, **kw)
        self.ops = ops
        self.sent = 0

    def _send(self, data: bytes) -> None:
        out = bytearray(data)
        for kind, a, b in self.ops:
            if not out:
                break
            pos = a % len(out)
            if kind == "flip":
                out[pos] ^= 1 << (b % 8)
            elif kind == "truncate":
                del out[pos:]
            elif kind == "insert":
                out[pos:pos] = ODD_BYTES[b % len(ODD_BYTES)]
            elif kind == "set":
                out[pos] = b % 256
            elif kind == "drop" and self.sent % 2 == b % 2:
                out.clear()
            elif kind == "double":
                out = out + bytes(out)
            elif kind == "fix-checksum":
                out = bytearray(_fix_checksum(bytes(out), self.vendor))
        self.sent += 1
        super()._send(bytes(out))


def _fix_checksum(pkt: bytes, vendor: str) -> bytes:
    """Recompute the checksum so a mutated packet passes the SDK's integrity check."""
    from robocal.backends.sim.servo import dxl_crc16

    if vendor == "feetech":
        return pkt[:-1] + bytes([(~sum(pkt[2:-1])) & 0xFF]) if len(pkt) > 3 else pkt
    if len(pkt) < 9:
        return pkt
    crc = dxl_crc16(pkt[:-2])
    return pkt[:-2] + bytes([crc & 0xFF, crc >> 8])


SERVO_OPS = st.lists(
    st.tuples(
        st.sampled_from(["flip", "truncate", "insert", "set", "drop", "double", "fix-checksum"]),
        st.integers(0, 255),
        st.integers(0, 255),
    ),
    min_size=1,
    max_size=4,
)


@pytest.mark.slow
@pytest.mark.parametrize("model", ["sts3215", "scs0009", "xl330-m288"])
@fuzz_settings(25)
@given(ops=SERVO_OPS, call=st.sampled_from(["ping", "read", "sync_read", "write"]))
def test_servo_status_packets_raise_only_calib_error(
    model: str, ops: list[tuple[str, int, int]], call: str
) -> None:
    if model == "xl330-m288":
        from robocal.backends.dynamixel import DynamixelBus as Bus
    else:
        from robocal.backends.feetech import FeetechBus as Bus  # type: ignore[assignment]
    servos = [SimServo(1, model), SimServo(2, model)]
    with (
        MutatingServoBus(servos, ops=ops) as sim,
        Bus(sim.port, {1: model, 2: model}, retries=1, packet_timeout_ms=20) as bus,
    ):
        fn = {
            "ping": lambda: bus.ping(1),
            "read": lambda: bus.read("Present_Position", 2),
            "sync_read": lambda: bus.sync_read("Present_Position", [1, 2]),
            "write": lambda: bus.write("Goal_Position", 1, 1000),
        }[call]
        calib_error_only(fn, f"{model} {call}")


class ShortReplyServoBus(SimServoBus):
    """Servos whose status packets carry no parameters (a reply to another instruction, or a truncated one)."""

    def _status(self, motor_id: int, error: int, params: bytes = b"") -> bytes:
        return super()._status(motor_id, error, b"")


@pytest.mark.parametrize("model", ["sts3215", pytest.param("scs0009", marks=pytest.mark.slow)])
def test_feetech_read_answered_without_data_is_a_protocol_error(model: str) -> None:
    """Found by the fuzzer (a ping status packet arriving twice, the second answering the model-number read):
    scservo_sdk indexes into the status packet's missing data; the IndexError escaped as a traceback."""
    from robocal.backends.feetech import FeetechBus
    from robocal.errors import ProtocolError

    with (
        ShortReplyServoBus([SimServo(1, model)]) as sim,
        FeetechBus(sim.port, {1: model}, retries=1, packet_timeout_ms=500) as bus,
    ):
        with pytest.raises(
            ProtocolError,
            match=r"motor 1: read 'Present_Position' failed after 2 tries: .*garbled status packet: IndexError",
        ):
            bus.read("Present_Position", 1)
        with pytest.raises(
            ProtocolError, match=r"motor 1: ping 'Model_Number' failed after 2 tries: .*garbled"
        ):
            bus.ping(1)
