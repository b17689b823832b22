"""The dataset health check's core on simulated teleoperation sessions with a known truth (issue 30)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from robocal.backends.sim.physics import Drive, JointPlant, PlantParams
from robocal.backends.sim.teleop import TELEOP_ARMS, TeleopFaults, TeleopSession, simulate_sessions
from robocal.backends.sim.teleop_plant import PlantArrays, simulate_tracking
from robocal.core.health import JointData, JointHealth, analyse_joint


def _joint(session: TeleopSession, name: str) -> JointHealth:
    arm = session.arm
    e, t, j = session.action_deg.shape
    k = arm.joints.index(name)
    a = session.action_deg.reshape(-1, j)[:, k]
    s = session.state_deg.reshape(-1, j)[:, k]
    data = JointData(
        name, a, s, np.repeat(np.arange(e), t), np.zeros_like(a), arm.stop_lo_deg[k], arm.stop_hi_deg[k]
    )
    return analyse_joint(data)


def test_vectorised_plant_matches_the_joint_plant() -> None:
    """One joint, no gravity, no stops reached: the numpy plant follows JointPlant's steps to within a tick."""
    p = PlantParams(
        inertia_kgm2=0.004,
        coulomb_nm=0.04,
        stiction_nm=0.06,
        viscous_nms_rad=0.02,
        stop_lower_rad=-2.0,
        stop_upper_rad=2.0,
        stiffness_lower=300,
        stiffness_upper=300,
        counts_per_rev=4096,
        dt_s=1 / 240,
    )
    kp, kd = 19.455, 0.3056
    goals = np.concatenate([np.zeros(10), np.full(30, 0.5), np.full(30, -0.3)])
    plant = JointPlant(p, q0_rad=0.0)
    ref = []
    for k, g in enumerate(goals):
        ref.append(plant.read().q_rad)
        plant.run_until((k + 1) / 30, Drive(kp, kd, float(g), 0.0, 0.0, 1.91))
    one = np.array([1.0])
    arrays = PlantArrays(
        kp * one,
        kd * one,
        1.91 * one,
        0.004 * one,
        0.04 * one,
        0.06 * one,
        0.02 * one,
        0.0 * one,
        -2.0 * one,
        2.0 * one,
        300.0 * one,
        0.0 * one,
    )
    got = simulate_tracking(goals[None, :, None], arrays, None, fps=30, substeps=8)[0, :, 0]
    assert np.max(np.abs(got - np.array(ref))) <= 2 * math.tau / 4096


@pytest.fixture(scope="module")
def so101_sessions() -> list[TeleopSession]:
    arm = TELEOP_ARMS["so101"]
    faults = [
        TeleopFaults(),
        TeleopFaults(offset_joint="elbow_flex", offset_deg=-17.0),
        TeleopFaults(slip_joint="wrist_flex", slip_episode=1, slip_frame=120, slip_deg=8.0),
        TeleopFaults(flip_joint="wrist_flex"),
        TeleopFaults(clip_joint="shoulder_lift", clip_end="hi", clip_short_deg=6.0),
    ]
    # followers pressed into their stops (no position limits enforced: the Koch's kind of servo)
    return simulate_sessions(arm, [11, 12, 13, 14, 15], faults, episodes=3, episode_s=10.0, p_end=1.0, goal_limits=False)


def _limited(session: TeleopSession, name: str) -> JointHealth:
    arm = session.arm
    e, t, j = session.action_deg.shape
    k = arm.joints.index(name)
    a, s = session.action_deg.reshape(-1, j)[:, k], session.state_deg.reshape(-1, j)[:, k]
    data = JointData(name, a, s, np.repeat(np.arange(e), t), np.zeros_like(a), arm.stop_lo_deg[k],
                     arm.stop_hi_deg[k], goal_limited=True)  # fmt: skip
    return analyse_joint(data)


@pytest.mark.parametrize("seed", [21, 22, 23, 24])
def test_an_so101_follower_held_by_its_limits_is_read_as_limits(seed: int) -> None:
    """The SO-101's STS3215s clamp the goal to LeRobot's recorded range. A correct pair is held up to the hand's
    scatter at both ends: before, that read as two ends that disagree (17 / 48 offset-free benchmark sessions
    flagged). A follower-side 17° offset holds both ends alike: its sign is not in the data, so no signed number
    (before, one end's hold was reported as an offset of either sign)."""
    arm = TELEOP_ARMS["so101"]
    faults = [TeleopFaults(), TeleopFaults(offset_joint="elbow_flex", offset_deg=17.0 if seed % 2 else -17.0),
              TeleopFaults(offset_joint="elbow_flex", offset_deg=-17.0, offset_arm="leader")]  # fmt: skip
    free, follower, leader = simulate_sessions(arm, [seed] * 3, faults, episodes=3, episode_s=10.0, p_end=1.0)
    for name in arm.joints[:4]:
        assert _limited(free, name).status in ("ok", "unobservable"), name
    t = follower.truth["elbow_flex"]
    h = _limited(follower, "elbow_flex")
    if min(t.limited_lo_deg, t.limited_hi_deg) > 10.0:  # both ends held
        assert (h.status, h.offset, h.ci) == ("suspect", None, None)
        assert any("sign not in the data" in r for r in h.reasons), h.reasons
    assert h.status != "offset" and h.status != "ok"
    t, h = leader.truth["elbow_flex"], _limited(leader, "elbow_flex")
    if t.limited_hi_deg > 10.0:
        assert (h.status, h.offset) == ("suspect", None) and any("held by its position limit" in r for r in h.reasons)


def test_17_degree_offset_is_flagged_on_its_joint(so101_sessions: list[TeleopSession]) -> None:
    s = so101_sessions[1]
    h = _joint(s, "elbow_flex")
    assert s.truth["elbow_flex"].follower_contact
    assert h.status == "offset"
    assert h.offset is not None and h.ci is not None
    assert h.ci[0] - 0.5 <= -17.0 <= h.ci[1] + 0.5
    assert abs(h.offset + 17.0) < 4.0


def test_offset_free_session_flags_nothing(so101_sessions: list[TeleopSession]) -> None:
    statuses = {n: _joint(so101_sessions[0], n).status for n in TELEOP_ARMS["so101"].joints[:5]}
    assert set(statuses.values()) <= {"ok", "unobservable"}


def test_slip_is_located_to_its_episode_and_frame(so101_sessions: list[TeleopSession]) -> None:
    h = _joint(so101_sessions[2], "wrist_flex")
    assert h.status == "suspect"
    assert [(j.episode, abs(j.frame - 120) <= 2) for j in h.jumps] == [(1, True)]
    assert h.jumps[0].size == pytest.approx(8.0, abs=1.5)


def test_mirrored_sign_is_suspect(so101_sessions: list[TeleopSession]) -> None:
    h = _joint(so101_sessions[3], "wrist_flex")
    assert h.status == "suspect"
    assert "sign flip" in h.reasons[0]


def test_clipped_values_are_not_read_as_an_offset(so101_sessions: list[TeleopSession]) -> None:
    h = _joint(so101_sessions[4], "shoulder_lift")
    assert h.status == "suspect"
    assert [e.kind for e in h.ends if e.end == "hi"] == ["clipped"]


def test_a_joint_that_never_moves_is_unobservable() -> None:
    a = np.zeros(100)
    h = analyse_joint(JointData("j", a, a, np.zeros(100, dtype=np.int64), a, -90.0, 90.0))
    assert h.status == "unobservable"
    assert h.offset is None and h.ci is None


def test_offsets_that_differ_between_episodes_are_a_drift() -> None:
    from robocal.core.health import HealthConfig, drift_reason

    episodes: list[dict[str, object]] = [
        {"episode": 0, "offset": 0.2, "status": "ok"},
        {"episode": 1, "offset": None, "status": "unobservable"},
        {"episode": 2, "offset": -9.0, "status": "offset"},
    ]
    reason = drift_reason(episodes, 0.6, HealthConfig(), 1.0)
    assert reason == "the offset changes between episodes: -9.00 in episode 2, +0.20 in episode 0"
    episodes[2]["offset"] = -2.5  # within twice the threshold (1.5°): one calibration
    assert drift_reason(episodes, 0.6, HealthConfig(), 1.0) is None


@pytest.mark.parametrize("seed", [2, 3])
def test_a_slip_whose_reading_is_the_sessions_extreme_is_located(seed: int) -> None:
    """A slip's own reading is often the follower's extreme, where the response fit leaves frames out (a stop
    holds the follower there); a reading thrown away from its goal by more than the threshold is judged anyway.
    Both seeds were missed before (the benchmark's two SO-101 slip misses were of this kind)."""
    arm = TELEOP_ARMS["so101"]
    (session,) = simulate_sessions(arm, [seed], [TeleopFaults()], episodes=2, episode_s=10.0)
    k = arm.joints.index("shoulder_pan")
    a = session.action_deg[:, :, k].reshape(-1)
    s = session.state_deg[:, :, k].reshape(-1).copy()
    ep = np.repeat(np.arange(2), 300)
    t = {2: 269, 3: 45}[seed]  # the follower at rest within 3° of its lowest reading
    assert abs(s[t] - s[t - 1]) < 0.2 and s[t] < s.min() + 3.0
    # the reading jumps 9° down, then the arm moves until its reading follows its goal again
    s[t : t + 5] -= 9.0 * np.array([1.0, 0.55, 0.25, 0.1, 0.03])
    assert s[t] == s.min()
    h = analyse_joint(JointData("shoulder_pan", a, s, ep, np.zeros_like(a), -110.0, 110.0))
    assert h.status == "suspect"
    assert [(j.episode, j.frame) for j in h.jumps] == [(0, t)]
    assert h.jumps[0].size == pytest.approx(-8.97, abs=0.02)


def test_a_follower_reversing_out_of_its_top_speed_is_no_step() -> None:
    """Seed 7029 of the benchmark's offset-free SO-101 sessions: the leader's wrist_roll is flicked faster than the
    follower can turn (it runs at its top speed, 8.4° a frame, up to 84° behind), and the follower's reversal out
    of that run missed the response fit by 3.4°, over the 3° floor: a "step" on a correct pair, the last false
    alarm of the offset-free sessions (1 of 348). The frames right after a run at the top speed are no longer
    judged by the fit; a slip anywhere else still is (the tests above)."""
    from robocal.dataset.teleop_sim import arm_gravity

    arm = TELEOP_ARMS["so101"]
    (session,) = simulate_sessions(arm, [7029], [TeleopFaults()], gravity=arm_gravity(arm), modes=arm.modes)
    k = arm.joints.index("wrist_roll")
    a = session.action_deg[0, :, k]
    s = session.state_deg[0, :, k]
    assert np.abs(np.diff(s[140:150])).max() > 8.0 and abs(a[147] - s[147]) > 10.0  # the run at its top speed
    h = _joint(session, "wrist_roll")
    assert h.jumps == ()
    assert h.status in ("ok", "unobservable")

