"""The sag-pattern fit (issue 30): the follower's own offset from how its gravity sag varies with pose."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

from robocal.backends.sim.teleop import TeleopFaults
from robocal.core.health import fit_sag_offsets, t_quantile
from robocal.core.health.sag import last_direction
from robocal.dataset.teleop_sim import generate_teleop_datasets
from robocal.workflows.dataset.health import HealthRequest, evaluate_health


def _synthetic(e: np.ndarray, seed: int, episodes: int = 6) -> tuple[np.ndarray, ...]:
    """Two loaded joints on slow paths; residual = −slope·e + backlash (−0.1° · sign τ) + friction (0.12° · dir)."""
    rng = np.random.default_rng(seed)
    per = 1500
    n = episodes * per
    t = np.arange(n)
    state = np.stack([60 * np.sin(t / 97.0), 40 * np.sin(t / 61.0 + 1.0)], axis=1)  # ≤ 0.66°/frame
    action = state.copy()
    episode = np.repeat(np.arange(episodes), per)
    sag = np.stack([-1.5 * np.sin(np.radians(state[:, 0])), -0.6 * np.cos(np.radians(state[:, 1]))], axis=1)
    slope = np.zeros((n, 2, 2))
    slope[:, 0, 0] = -1.5 * np.cos(np.radians(state[:, 0])) * np.pi / 180
    slope[:, 1, 1] = 0.6 * np.sin(np.radians(state[:, 1])) * np.pi / 180
    slope[:, 1, 0] = 0.004
    direction = np.stack([last_direction(state[:, g], episode, 0.25) for g in range(2)], axis=1)
    residual = (
        -np.einsum("nij,j->ni", slope, e)
        + 0.1 * np.sign(sag)  # the link on the side gravity pulls it: −half · sign τ, τ of sign −sag
        + 0.12 * direction  # stopped short of the goal on the side it came from
        + rng.normal(0, 0.05, (n, 2))
    )
    residual[np.r_[True, episode[1:] != episode[:-1]]] = np.nan
    return residual, slope, sag, action, state, episode


@pytest.mark.parametrize("e", [(0.0, 0.0), (12.0, -6.0)])
def test_the_fit_recovers_the_offsets_with_backlash_and_friction_in_the_residual(
    e: tuple[float, float],
) -> None:
    residual, slope, sag, action, state, episode = _synthetic(np.array(e), seed=3)
    fit = fit_sag_offsets(residual, slope, sag, action, state, episode, (1, 2))
    assert fit is not None and fit.joints == (1, 2) and fit.episodes == 6
    for g in range(2):
        lo, hi = fit.interval(g, 0.99)
        assert lo <= e[g] <= hi
        assert hi - lo < 4.0
    assert np.allclose(fit.estimate, e, atol=1.0)


def test_the_fit_needs_three_episodes() -> None:
    residual, slope, sag, action, state, episode = _synthetic(np.zeros(2), seed=4, episodes=2)
    assert fit_sag_offsets(residual, slope, sag, action, state, episode, (0, 1)) is None


def test_t_quantiles_and_the_last_direction() -> None:
    assert t_quantile(0.99, 5) == pytest.approx(4.032)
    assert t_quantile(0.95, 11) == pytest.approx(2.228)  # the tabled dof below: conservative
    with pytest.raises(ValueError, match=r"level 0\.9 "):
        t_quantile(0.9, 5)
    x = np.array([0.0, 0.1, 0.5, 0.6, 0.4, 0.3, 0.0, 0.2, 5.0])
    ep = np.array([0, 0, 0, 0, 0, 0, 0, 0, 1])
    assert list(last_direction(x, ep, 0.25)) == [0, 0, 1, 1, 1, -1, -1, -1, 0]  # 0.6 → 0.3: reversed


@pytest.fixture(scope="module")
def reports(tmp_path_factory: pytest.TempPathFactory) -> dict[str, dict[str, Any]]:
    """One operator's motion (seed 8) three times, no range-end visits (p_end 0): the sag is the only evidence."""
    d = tmp_path_factory.mktemp("sag")
    cases = {
        "follower": TeleopFaults(offset_joint="shoulder_lift", offset_deg=17.0),
        "clean": TeleopFaults(),
        "leader": TeleopFaults(offset_joint="shoulder_lift", offset_deg=17.0, offset_arm="leader"),
    }
    out = {}
    for name, faults in cases.items():
        (root,) = generate_teleop_datasets(d / name, "so101", [8], [faults], p_end=0.0)
        out[name] = evaluate_health(HealthRequest(root, d / "r.json"))[1]
    return out


@pytest.mark.slow
@pytest.mark.timeout(900)  # the fixture simulates and checks three sessions: ~40 s quiet, minutes at load 20
def test_a_17_degree_follower_offset_without_range_end_contact_is_flagged_from_its_sag(
    reports: dict[str, dict[str, Any]],
) -> None:
    report = reports["follower"]
    j = report["joints"]["shoulder_lift"]
    assert j["status"] == "offset" and report["flagged"] == ["shoulder_lift"]
    assert all(e["kind"] == "together" for e in j["range_ends"])  # no range end showed it
    assert j["ci_deg"][0] <= 17.0 <= j["ci_deg"][1]
    assert j["offset_deg"] == pytest.approx(17.0, abs=3.0)
    assert "gravity sag follows another angle" in j["reasons"][0]


@pytest.mark.slow
@pytest.mark.timeout(900)
def test_offset_free_and_leader_offsets_without_contact_stay_unobservable(
    reports: dict[str, dict[str, Any]],
) -> None:
    for case in ("clean", "leader"):  # the leader's calibration leaves no trace in the follower's sag
        report = reports[case]
        assert report["flagged"] == []
        for name in ("shoulder_lift", "elbow_flex", "wrist_flex"):
            j = report["joints"][name]
            assert j["status"] == "unobservable"  # never ok: no range end was visited
            assert j["sag"]["ci99_deg"][0] <= 0.0 <= j["sag"]["ci99_deg"][1]
        assert report["joints"]["shoulder_pan"]["sag"] is None  # a vertical axis: no sag to fit


def test_without_masses_the_sag_shape_is_fitted_from_the_slow_frames() -> None:
    """Koch-like: 2.5° of sag ``−A·sin q`` and a follower pinned at its upper extreme; the pinned frames stay out."""
    from robocal.core.health import fitted_sag

    n = 3000
    q = 70 * np.sin(np.arange(n) / 150.0)  # slow: ≤ 0.47°/frame
    sag = 2.5 * np.sin(np.radians(q))  # action − state at rest
    state = q.copy()
    action = np.r_[q[1:], q[-1]] + sag  # the reading of t lags action t − 1
    state[q > 60] = 60.0  # pinned by a stop: the leader goes on
    episode = np.repeat(np.arange(3), n // 3)
    fit = fitted_sag(action, state, episode, state, 0.6, 3.0)
    free = q < 55
    assert np.max(np.abs(fit[free] - sag[free])) < 0.1
    assert fit.shape == (n,)
    few = fitted_sag(action[:20], state[:20], episode[:20], state[:20], 0.6, 3.0)
    assert np.all(few == 0.0)  # fewer than 30 slow frames: no fit
