"""Issue 26 item 4: a reading that comes late (the host was descheduled for hundreds of milliseconds, or the reply
was late) while a joint is driven is a fault: the search fails ``no_reply`` and limps the joint, never takes the
gap for a stall (a stop) or for free travel."""

from __future__ import annotations

import math

import pytest

from robocal.core.stop_search import SearchConfig, StopSample, StopSearch

SPEED = math.radians(10)


def _config() -> SearchConfig:
    return SearchConfig(
        speed_rad_s=SPEED, torque_cap_nm=1.0, max_travel_rad=2.0, max_time_s=30.0, max_lag_rad=0.1,
        reply_timeout_s=0.5,
    )  # fmt: skip


def _moving(search: StopSearch, n: int, dt_s: float = 0.01) -> float:
    """Feed ``n`` readings of a joint moving at the search speed; returns the last time."""
    t = 0.0
    search.start(StopSample(t, 0.0, 0.0, 0.0))
    for _ in range(n):
        t += dt_s
        cmd = search.step(StopSample(t, SPEED * t, SPEED, 0.1))
        assert cmd.action != "limp"
    return t


@pytest.mark.parametrize("gap_s", [0.51, 0.8, 3.0])
def test_a_late_reading_while_driving_fails_no_reply_and_limps(gap_s: float) -> None:
    search = StopSearch(+1, _config())
    t = _moving(search, 60)
    # the joint stands still after the gap (it hit something, or not): the gap is no evidence either way
    cmd = search.step(StopSample(t + gap_s, SPEED * t, 0.0, 1.0))
    assert cmd.action == "limp"
    assert search.done and search.result.code == "no_reply"
    assert f"{gap_s:.2f} s after the one before" in search.result.reason


def test_readings_within_the_bound_are_not_a_fault() -> None:
    search = StopSearch(+1, _config())
    t = _moving(search, 60)
    cmd = search.step(StopSample(t + 0.45, SPEED * (t + 0.45), SPEED, 0.1))
    assert cmd.action != "limp" and not search.done


def test_silence_at_the_time_bound_is_no_reply_not_a_missing_stop() -> None:
    """A device lost just before the time bound: the search names the silence (``no_reply``), never "no stop"."""
    cfg = SearchConfig(
        speed_rad_s=SPEED, torque_cap_nm=1.0, max_travel_rad=2.0, max_time_s=1.0, max_lag_rad=0.1,
        reply_timeout_s=0.5,
    )  # fmt: skip
    search = StopSearch(+1, cfg)
    t = _moving(search, 90)
    cmd = None
    while not search.done:
        t += 0.05
        cmd = search.step(StopSample(t, math.nan, ok=False))
    assert cmd is not None and cmd.action == "limp"
    assert search.result.code == "no_reply"
    assert "the device is lost or not answering" in search.result.reason
    assert "no stop" not in search.result.reason
