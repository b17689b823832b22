"""End-to-end sweeps on the simulated Lite over the virtual CAN bus, replay equivalence, interrupts."""

from __future__ import annotations

import json
import math
import signal
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from tests.bags import write_joint_states

from robocal.backends.sim.lite import SimLite
from robocal.core.sweep import wrap_in_travel
from robocal.formats import read_calibration
from robocal.workflows.sweep.job import SweepAbortedError, SweepRequest, run_sweep
from robocal.workflows.sweep.power_on_check import check_source

TOL = 2e-3


@pytest.mark.slow
@pytest.mark.parametrize(
    ("seed", "zero_sta", "single_turn"),
    [(0, 1, False), (1, 1, True), (2, 0, False), (3, 0, True)],
)
def test_recovered_offsets_match_truth(
    urdf: Path, tmp_path: Path, h: Any, seed: int, zero_sta: int, single_turn: bool
) -> None:
    sim = SimLite(seed, noise_rad=5e-4, zero_sta=zero_sta, single_turn=single_turn)
    out = tmp_path / "cal.yaml"
    outcome = run_sweep(SweepRequest(urdf, "sim:lite", out), open_source_fn=h.sim_opener(sim))
    truth = sim.true_offsets()
    cf = read_calibration(out)
    assert cf.calibration.joint_names == tuple(h.names)
    for j in outcome.result.joints:
        assert j.homing_offset == pytest.approx(truth[j.name], abs=TOL), j.name
        assert cf.calibration.homing_offset[cf.calibration.index(j.name)] == j.homing_offset
        assert "not_swept" not in j.warnings and "span_mismatch" not in j.warnings
        assert j.sweep == pytest.approx(j.span, abs=0.01)
    assert dict(cf.ids) == {j.name: j.can_id for j in sim.joints}


def _two_ctrl_c() -> None:
    """Two real Ctrl-Cs (SIGINT to this process; each handler runs before ``raise_signal`` returns)."""
    signal.raise_signal(signal.SIGINT)
    signal.raise_signal(signal.SIGINT)
    raise AssertionError("a second Ctrl-C while finishing must interrupt")


@pytest.mark.slow
def test_joints_whose_travel_crosses_the_wrap_point(urdf: Path, tmp_path: Path, h: Any) -> None:
    # factory zeros chosen so the power-on wrap point (0 with zero_sta 0) lies inside the travel of these joints;
    # single-turn readings jump by 2π mid-sweep
    zeros = {"left_shoulder_pitch": 0.3, "left_elbow_pitch": -0.6, "right_shoulder_roll": 0.2}
    sim = SimLite(5, noise_rad=5e-4, zero_sta=0, single_turn=True, factory_zero_rad=zeros)
    outcome = run_sweep(SweepRequest(urdf, "sim:lite", tmp_path / "c.yaml"), open_source_fn=h.sim_opener(sim))
    truth = sim.true_offsets()
    for name in zeros:
        j = outcome.result[name]
        assert j.homing_offset == pytest.approx(truth[name], abs=TOL)
        assert "wrap_in_travel" in j.warnings
        assert bool(wrap_in_travel(truth[name], j.direction, j.lower, j.upper, 0))
        assert j.sweep == pytest.approx(j.span, abs=0.01)  # the tracker unwrapped the 2π jump
    assert outcome.exit_code == 1


@pytest.mark.slow
def test_power_on_branch_selection_via_check_source(urdf: Path, tmp_path: Path, h: Any) -> None:
    zeros = {"left_elbow_pitch": 0.6}
    sim = SimLite(6, noise_rad=0.0, zero_sta=0, factory_zero_rad=zeros)
    out = tmp_path / "c.yaml"
    run_sweep(SweepRequest(urdf, "sim:lite", out), open_source_fn=h.sim_opener(sim))
    # after a power cycle at another pose every joint must still read its true position
    h_cal = read_calibration(out).calibration.homing_offset[3]
    sim.motors["left_elbow_pitch"].set_position(-2.3)
    sim.power_cycle()
    checks = {c.name: c for c in check_source(urdf, out, "sim:lite", open_source_fn=h.sim_opener(sim))}
    c = checks["left_elbow_pitch"]
    assert c.in_limits and c.problem is None
    assert c.q_rad == pytest.approx(-2.3, abs=1e-3)
    assert c.raw_selected_rad - c.raw_rad == pytest.approx(2 * math.pi * c.turns)
    assert np.isfinite(h_cal)
    for name, q in sim.joint_positions().items():
        assert checks[name].q_rad == pytest.approx(q, abs=1e-3), name


@pytest.mark.slow
def test_check_source_reports_the_two_pi_correction(urdf: Path, tmp_path: Path, h: Any) -> None:
    sim = SimLite(8, noise_rad=0.0, zero_sta=0, factory_zero_rad={"left_shoulder_pitch": 0.2})
    out = tmp_path / "c.yaml"
    run_sweep(SweepRequest(urdf, "sim:lite", out), open_source_fn=h.sim_opener(sim))
    sp = sim.motors["left_shoulder_pitch"]  # dir -1: raw = -q + 0.2 (+ branch)
    results = []
    for q in (-2.5, 0.5):  # raw 2.7 and -0.3: the second wraps to 2π - 0.3 at power-on
        sp.set_position(q)
        sim.power_cycle()
        c = {c.name: c for c in check_source(urdf, out, "sim:lite", open_source_fn=h.sim_opener(sim))}
        results.append(c["left_shoulder_pitch"])
        assert c["left_shoulder_pitch"].q_rad == pytest.approx(q, abs=1e-3)
    assert {r.turns for r in results} == {0, 1} or {r.turns for r in results} == {0, -1}


def _write_csv(path: Path, names: list[str], t: np.ndarray, s: np.ndarray) -> None:
    rows = ["t," + ",".join(names)]
    rows += [",".join(repr(float(x)) for x in (ti, *si)) for ti, si in zip(t, s, strict=True)]
    path.write_text("\n".join(rows) + "\n")


@pytest.mark.slow
def test_replay_csv_and_rosbag_match_live(urdf: Path, tmp_path: Path, h: Any) -> None:
    sim = SimLite(11, noise_rad=5e-4, zero_sta=0, single_turn=True)
    opener, made = h.recording_opener(sim)
    live = run_sweep(SweepRequest(urdf, "sim:lite", tmp_path / "live.yaml"), open_source_fn=opener)
    rec = made[0]
    t = np.array([s.t_s for s in rec.samples])
    raw = np.vstack([s.position_rad for s in rec.samples])
    d = np.array([h.dirs[n] for n in h.names], dtype=float)
    ident = raw * d  # what the robot publishes with an empty calibration
    live_off = live.result.offsets()

    _write_csv(tmp_path / "sweep.csv", h.names, t, ident)
    _write_csv(tmp_path / "motor.csv", h.names, t, raw)
    write_joint_states(tmp_path / "bag_sqlite", h.names, t, ident, plugin="sqlite3")
    write_joint_states(tmp_path / "bag_mcap", h.names, t, ident, topic="/robot/js")
    cases: list[tuple[str, dict[str, Any]]] = [
        (f"replay:{tmp_path / 'sweep.csv'}", {}),
        (f"replay:{tmp_path / 'motor.csv'}", {"frame": "motor"}),
        (f"replay:{tmp_path / 'bag_sqlite'}", {}),
        (f"replay:{tmp_path / 'bag_mcap'}", {"topic": "/robot/js"}),
    ]
    for i, (src, kw) in enumerate(cases):
        res = run_sweep(SweepRequest(urdf, src, tmp_path / f"r{i}.yaml", **kw))
        for name, off in live_off.items():
            assert res.result[name].homing_offset == pytest.approx(off, abs=1e-12), (src, name)
        assert [j.warnings for j in res.result.joints] == [j.warnings for j in live.result.joints]
        assert res.samples == live.samples


@pytest.mark.slow
def test_first_ctrl_c_writes_a_complete_file(urdf: Path, tmp_path: Path, h: Any) -> None:
    out = tmp_path / "cal.yaml"
    prior_sim = SimLite(12, noise_rad=0.0)
    run_sweep(SweepRequest(urdf, "sim:lite", out), open_source_fn=h.sim_opener(prior_sim))
    before = read_calibration(out).calibration
    sim = SimLite(13, noise_rad=0.0, skip=["left_wrist_pitch"])
    opener, _ = h.recording_opener(sim, interrupt_at=60)
    outcome = run_sweep(SweepRequest(urdf, "sim:lite", out), open_source_fn=opener)
    assert outcome.interrupted and outcome.samples == 60
    after = read_calibration(out).calibration
    assert after.joint_names == tuple(h.names)  # complete: every joint present
    kept = [j.name for j in outcome.result.joints if j.kept_prior]
    assert kept == [
        "left_wrist_pitch"
    ]  # joints not yet swept at the interrupt kept the previous file's offset
    for name in kept:
        assert after.homing_offset[after.index(name)] == before.homing_offset[before.index(name)]
    assert (tmp_path / "cal.yaml.bak").exists()


@pytest.mark.slow
def test_second_ctrl_c_writes_nothing(urdf: Path, tmp_path: Path, h: Any) -> None:
    out = tmp_path / "cal.yaml"
    run_sweep(SweepRequest(urdf, "sim:lite", out), open_source_fn=h.sim_opener(SimLite(14, noise_rad=0.0)))
    old = out.read_bytes()
    opener, _ = h.recording_opener(SimLite(15), interrupt_at=30, interrupt_close=True)
    with pytest.raises(SweepAbortedError, match="second Ctrl-C; nothing was written"):
        run_sweep(SweepRequest(urdf, "sim:lite", out, report=tmp_path / "r.json"), open_source_fn=opener)
    assert out.read_bytes() == old
    assert not (tmp_path / "r.json").exists()


@pytest.mark.slow
def test_report_json_exact_shape(urdf: Path, tmp_path: Path, h: Any) -> None:
    sim = SimLite(16, noise_rad=0.0, skip=["right_wrist_roll"])
    prior = tmp_path / "prior.json"
    ids = {j.name: j.can_id for j in sim.joints}
    prior.write_text(
        json.dumps({n: {"id": ids[n], "direction": h.dirs[n], "homing_offset": 0.125} for n in h.names})
    )
    out, rep = tmp_path / "cal.json", tmp_path / "report.json"
    outcome = run_sweep(
        SweepRequest(
            urdf,
            "sim:lite",
            out,
            prior=prior,
            report=rep,
        ),
        open_source_fn=h.sim_opener(sim),
    )
    data = json.loads(rep.read_text())
    assert list(data) == ["joints"] and list(data["joints"]) == h.names
    keys = [
        "sampled_min",
        "sampled_max",
        "sweep",
        "homing_offset",
        "previous_homing_offset",
        "kept_prior",
        "warnings",
    ]
    for entry in data["joints"].values():
        assert list(entry) == keys
    wr = data["joints"]["right_wrist_roll"]
    assert wr["kept_prior"] is True and wr["homing_offset"] == 0.125 and wr["warnings"] == ["not_swept"]
    assert data["joints"]["left_elbow_pitch"]["previous_homing_offset"] == 0.125
    assert json.loads(out.read_text())["right_wrist_roll"] == {
        "id": 26,
        "direction": 1,
        "homing_offset": 0.125,
    }
    assert outcome.exit_code == 1


@pytest.mark.slow
def test_second_ctrl_c_between_report_and_calibration_says_what_was_written(
    urdf: Path, tmp_path: Path, h: Any, monkeypatch: pytest.MonkeyPatch
) -> None:
    # the report is written first, the calibration last; a Ctrl-C between the two names the report as written
    # and the calibration as unchanged
    from robocal.workflows.sweep import job as wf

    out, rep = tmp_path / "cal.yaml", tmp_path / "r.json"
    run_sweep(SweepRequest(urdf, "sim:lite", out), open_source_fn=h.sim_opener(SimLite(41, noise_rad=0.0)))
    old = out.read_bytes()

    def interrupted_before(*a: Any, **k: Any) -> None:
        assert rep.exists()  # the report is already complete when the calibration is written
        _two_ctrl_c()

    monkeypatch.setattr(wf, "write_calibration", interrupted_before)
    with pytest.raises(SweepAbortedError) as exc:
        run_sweep(
            SweepRequest(
                urdf,
                "sim:lite",
                out,
                report=rep,
            ),
            open_source_fn=h.sim_opener(SimLite(42, noise_rad=0.0)),
        )
    assert str(exc.value) == (
        f"sweep aborted by a second Ctrl-C after writing {rep} (complete); {out} not written (unchanged)"
    )
    assert out.read_bytes() == old and list(json.loads(rep.read_text())) == ["joints"]


@pytest.mark.slow
def test_second_ctrl_c_after_the_calibration_was_written_says_so(
    urdf: Path, tmp_path: Path, h: Any, monkeypatch: pytest.MonkeyPatch
) -> None:
    from robocal.workflows.sweep import job as wf

    real = wf.write_calibration
    out, rep = tmp_path / "cal.yaml", tmp_path / "r.json"

    def interrupted_after(*a: Any, **k: Any) -> None:
        real(*a, **k)
        _two_ctrl_c()  # lands after the rename, before run_sweep returns

    monkeypatch.setattr(wf, "write_calibration", interrupted_after)
    with pytest.raises(SweepAbortedError) as exc:
        run_sweep(
            SweepRequest(
                urdf,
                "sim:lite",
                out,
                report=rep,
            ),
            open_source_fn=h.sim_opener(SimLite(43, noise_rad=0.0)),
        )
    assert str(exc.value) == f"sweep aborted by a second Ctrl-C after writing {out} and {rep} (complete)"
    assert read_calibration(out).calibration.joint_names == tuple(h.names)
    # without a report, an interrupt before the calibration is written leaves nothing
    monkeypatch.setattr(wf, "write_calibration", lambda *a, **k: _two_ctrl_c())
    out2 = tmp_path / "other.yaml"
    with pytest.raises(SweepAbortedError, match=r"^sweep aborted by a second Ctrl-C; nothing was written$"):
        run_sweep(
            SweepRequest(
                urdf,
                "sim:lite",
                out2,
            ),
            open_source_fn=h.sim_opener(SimLite(44, noise_rad=0.0)),
        )
    assert not out2.exists()


@pytest.mark.slow
def test_nan_positions_are_skipped_alike_in_csv_and_rosbag(urdf: Path, tmp_path: Path, h: Any) -> None:
    # NaN = no reading of that joint in that sample (legal in a JointState): both replays skip and count it
    sim = SimLite(17, noise_rad=0.0)
    opener, made = h.recording_opener(sim)
    live = run_sweep(SweepRequest(urdf, "sim:lite", tmp_path / "live.yaml"), open_source_fn=opener)
    rec = made[0]
    t = np.array([s.t_s for s in rec.samples])
    d = np.array([h.dirs[n] for n in h.names], dtype=float)
    ident = np.vstack([s.position_rad for s in rec.samples]) * d
    el = h.names.index("left_elbow_pitch")
    rows = np.arange(10, len(t), 37)  # interior samples, away from the dwell at the stops
    ident[rows, el] = np.nan
    ident[5, 0] = np.nan
    _write_csv(tmp_path / "nan.csv", h.names, t, ident)
    assert ",nan," in (tmp_path / "nan.csv").read_text()
    write_joint_states(tmp_path / "nan_bag", h.names, t, ident)
    want = {"left_shoulder_pitch": 1, "left_elbow_pitch": len(rows)}
    for i, src in enumerate((tmp_path / "nan.csv", tmp_path / "nan_bag")):
        res = run_sweep(SweepRequest(urdf, f"replay:{src}", tmp_path / f"n{i}.yaml"))
        assert dict(res.missing_samples) == want, src
        assert res.samples == len(t)
        for name, off in live.result.offsets().items():
            assert res.result[name].homing_offset == pytest.approx(off, abs=1e-9), (src, name)
    assert live.missing_samples == {}


def test_infinite_positions_are_refused_alike_in_csv_and_rosbag(urdf: Path, tmp_path: Path, h: Any) -> None:
    from robocal.errors import FileFormatError

    t = np.array([0.0, 0.01])
    s = np.zeros((2, len(h.names)))
    s[1, 3] = np.inf
    _write_csv(tmp_path / "inf.csv", h.names, t, s)
    write_joint_states(tmp_path / "inf_bag", h.names, t, s, plugin="sqlite3")
    with pytest.raises(FileFormatError, match=r"line 3: left_elbow_pitch is not finite"):
        run_sweep(SweepRequest(urdf, f"replay:{tmp_path / 'inf.csv'}", tmp_path / "a.yaml"))
    with pytest.raises(FileFormatError, match=r"joint left_elbow_pitch is inf at t = 1\.01.* not finite"):
        run_sweep(SweepRequest(urdf, f"replay:{tmp_path / 'inf_bag'}", tmp_path / "b.yaml"))
    assert not (tmp_path / "a.yaml").exists() and not (tmp_path / "b.yaml").exists()
