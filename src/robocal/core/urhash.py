"""The ``calib_`` hash UR's driver compares with the robot (``KinematicsInfo::toHash``).

The string is every joint's θ, d, a, α (in that order, joints 1..6) printed with a C++ ``std::ostream``'s
default formatting (``%g``: 6 significant digits) and concatenated without separators. The hash is
libstdc++'s 64-bit ``std::hash<std::string>`` (``_Hash_bytes``, a MurmurHash2-64 variant with seed
``0xc70f6907``) printed as an unsigned decimal after ``calib_``. It hashes the **raw** controller DH, not the
corrected values, and is libstdc++-specific (libc++ and MSVC builds of the driver compute different numbers).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

__all__ = [
    "MURMUR_SEED",
    "calib_hash",
    "cpp_ostream_format",
    "hash_bytes_libstdcxx",
    "kinematics_hash_string",
]

_MASK = (1 << 64) - 1
_MUL = 0xC6A4A7935BD1E995
MURMUR_SEED = 0xC70F6907
"""Seed libstdc++ passes to ``_Hash_bytes`` for ``std::hash<std::string>``."""


def _shift_mix(v: int) -> int:
    return v ^ (v >> 47)


def hash_bytes_libstdcxx(data: bytes, seed: int = MURMUR_SEED) -> int:
    """libstdc++ ``std::_Hash_bytes`` for 64-bit ``size_t``.

    Args:
        data: Bytes to hash.
        seed: Seed (``0xc70f6907`` for ``std::hash<std::string>``).

    Returns:
        The unsigned 64-bit hash.
    """
    n = len(data)
    h = (seed ^ ((n * _MUL) & _MASK)) & _MASK
    end8 = n - (n % 8)
    for off in range(0, end8, 8):
        w = int.from_bytes(data[off : off + 8], "little")
        h ^= (_shift_mix((w * _MUL) & _MASK) * _MUL) & _MASK
        h = (h * _MUL) & _MASK
    if n % 8:
        t = int.from_bytes(data[end8:], "little")
        h ^= t
        h = (h * _MUL) & _MASK
    h = (_shift_mix(h) * _MUL) & _MASK
    return _shift_mix(h)


def cpp_ostream_format(value: float) -> str:
    """Format a double like ``std::ostream << value`` with default flags (``%g``, precision 6).

    Args:
        value: The number.

    Returns:
        E.g. ``"0.1625"``, ``"1.5708"``, ``"-0.425"``, ``"1e-05"``, ``"-0"``, ``"inf"``, ``"nan"``.
    """
    if math.isnan(value):
        return "-nan" if math.copysign(1.0, value) < 0 else "nan"
    return "%g" % value  # noqa: UP031 - C printf semantics are the point


def kinematics_hash_string(
    theta_rad: Sequence[float], d_m: Sequence[float], a_m: Sequence[float], alpha_rad: Sequence[float]
) -> str:
    """The string hashed by ``KinematicsInfo::toHash`` (θ, d, a, α per joint, ``%g``, no separators)."""
    parts: list[str] = []
    for i in range(len(theta_rad)):
        parts.extend(cpp_ostream_format(float(v[i])) for v in (theta_rad, d_m, a_m, alpha_rad))
    return "".join(parts)


def calib_hash(
    theta_rad: Sequence[float], d_m: Sequence[float], a_m: Sequence[float], alpha_rad: Sequence[float]
) -> str:
    """The ``calib_<uint64>`` hash of raw DH parameters, as ``ur_robot_driver`` computes it.

    Args:
        theta_rad: θ per joint, radians.
        d_m: d per joint, metres.
        a_m: a per joint, metres.
        alpha_rad: α per joint, radians.

    Returns:
        E.g. ``"calib_12788084448423163542"`` for the nominal UR5e.
    """
    s = kinematics_hash_string(theta_rad, d_m, a_m, alpha_rad)
    return f"calib_{hash_bytes_libstdcxx(s.encode('ascii'))}"
