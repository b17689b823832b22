"""Wire format of the simulated servo buses: Feetech protocol 0/1 and Dynamixel protocol 2.0 packets.

Pure functions: parse one instruction packet at the start of a byte buffer (Feetech: ``FF FF id len inst params
checksum``; Dynamixel 2.0: ``FF FF FD 00 id len_l len_h inst params crc_l crc_h`` with byte stuffing and CRC-16)
and build status packets.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable

__all__ = [
    "Instruction",
    "dxl_crc16",
    "dynamixel_status",
    "feetech_status",
    "parse_dynamixel",
    "parse_feetech",
]

Instruction = tuple[int, int, bytes]
"""A parsed instruction packet: (id, instruction, parameters)."""


def _crc_table() -> list[int]:
    table = []
    for i in range(256):
        crc = i << 8
        for _ in range(8):
            crc = ((crc << 1) ^ 0x8005) if crc & 0x8000 else (crc << 1)
        table.append(crc & 0xFFFF)
    return table


_CRC_TABLE = _crc_table()


def dxl_crc16(data: Iterable[int]) -> int:
    """Dynamixel protocol 2.0 CRC-16 (polynomial 0x8005, initial 0)."""
    crc = 0
    for b in data:
        i = ((crc >> 8) ^ b) & 0xFF
        crc = ((crc << 8) ^ _CRC_TABLE[i]) & 0xFFFF
    return crc


def _frame(
    buf: bytes | bytearray, header: bytes, head_len: int, total_len: Callable[[bytes | bytearray], int]
) -> tuple[int, bytes | None]:
    """Find the packet at the start of ``buf``: (bytes consumed, the whole packet or None).

    Bytes before ``header`` are consumed (resync) with None; consumed 0 means more bytes are needed: fewer
    than ``head_len`` (the bytes up to the length field) or than ``total_len(buf)``.
    """
    start = buf.find(header)
    if start < 0:
        return max(0, len(buf) - (len(header) - 1)), None
    if start > 0:
        return start, None
    if len(buf) < head_len:
        return 0, None
    total = total_len(buf)
    if len(buf) < total:
        return 0, None
    return total, bytes(buf[:total])


def parse_feetech(buf: bytes | bytearray) -> tuple[int, Instruction | None]:
    """One Feetech packet at the start of ``buf``: (bytes consumed, the instruction or None).

    Consumed 0 means more bytes are needed; a bad checksum consumes one byte (resync) and yields None.
    """
    total, pkt = _frame(buf, b"\xff\xff", 4, lambda b: b[3] + 4)
    if pkt is None:
        return total, None
    if (~sum(pkt[2:-1])) & 0xFF != pkt[-1]:
        return 1, None
    return total, (pkt[2], pkt[4], pkt[5:-1])


def feetech_status(motor_id: int, error: int, params: bytes, *, corrupt: bool = False) -> bytes:
    """A Feetech status packet (``corrupt``: with a wrong checksum)."""
    body = bytes([motor_id, len(params) + 2, error]) + params
    chk = (~sum(body)) & 0xFF
    if corrupt:
        chk ^= 0xFF
    return b"\xff\xff" + body + bytes([chk])


def parse_dynamixel(buf: bytes | bytearray) -> tuple[int, Instruction | None]:
    """One Dynamixel 2.0 packet at the start of ``buf`` (unstuffed): (bytes consumed, the instruction or None)."""
    total, pkt = _frame(buf, b"\xff\xff\xfd\x00", 7, lambda b: 7 + (b[5] | (b[6] << 8)))
    if pkt is None:
        return total, None
    if dxl_crc16(pkt[:-2]) != (pkt[-2] | (pkt[-1] << 8)):
        return 1, None
    body = pkt[7:-2]  # instruction + params, stuffed
    unstuffed = bytearray()
    i = 0
    while i < len(body):
        unstuffed.append(body[i])
        stuffed_fd = body[i] == 0xFD and i >= 2 and body[i - 1] == 0xFF and body[i - 2] == 0xFF
        if stuffed_fd and i + 1 < len(body) and body[i + 1] == 0xFD:
            i += 1
        i += 1
    if not unstuffed:
        return total, None
    return total, (pkt[4], unstuffed[0], bytes(unstuffed[1:]))


def dynamixel_status(motor_id: int, error: int, params: bytes, *, corrupt: bool = False) -> bytes:
    """A Dynamixel 2.0 status packet (instruction 0x55), byte-stuffed (``corrupt``: with a wrong CRC)."""
    raw = bytes([0x55, error]) + params
    stuffed = bytearray()
    for b in raw:
        stuffed.append(b)
        if b == 0xFD and len(stuffed) >= 3 and stuffed[-2] == 0xFF and stuffed[-3] == 0xFF:
            stuffed.append(0xFD)
    # a header-like FF FF FD spanning the id/length fields cannot occur in practice
    length = len(stuffed) + 2
    head = bytes([0xFF, 0xFF, 0xFD, 0x00, motor_id, length & 0xFF, length >> 8]) + bytes(stuffed)
    crc = dxl_crc16(head)
    if corrupt:
        crc ^= 0xFFFF
    return head + bytes([crc & 0xFF, crc >> 8])
