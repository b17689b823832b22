"""Issue 26: ``sweep --auto`` (Robstride, the simulated Lite on python-can's virtual bus) under SIGTERM, SIGHUP and
SIGQUIT mid-search: the motion guard makes every motor limp (reset mode, no torque at all) and the files are not
touched. The signal is real (sent to this process while the joint is driven) and arrives with the default
disposition a fresh process has (before the guard, SIGTERM killed robocal on the spot); the oracle is the
simulated motors' mode and torque limit."""

from __future__ import annotations

import os
import signal
from pathlib import Path
from typing import Any

import pytest

pytest.importorskip("can")

from robocal.backends.sim.lite import lite_urdf_text
from robocal.core.stop_search import StopSample
from robocal.errors import SignalInterrupt
from robocal.workflows.autocal.sim import SimAutoLite, sim_opener
from robocal.workflows.autocal.sweep import SweepAutoRequest, run_sweep_auto

pytestmark = pytest.mark.timeout(600)

PRIOR = "left_wrist_roll:\n  id: 16\n  direction: -1\n  homing_offset: 0.25\n"


class _SignalAt:
    """A live view that sends this process ``signum`` at the ``nth`` reading of the first search's approach."""

    def __init__(self, signum: int, nth: int) -> None:
        self.signum, self.nth, self.count = signum, nth, 0

    def joint_start(self, name: str, cap_nm: float, speed_rad_s: float) -> None:
        pass

    def sample(self, name: str, phase: str, side: str, sample: StopSample) -> None:
        if phase == "approach":
            self.count += 1
            if self.count == self.nth:
                os.kill(os.getpid(), self.signum)

    def joint_done(self, outcome: Any) -> None:
        pass


@pytest.mark.parametrize("signum", [signal.SIGTERM, signal.SIGHUP, signal.SIGQUIT])
def test_a_signal_mid_search_leaves_every_motor_limp_and_the_files_unchanged(
    tmp_path: Path, signum: int
) -> None:
    urdf = tmp_path / "lite.urdf"
    urdf.write_text(lite_urdf_text())
    out = tmp_path / "cal.yaml"
    out.write_text(PRIOR)
    holder: list[SimAutoLite] = []
    previous = signal.signal(signum, signal.SIG_DFL)  # as a fresh robocal process has it
    try:
        with pytest.raises(SignalInterrupt) as info:
            run_sweep_auto(
                SweepAutoRequest(
                    urdf, "sim:lite?seed=2", out, robot="bhl_arms", joints=["left_wrist_roll", "left_wrist_pitch"],
                    report=tmp_path / "r.json",
                ),
                view=_SignalAt(signum, 30), open_drivers_fn=sim_opener(holder),
            )  # fmt: skip
        assert signal.getsignal(signum) is signal.SIG_DFL  # the guard put the disposition back
    finally:
        signal.signal(signum, previous)
    assert info.value.signum == signum and info.value.exit_code == 128 + signum
    assert info.value.args == ()  # every motor answered the torque-off
    sim = holder[0]
    assert all(m.mode == 0 for m in sim.motors.values())  # reset mode on every motor
    assert all(m.drive().tau_max_nm == 0.0 for m in sim.motors.values())
    assert out.read_text() == PRIOR and not (tmp_path / "r.json").exists()
