"""A Robstride motor silent at its stop, over the wire: each lost reply lasts the hardware's reply timeout on the
simulated clock, so the search's reply bound ends it (no_reply, limp, nothing written) instead of re-reading forever."""

from __future__ import annotations

import time
from pathlib import Path

import pytest

pytest.importorskip("can")

from robocal.backends.sim.lite import lite_urdf_text
from robocal.workflows.autocal.job import AutoCalFailedError
from robocal.workflows.autocal.sim import SimAutoLite, sim_opener
from robocal.workflows.autocal.sweep import SweepAutoRequest, run_sweep_auto


def test_silent_motor_at_the_stop_fails_with_no_reply_in_bounded_time(tmp_path: Path) -> None:
    urdf = tmp_path / "lite.urdf"
    urdf.write_text(lite_urdf_text())
    out = tmp_path / "cal.yaml"
    holder: list[SimAutoLite] = []
    t0 = time.monotonic()
    with pytest.raises(
        AutoCalFailedError, match=r"left_wrist_roll: no_reply \(lower stop: no reply for 0\.50 s\)"
    ) as info:
        run_sweep_auto(
            SweepAutoRequest(
                urdf,
                "sim:lite?seed=4&silent=left_wrist_roll",
                out,
                robot="bhl_arms",
                joints=["left_wrist_roll"],
            ),
            open_drivers_fn=sim_opener(holder),
        )
    assert time.monotonic() - t0 < 120  # was: a timed-out re-read did not move the simulated clock (minutes+)
    outcome = info.value.result["left_wrist_roll"]
    assert outcome.stops.code == "no_reply"
    assert outcome.time_s < 10.0  # simulated: the 0.5 s reply bound after contact, not an endless re-read
    assert not out.exists()
    assert all(m.mode == 0 for m in holder[0].motors.values())
