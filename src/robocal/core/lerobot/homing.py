"""Homing rules of LeRobot's current calibration: the half-turn homing offset and robocal's centring of a swept travel."""

from __future__ import annotations

from ...errors import InvalidCalibrationError
from ..vendors import HomingRule, expected_homing_vendors, homing_vendor
from .normalisation import Compat
from .registers import encode_sign_magnitude

__all__ = ["centre_homing", "half_turn_homing_offset", "offset_in_register", "wrap_feetech_offset"]


def half_turn_homing_offset(
    present_ticks: int,
    *,
    vendor: str,
    resolution: int = 4096,
    compat: Compat = "exact",
) -> int:
    """Homing offset that makes the held pose read half a turn (``set_half_turn_homings``).

    Feetech firmware: ``Present = Actual − Homing_Offset`` → ``offset = pos − (res−1)//2``. Dynamixel:
    ``Present = Actual + Homing_Offset`` → ``offset = (res−1)//2 − pos``. The pose must be read after
    ``reset_calibration`` (offset 0), so Present = Actual.

    With ``compat="lerobot"`` a Feetech pose at 4095 gives +2048, which the sign-magnitude register cannot
    hold (LeRobot crashes with "Magnitude 2048 exceeds 2047"). The default ``"exact"`` first wraps the pose
    into ``[0, res)`` (multi-turn feedback) and clamps the Feetech offset to ±(res/2 − 1),
    so that pose reads 2048.

    Raises:
        InvalidCalibrationError: ``compat="lerobot"`` and the Feetech offset is not encodable.
    """
    spec = homing_vendor(vendor)
    if spec is None:
        raise InvalidCalibrationError(f"vendor {vendor!r}: expected {expected_homing_vendors()}")
    rule = spec.homing_rule()
    half = (resolution - 1) // 2
    pos = int(present_ticks)
    if not rule.wraps_per_turn:
        return rule.offset_reading(pos, half)
    if compat == "lerobot":
        offset = rule.offset_reading(pos, half)
        if rule.encoding == "sign-magnitude":
            encode_sign_magnitude(offset, rule.sign_bit)
        return offset
    offset = rule.offset_reading(pos % resolution, half)
    limit = resolution // 2 - 1
    return max(-limit, min(limit, offset))


def centre_homing(min_unwrapped: int, max_unwrapped: int, *, resolution: int = 4096) -> tuple[int, int, int]:
    """Shift that centres a swept travel on the half turn, so the seam lies outside it (fixes #3587).

    Args:
        min_unwrapped: Smallest unwrapped Present reading, ticks (may be < 0).
        max_unwrapped: Largest unwrapped Present reading, ticks (may be > resolution − 1).
        resolution: Ticks per turn.

    Returns:
        ``(shift, range_min, range_max)``: readings must be lowered by ``shift`` ticks (Feetech: add ``shift``
        to Homing_Offset; Dynamixel: subtract it), after which the travel is ``range_min..range_max`` inside
        ``[0, resolution − 1]``. A travel of a full turn or more gives ``0..resolution − 1``.
    """
    lo, hi = int(min_unwrapped), int(max_unwrapped)
    if hi - lo >= resolution - 1:
        shift = (lo + hi) // 2 - (resolution - 1) // 2
        return shift, 0, resolution - 1
    centre = (lo + hi) // 2
    shift = centre - (resolution - 1) // 2
    return shift, lo - shift, hi - shift


def wrap_feetech_offset(offset: int, lo: int, hi: int, res: int) -> tuple[int, int, int]:
    """Bring a Feetech Homing_Offset into ±(res/2 − 1), the sign-magnitude register's reach.

    Present wraps modulo a turn, so whole turns can be dropped; −res/2 is not encodable and becomes
    −res/2 + 1, which makes every reading one tick lower (the range ``lo..hi`` is lowered with it).

    Returns:
        ``(offset, lo, hi)``.
    """
    half = res // 2
    off = (offset + half) % res - half
    if off == -half:  # −2048 is not encodable: use −2047, which makes every reading one tick lower
        off = -half + 1
        lo, hi = lo - 1, hi - 1
    return off, lo, hi


def offset_in_register(rule: HomingRule, offset: int, lo: int, hi: int, res: int) -> tuple[int, int, int]:
    """A homing offset and its range as the register holds them.

    Brought into a half turn where the reading wraps per turn (:func:`wrap_feetech_offset`), unchanged otherwise.

    Returns:
        ``(offset, lo, hi)``.
    """
    if rule.wraps_per_turn:
        return wrap_feetech_offset(offset, lo, hi, res)
    return offset, lo, hi
