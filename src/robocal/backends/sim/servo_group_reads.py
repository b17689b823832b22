"""Dynamixel Protocol 2.0 Bulk Read (0x92), Fast Sync Read (0x8A), Fast Bulk Read (0x9A), Bulk Write (0x93).

Bulk Read: ``{id, ADDR(2), LEN(2)}…`` to 0xFE, answered by one ordinary status packet per listed servo, in the
listed order. Fast Sync Read (params as Sync Read: ``ADDR(2) LEN(2) id…``) and Fast Bulk Read (params as Bulk
Read) are answered by one combined status packet with id 0xFE::

    FF FF FD 00 FE LEN_L LEN_H 55 | ERR_1 ID_1 DATA_1 CRC_1(2) | … | ERR_k ID_k DATA_k CRC_k(2)

``LEN = 1 + Σ(N_i + 4)``; each slot's CRC is the running CRC-16 of every byte before it, so the last one is the
packet's CRC; the packet is not byte-stuffed (ROBOTIS's DynamixelSDK parses it so; see docs/sim.md).
Bulk Write (``{id, ADDR(2), LEN(2), LEN bytes}…`` to 0xFE) is applied by each listed servo, answered by none.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING

from .servo_packets import dxl_crc16

if TYPE_CHECKING:
    from .servo import SimServoBus
    from .servo_model import SimServo

__all__ = ["BULK_WRITE", "GROUP_READS", "bulk_write", "fast_status", "group_read"]

GROUP_READS = (0x8A, 0x92, 0x9A)
"""Fast Sync Read, Bulk Read, Fast Bulk Read."""
BULK_WRITE = 0x93
"""Bulk Write."""


def fast_status(slots: Sequence[tuple[int, int, bytes]]) -> bytes:
    """The combined status packet of a fast read: ``(error, id, data)`` per slot, running CRCs, no stuffing."""
    length = 1 + sum(len(data) + 4 for _, _, data in slots)
    out = bytearray([0xFF, 0xFF, 0xFD, 0x00, 0xFE, length & 0xFF, length >> 8, 0x55])
    for error, motor_id, data in slots:
        out += bytes([error, motor_id]) + data
        crc = dxl_crc16(out)
        out += bytes([crc & 0xFF, crc >> 8])
    return bytes(out)


def _requests(inst: int, params: bytes) -> list[tuple[int, int, int]]:
    """``(id, address, length)`` per servo asked, in the packet's order."""
    if inst == 0x8A:
        addr, size = params[0] | params[1] << 8, params[2] | params[3] << 8
        return [(i, addr, size) for i in params[4:]]
    return [
        (params[k], params[k + 1] | params[k + 2] << 8, params[k + 3] | params[k + 4] << 8)
        for k in range(0, len(params) - 4, 5)
    ]


def group_read(bus: SimServoBus, inst: int, params: bytes, listening: Sequence[SimServo]) -> None:
    """Answer a Bulk / Fast Sync / Fast Bulk Read (whatever the servos' status return level)."""
    slots: list[tuple[int, int, bytes]] = []
    for motor_id, addr, size in _requests(inst, params):
        for servo in listening:
            if servo.bus_id != motor_id or motor_id in bus.silent_ids:
                continue
            data = bus.read_registers(servo, addr, size)
            if inst == 0x92:
                bus.reply(servo, 0, data)
                continue
            fw = servo.firmware
            if fw is not None and not fw.answers():  # its slot is missing, as a servo that does not answer
                continue
            slots.append((fw.error_byte() if fw is not None else 0, servo.bus_id, data))
    if slots:
        bus.send(fast_status(slots))


def bulk_write(bus: SimServoBus, params: bytes, listening: Sequence[SimServo]) -> None:
    """Apply a Bulk Write: each ``{id, ADDR(2), LEN(2), data}`` block by the servo with that id; no reply."""
    k = 0
    while k + 5 <= len(params):
        motor_id, addr, size = params[k], params[k + 1] | params[k + 2] << 8, params[k + 3] | params[k + 4] << 8
        data = params[k + 5 : k + 5 + size]
        k += 5 + size
        if len(data) < size:
            return
        for servo in [s for s in listening if s.bus_id == motor_id]:
            if not bus.write_registers(servo, addr, data):
                bus.note_write(servo, addr, size)
