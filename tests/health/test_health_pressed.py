"""A Koch follower pinned at its stop: the dead band's side in the fitted sag, the raw cap, and what the stop held.

Issue 30, "a ≥ 5° offset flagged where the joint is taken to a range end": a Koch XL330 at its factory gain stops
up to 1.3° short of its goal on the side it came from, and gravity holds its elbow 2.5° off a stop at LeRobot's
gain 1500. The sag fitted from the data takes the dead band's side as a column (the band narrows), a pinned end
must also stand out of the raw residual (no sag model at the ends), and the simulator records how hard the stop
held the follower, which says whether the data can show the offset at all.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from robocal.backends.sim.teleop import TELEOP_ARMS, TeleopFaults, TeleopSession, simulate_sessions
from robocal.core.health import (
    HealthConfig,
    JointData,
    JointHealth,
    analyse_joint,
    end_raw_caps,
    fitted_joint,
    fitted_sag,
    last_direction,
)

ARM = TELEOP_ARMS["koch"]


def _frames(session: TeleopSession, name: str) -> tuple[np.ndarray, np.ndarray, np.ndarray, int]:
    e, t, j = session.action_deg.shape
    k = ARM.joints.index(name)
    return (
        session.action_deg.reshape(-1, j)[:, k],
        session.state_deg.reshape(-1, j)[:, k],
        np.repeat(np.arange(e), t),
        k,
    )


def _checked(session: TeleopSession, name: str) -> JointHealth:
    a, s, ep, k = _frames(session, name)
    return analyse_joint(fitted_joint(name, a, s, ep, s, ARM.stop_lo_deg[k], ARM.stop_hi_deg[k]))


def _checked_before(session: TeleopSession, name: str) -> JointHealth:
    """The check before the dead band's side and the raw cap: a sine-only sag, no cap."""
    a, s, ep, k = _frames(session, name)
    sag = fitted_sag(a, s, ep, s, 0.3, 3.0)
    return analyse_joint(JointData(name, a, s, ep, sag, ARM.stop_lo_deg[k], ARM.stop_hi_deg[k]))


def _triangle(h_deg: float, sag_amp_deg: float, n: int = 3000) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A slow ±60° triangle; the follower sags ``sag_amp·sin q`` and stops ``h_deg`` short on the side it came from."""
    t = np.arange(n)
    action = 60.0 * (2.0 * np.abs((t / 600.0) % 2.0 - 1.0) - 1.0)
    up = np.gradient(action) > 0
    state = action - np.where(up, h_deg, -h_deg) - sag_amp_deg * np.sin(np.radians(action))
    return action, state, np.zeros(n, dtype=np.int64)


def test_the_fitted_sag_takes_the_dead_bands_side() -> None:
    a, s, ep = _triangle(1.3, 1.2)
    prev = np.concatenate([[np.nan], a[:-1]])
    way = last_direction(s, ep, 0.3)
    with_side = fitted_sag(a, s, ep, s, 0.3, 3.0, way)
    without = fitted_sag(a, s, ep, s, 0.3, 3.0)
    inner = (s > s.min() + 3) & (s < s.max() - 3) & np.isfinite(prev)
    # what is left after the fit: 0.014° with the side; 1.35° without it (the dead band either side, less the
    # 0.2° the goal moved in a frame, and the sine fitted through both sides)
    assert np.max(np.abs((prev - s - with_side)[inner])) == pytest.approx(0.014, abs=0.002)
    assert np.max(np.abs((prev - s - without)[inner])) == pytest.approx(1.35, abs=0.02)


def test_raw_caps_are_the_largest_raw_residual_towards_each_end_only_for_a_fitted_sag() -> None:
    a, s, ep = _triangle(1.3, 0.0)
    cfg = HealthConfig()
    slow = np.ones(a.size, dtype=bool)
    fitted = JointData("j", a, s, ep, np.zeros(a.size), -100.0, 100.0, sag_fitted=True)
    lo, hi = end_raw_caps(fitted, slow, cfg)
    # towards either end the follower trails its last goal by 1.3° less the 0.2° of one frame, + the 0.25° margin
    assert lo == pytest.approx(1.1 + cfg.end_margin_deg, abs=0.01)
    assert hi == pytest.approx(1.1 + cfg.end_margin_deg, abs=0.01)
    urdf = JointData("j", a, s, ep, np.zeros(a.size), -100.0, 100.0)
    assert end_raw_caps(urdf, slow, cfg) == (-math.inf, -math.inf)  # a URDF's sag is not extrapolated: no cap


def test_a_5_degree_wrist_offset_the_old_band_hid_is_flagged_with_its_interval() -> None:
    (session,) = simulate_sessions(
        ARM, [22], [TeleopFaults(offset_joint="wrist_flex", offset_deg=5.0, offset_arm="follower")]
    )
    truth = session.truth["wrist_flex"]
    assert truth.held_lo_deg == pytest.approx(3.46, abs=0.01)  # the lower stop held it past its friction
    assert truth.friction_span_deg == pytest.approx(2.60, abs=0.01)
    assert _checked_before(session, "wrist_flex").status == "unobservable"
    h = _checked(session, "wrist_flex")
    assert h.status == "offset"
    assert h.offset == pytest.approx(4.91, abs=0.01)
    assert h.ci is not None and h.ci[0] <= 5.0 <= h.ci[1]


def test_the_raw_cap_keeps_an_offset_free_wrist_from_a_false_pin() -> None:
    # seed 40091 of the batch 40050-40099 (the batch's noise is drawn from its first seed): an offset-free wrist
    # whose fitted sag is 1° off at its upper end, where the follower rested 2.2° behind its leader
    sessions = simulate_sessions(ARM, list(range(40050, 40100)), [TeleopFaults()] * 50)
    session = sessions[41]
    assert session.seed == 40091
    a, s, ep, k = _frames(session, "wrist_flex")
    data = fitted_joint("wrist_flex", a, s, ep, s, ARM.stop_lo_deg[k], ARM.stop_hi_deg[k])
    uncapped = analyse_joint(JointData(**{**data.__dict__, "sag_fitted": False}))
    assert uncapped.status == "offset" and uncapped.ends[0].kind == "pinned"  # what the cap prevents
    h = analyse_joint(data)
    assert h.status == "unobservable"
    (hi,) = h.ends
    assert hi.kind == "together"
    assert hi.leader - hi.follower == pytest.approx(2.20, abs=0.01)
    assert h.raw_caps[1] == pytest.approx(3.33, abs=0.01)


def test_the_simulator_records_how_hard_the_stop_held_the_follower() -> None:
    spans = simulate_sessions(ARM, [1], [TeleopFaults()])[0].truth
    # 2·τ_stiction/kp: XL430 at 640, XL330 at 1500 (elbow), XL330 at 400
    assert [round(spans[n].friction_span_deg, 2) for n in ARM.joints] == [0.57, 0.57, 0.69, 2.6, 2.6, 2.6]
    pressed, touched = simulate_sessions(
        ARM,
        [0, 13],
        [
            TeleopFaults(offset_joint="elbow_flex", offset_deg=5.0, offset_arm="follower"),
            TeleopFaults(offset_joint="elbow_flex", offset_deg=-5.0, offset_arm="follower"),
        ],
    )
    # the goal 5.07° past the lower stop: gravity (2.5°) and friction leave the stop holding 2.3° of it
    t = pressed.truth["elbow_flex"]
    assert (round(t.pin_depth_deg, 2), round(t.held_lo_deg, 2), t.held_hi_deg) == (5.07, 2.32, 0.0)
    assert _checked(pressed, "elbow_flex").status == "offset"
    # the goal 2.4° past the upper stop, the sag 2.5°: the follower never reached it; the data cannot show it
    t = touched.truth["elbow_flex"]
    assert t.follower_contact and (round(t.pin_depth_deg, 2), t.held_lo_deg, t.held_hi_deg) == (2.43, 0.0, 0.0)
    h = _checked(touched, "elbow_flex")
    assert h.status == "unobservable"
    assert h.reasons == (
        "neither range end pressed the follower against its stop",
        "the upper end: the follower came to 91.33 with its leader at 94.13, not held by its stop (a negative "
        "offset shows there only as a follower held at its stop while the leader goes on)",
        "the lower end: the follower came to -94.47 with its leader at -96.77, not held by its stop (a positive "
        "offset shows there only as a follower held at its stop while the leader goes on)",
    )


@pytest.mark.slow
def test_the_report_carries_each_ends_band_and_raw_cap(tmp_path: Path) -> None:
    from robocal.cli.main import main
    from robocal.dataset.teleop_sim import generate_teleop_datasets

    faults = [TeleopFaults(offset_joint="wrist_flex", offset_deg=5.0, offset_arm="follower")]
    (root,) = generate_teleop_datasets(tmp_path, "koch", [22], faults)  # the session of the test above
    report = tmp_path / "h.json"
    code = main(["dataset", "health", str(root), "--robot", "koch_follower", "--use-degrees", "--report", str(report)])
    rep = json.loads(report.read_text())
    assert code == 1 and rep["flagged"] == ["wrist_flex"]
    joint = rep["joints"]["wrist_flex"]
    assert joint["status"] == "offset" and joint["offset_deg"] == pytest.approx(4.91, abs=0.01)
    (lo,) = [e for e in joint["range_ends"] if e["end"] == "lo"]
    assert lo["kind"] == "pinned"
    assert lo["leader"] - lo["follower"] < -lo["raw_cap"]  # the leader went on past the follower beyond the cap
    assert lo["excess"] > lo["band"]
    shoulder = rep["joints"]["shoulder_pan"]  # no stops (a full turn): no fitted sag, no cap
    assert shoulder["status"] == "unobservable" and shoulder["range_ends"] == []
