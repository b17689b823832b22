"""Issue 26 item 4: a reading that comes late (the host was descheduled for hundreds of milliseconds, or the reply
was late) while a joint is driven is a fault: the search fails ``no_reply`` and limps the joint, never takes the
gap for a stall (a stop) or for free travel. A driver whose motor's own host-loss watchdog decides sets no such bound
(``max_reading_gap_s=inf``, the Damiao driver; issue 31): the gap then only counts at most ``evidence_gap_s``.
A lost reply while the joint rests in free travel confirms no stop (issue 31)."""

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


def test_a_driver_whose_motor_watchdog_decides_goes_on_after_a_gap_without_counting_it() -> None:
    """``max_reading_gap_s=inf`` (the Damiao driver: the motor's armed TIMEOUT and the read-back decide, issue 31):
    a gap is not a fault; it counts at most ``evidence_gap_s`` toward the dwell, so one gap never confirms a stop."""
    cfg = SearchConfig(
        speed_rad_s=SPEED, torque_cap_nm=1.0, max_travel_rad=2.0, max_time_s=30.0, max_lag_rad=0.1,
        reply_timeout_s=0.5, max_reading_gap_s=math.inf,
    )  # fmt: skip
    search = StopSearch(+1, cfg)
    t = _moving(search, 60)
    q = SPEED * t
    for gap_s in (0.8, 3.0):  # two stalled readings, each after a long gap: 0.1 s of the dwell counted
        t += gap_s
        cmd = search.step(StopSample(t, q, 0.0, 1.0))
        assert cmd.action == "drive" and not search.done
    actions = []
    for _ in range(12):  # the rest of the 0.2 s dwell needs ~0.1 s more of readings 10 ms apart
        t += 0.01
        actions.append(search.step(StopSample(t, q, 0.0, 1.0)).action)
    assert actions[:8] == ["drive"] * 8 and "push" in actions[8:11]


@pytest.mark.parametrize("bad", [0.0, -1.0, math.nan])
def test_a_reading_gap_bound_must_be_positive(bad: float) -> None:
    from robocal.errors import InvalidCalibrationError

    with pytest.raises(InvalidCalibrationError, match="max_reading_gap_s"):
        SearchConfig(
            speed_rad_s=SPEED, torque_cap_nm=1.0, max_travel_rad=2.0, max_time_s=30.0, max_lag_rad=0.1,
            max_reading_gap_s=bad,
        )  # fmt: skip


def test_a_lost_reply_while_the_joint_rests_in_free_travel_confirms_no_stop() -> None:
    """A reply lost while an armed joint happens to rest (a stick-slip step on a busy host) and a re-read that
    agrees: not a stop (issue 31's soak: the gripper's upper stop "confirmed" 24° short). The joint is driven on
    2° past that place; it follows, and the search goes on."""
    search = StopSearch(+1, _config())
    t = _moving(search, 60)  # armed (0.6 s at the search speed: 6° of travel)
    q = SPEED * t
    t += 0.04
    assert search.step(StopSample(t, q, 0.0, 0.02)).action == "drive"  # at rest, no push: a stick-slip step
    t += 0.1
    assert search.step(StopSample(t, math.nan, ok=False)).action == "reread"  # the reply came too late
    t += 0.01
    cmd = search.step(StopSample(t, q + math.radians(0.3), 0.0, 0.02))  # the re-read agrees within 1°
    assert cmd.action == "drive" and cmd.q_target_rad == pytest.approx(q + math.radians(2.3))  # on, 2° past it
    for _ in range(30):  # it follows: no stop
        t += 0.01
        q += SPEED * 0.01 + math.radians(0.07)
        assert search.step(StopSample(t, q, SPEED, 0.1)).action == "drive"
    assert not search.done and search.phase == "approach"


def test_a_joint_silent_at_its_stop_is_confirmed_once_it_stays_put_when_driven_past() -> None:
    search = StopSearch(+1, _config())
    t = _moving(search, 60)
    q = SPEED * t
    t += 0.01
    search.step(StopSample(t, q, 0.0, 0.3))  # slowed at the stop
    for _ in range(2):  # silent at the stop: lost, re-read where it was, driven past, lost again, re-read there
        t += 0.1
        assert search.step(StopSample(t, math.nan, ok=False)).action == "reread"
        t += 0.01
        cmd = search.step(StopSample(t, q, 0.0, 0.3))
    assert cmd.action == "drive" and cmd.q_target_rad == pytest.approx(q)  # backing off from the confirmed stop
    assert search.phase == "backoff"


def test_lost_replies_all_along_the_travel_are_counted_per_place_not_per_search() -> None:
    """A busy host loses a reply now and then while the joint travels freely: five such events over 30° are not
    the ``max_suspects`` (3) events at one place that fail a search (the soak's J6: "4 no-reply events the position
    re-read did not confirm as a stop" with no fault injected). Four at one place still fail it."""
    search = StopSearch(+1, _config())
    t = _moving(search, 10)  # not armed yet (1° of travel): every lost reply is a plain suspect
    q = SPEED * t
    for _ in range(5):
        t += 0.1
        assert search.step(StopSample(t, math.nan, ok=False)).action == "reread"
        t += 0.01
        search.step(StopSample(t, q, SPEED, 0.1))  # the re-read: where it was
        for _ in range(60):  # then 6° of free travel
            t += 0.01
            q += SPEED * 0.01
            assert search.step(StopSample(t, q, SPEED, 0.1)).action != "limp"
    assert not search.done
    for _ in range(4):  # four at one place (re-read there each time, as if moving: not a probe of a stop)
        t += 0.1
        search.step(StopSample(t, math.nan, ok=False))
        t += 0.01
        cmd = search.step(StopSample(t, q, SPEED, 0.1))
    assert cmd.action == "limp" and search.result.code == "no_reply"
    assert "4 no-reply events the position re-read did not confirm as a stop" in search.result.reason
