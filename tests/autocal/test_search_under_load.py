"""A slow control loop (robocal held up on a busy host) is never taken for a stop or a blocked move (issue 26 item 4).

The joint here follows every command at once (as ``robocal sim``'s servos do: a goal places the shaft, clamped at
its stops) and reports no velocity, while robocal's readings come 0.2–0.25 s apart. The search's target then
leads the last reading by ``speed·gap`` (clamped to ``max_lag``) although the joint reached every target it was
given: before the fix that lead was the lag test's evidence, so a search found a "stop" in free travel (the
SO-101 gripper's span 113° instead of 125° in the soak) and a transit move ran out of time ("could not reach …
blocked?"). The tests now judge the target the joint had a whole period to reach, and count each interval at
most ``EVIDENCE_GAP_S``.
"""

from __future__ import annotations

import math

import pytest

from robocal.core.stop_search import EVIDENCE_GAP_S, Command, SearchConfig, StopSample, StopSearch
from robocal.workflows.autocal.joint import move_to
from robocal.workflows.autocal.model import AutoCalAbortedError

MAX_LAG_RAD = math.radians(3.0)  # the Feetech goal's lead
SPEED_RAD_S = math.radians(20.0)


class TeleportJoint:
    """A joint that is wherever its last goal put it (clamped at ``stop_rad``); readings ``gap_s`` apart."""

    name = "j"

    def __init__(self, q_rad: float, stop_rad: float, gaps_s: tuple[float, ...]) -> None:
        self.q_rad, self.stop_rad, self.gaps_s = q_rad, stop_rad, gaps_s
        self.t_s = 0.0
        self.n = 0

    def read(self) -> StopSample:
        return StopSample(self.t_s, self.q_rad, 0.0, 0.0, True)

    def execute(self, cmd: Command) -> StopSample:
        if cmd.action in ("drive", "push", "hold") and math.isfinite(cmd.q_target_rad):
            self.q_rad = min(cmd.q_target_rad, self.stop_rad)
        self.t_s += self.gaps_s[self.n % len(self.gaps_s)]
        self.n += 1
        return self.read()

    def limp(self) -> None:
        pass

    def position_count_rad(self) -> float:
        return 0.0


def _search(joint: TeleportJoint) -> StopSearch:
    search = StopSearch(
        +1,
        SearchConfig(
            speed_rad_s=SPEED_RAD_S,
            torque_cap_nm=0.5,
            max_travel_rad=math.radians(150.0),
            max_time_s=12.0,
            max_lag_rad=MAX_LAG_RAD,
            reply_timeout_s=4.0,  # ROBOCAL_REPLY_TIMEOUT_MS 2000, as the soak runs robocal beside `robocal sim`
        ),
    )
    cmd = search.start(joint.read())
    for _ in range(5000):  # bounded
        if search.done:
            break
        cmd = search.step(joint.execute(cmd))
    assert search.done
    return search


@pytest.mark.parametrize("gaps_s", [(0.2,), (0.25,), (0.01, 0.3), (0.01, 0.01, 0.45)])
def test_a_slow_loop_finds_the_stop_where_it_is(gaps_s: tuple[float, ...]) -> None:
    joint = TeleportJoint(0.0, math.radians(60.0), gaps_s)
    result = _search(joint).result
    # the joint never reports a speed, so the test never arms: it ends "blocked" where it is held, at the stop
    # (the workflow takes that as the contact); before the fix it stopped within a few degrees of the start
    assert result.code == "blocked"
    assert math.degrees(result.q_pressed_rad) == pytest.approx(60.0, abs=1e-9)


def test_a_normal_loop_still_finds_the_stop_in_its_dwell() -> None:
    joint = TeleportJoint(0.0, math.radians(10.0), (0.01,))
    search = _search(joint)
    assert search.result.code == "blocked"
    assert math.degrees(search.result.q_pressed_rad) == pytest.approx(10.0, abs=1e-9)
    # at the stop until the verdict: the lead builds up to 0.9·max_lag (0.135 s at 20 °/s), one period for the
    # judged target to be that one, then 2·dwell (0.4 s)
    at_stop_s = joint.t_s - math.radians(10.0) / SPEED_RAD_S
    assert 0.54 <= at_stop_s <= 0.57


def test_a_transit_move_on_a_slow_loop_arrives() -> None:
    joint = TeleportJoint(0.0, math.inf, (0.2,))
    target = math.radians(90.0)
    s, stalled = move_to(joint, target, math.radians(100.0), 0.5, MAX_LAG_RAD, stall_s=0.2)  # type: ignore[arg-type]
    assert not stalled
    assert s.q_rad == pytest.approx(target, abs=math.radians(1.0))


def test_a_blocked_move_on_a_slow_loop_still_ends() -> None:
    joint = TeleportJoint(0.0, math.radians(20.0), (0.2,))
    with pytest.raises(AutoCalAbortedError, match="blocked"):
        move_to(joint, math.radians(90.0), math.radians(100.0), 0.5, MAX_LAG_RAD)  # type: ignore[arg-type]
    # the bound counts each 0.2-s interval as EVIDENCE_GAP_S: 0.9 s + 3 s of counted time
    assert joint.n * EVIDENCE_GAP_S == pytest.approx(3.9, abs=2 * EVIDENCE_GAP_S)


def test_a_transit_stall_on_a_slow_loop_is_at_the_obstacle() -> None:
    joint = TeleportJoint(0.0, math.radians(40.0), (0.2,))
    s, stalled = move_to(joint, math.radians(90.0), math.radians(100.0), 0.5, MAX_LAG_RAD, stall_s=0.2)  # type: ignore[arg-type]
    assert stalled
    assert math.degrees(s.q_rad) == pytest.approx(40.0, abs=1e-9)
