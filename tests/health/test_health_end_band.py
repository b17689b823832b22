"""A range end is judged against the residual of frames that came the same way (issue 30: Koch wrist_flex at 5°).

A servo's friction dead band leaves it short of its goal on the side it came from; the symmetric band of all slow
frames holds both sides (±1.3° on a Koch XL330 at its factory gain), which hid a 5° offset pinned at a stop.
"""

from __future__ import annotations

import numpy as np
import pytest

from robocal.backends.sim.teleop import TELEOP_ARMS, TeleopFaults, TeleopSession, simulate_sessions
from robocal.core.health import HealthConfig, JointData, JointHealth, analyse_joint, end_bands, fitted_joint


def _dead_band_joint(h_deg: float, n: int = 3000) -> tuple[JointData, np.ndarray, np.ndarray]:
    """A slow triangle wave whose follower stays ``h_deg`` short of its goal on the side it came from."""
    t = np.arange(n)
    action = 60.0 * (2.0 * np.abs((t / 600.0) % 2.0 - 1.0) - 1.0)  # ±60°, 0.2°/frame
    moving_up = np.gradient(action) > 0
    state = action - np.where(moving_up, h_deg, -h_deg)
    data = JointData("j", action, state, np.zeros(n, dtype=np.int64), np.zeros(n), -100.0, 100.0)
    residual = np.full(n, np.nan)
    residual[1:] = action[:-1] - state[1:]
    slow = np.ones(n, dtype=bool)
    return data, residual, slow


def test_each_end_band_is_the_side_the_follower_came_from_plus_the_margin() -> None:
    cfg = HealthConfig()
    data, residual, slow = _dead_band_joint(1.3)
    lo, hi = end_bands(data, residual, slow, 10.0, cfg)
    # towards each end the residual is 1.3° less the 0.2° the action moved in the frame, with no spread: the floor
    assert hi == pytest.approx(1.1 + cfg.band_floor_deg + cfg.end_margin_deg, abs=0.01)
    assert lo == pytest.approx(hi, abs=0.01)
    assert end_bands(data, residual, slow, 1.0, cfg) == (1.0, 1.0)  # never wider than the symmetric band
    few = np.zeros_like(slow)
    few[:20] = True
    assert end_bands(data, residual, few, 7.0, cfg) == (7.0, 7.0)  # under 30 frames: the symmetric band


def _koch_wrist(faults: TeleopFaults, seed: int) -> JointHealth:
    arm = TELEOP_ARMS["koch"]
    (session,) = simulate_sessions(arm, [seed], [faults])
    return _analysed(session, "wrist_flex")


def _analysed(session: TeleopSession, name: str) -> JointHealth:
    arm = session.arm
    e, t, j = session.action_deg.shape
    k = arm.joints.index(name)
    a = session.action_deg.reshape(-1, j)[:, k]
    s = session.state_deg.reshape(-1, j)[:, k]
    ep = np.repeat(np.arange(e), t)
    # the dataset check's joint without URDF masses: the sag and the dead band's side fitted from the data
    return analyse_joint(fitted_joint(name, a, s, ep, s, arm.stop_lo_deg[k], arm.stop_hi_deg[k]))


def test_a_5_degree_koch_wrist_offset_pinned_at_its_stop_is_flagged() -> None:
    h = _koch_wrist(TeleopFaults(offset_joint="wrist_flex", offset_deg=-5.0, offset_arm="follower"), 136)
    hi = next(e for e in h.ends if e.end == "hi")
    assert hi.kind == "pinned"
    # with the dead band's side fitted, the symmetric band is 1.18° (2-4.5° without it, which hid this end)
    assert h.band == pytest.approx(1.18, abs=0.01)
    assert hi.excess == pytest.approx(3.09, abs=0.01)
    # and the leader went on 5.0° past the follower, beyond the 3.14° it ever led it by elsewhere that way
    assert hi.leader - hi.follower == pytest.approx(5.0, abs=0.01)
    assert h.raw_caps[1] == pytest.approx(3.14, abs=0.01)
    assert h.status == "offset" and h.offset == pytest.approx(-5.0, abs=0.3)
    assert h.ci is not None and h.ci[0] <= -5.0 <= h.ci[1]


def test_an_offset_free_koch_wrist_is_not_flagged() -> None:
    sessions = simulate_sessions(TELEOP_ARMS["koch"], [0, 1, 2], [TeleopFaults()] * 3)  # integrated together
    for session in sessions:
        h = _analysed(session, "wrist_flex")
        assert h.status in ("ok", "unobservable"), (session.seed, h.reasons)
        assert all(e.kind == "together" and e.excess <= e.threshold for e in h.ends)
