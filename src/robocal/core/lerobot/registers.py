"""Servo register encodings LeRobot uses: Feetech sign-magnitude and Dynamixel two's complement.

Pure integer functions (no numpy needed); the vendor backends and the homing rule encode with them.
"""

from __future__ import annotations

from ...errors import InvalidCalibrationError

__all__ = [
    "decode_sign_magnitude",
    "decode_twos_complement",
    "encode_sign_magnitude",
    "encode_twos_complement",
]


def encode_sign_magnitude(value: int, sign_bit_index: int) -> int:
    """Feetech sign-magnitude encoding: ``((value < 0) << k) | |value|``.

    Raises:
        InvalidCalibrationError: ``|value| > 2**k − 1`` (LeRobot's message).
    """
    max_magnitude = (1 << sign_bit_index) - 1
    magnitude = abs(int(value))
    if magnitude > max_magnitude:
        raise InvalidCalibrationError(
            f"Magnitude {magnitude} exceeds {max_magnitude} (max for sign_bit_index={sign_bit_index})"
        )
    direction_bit = 1 if value < 0 else 0
    return (direction_bit << sign_bit_index) | magnitude


def decode_sign_magnitude(encoded: int, sign_bit_index: int) -> int:
    """Inverse of :func:`encode_sign_magnitude`; bits above ``k`` are ignored and "−0" is 0."""
    magnitude = int(encoded) & ((1 << sign_bit_index) - 1)
    return -magnitude if (int(encoded) >> sign_bit_index) & 1 else magnitude


def encode_twos_complement(value: int, n_bytes: int) -> int:
    """Dynamixel two's complement of ``value`` in ``n_bytes`` bytes.

    Raises:
        InvalidCalibrationError: value outside ``[−2**(8n−1), 2**(8n−1) − 1]`` (LeRobot's message).
    """
    bits = 8 * n_bytes
    lo, hi = -(1 << (bits - 1)), (1 << (bits - 1)) - 1
    v = int(value)
    if not lo <= v <= hi:
        raise InvalidCalibrationError(
            f"Value {v} out of range for {n_bytes}-byte two's complement: [{lo}, {hi}]"
        )
    return v & ((1 << bits) - 1)


def decode_twos_complement(encoded: int, n_bytes: int) -> int:
    """Inverse of :func:`encode_twos_complement`."""
    bits = 8 * n_bytes
    v = int(encoded) & ((1 << bits) - 1)
    return v - (1 << bits) if v & (1 << (bits - 1)) else v
