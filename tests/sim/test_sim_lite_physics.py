"""The standalone ``robocal sim lite`` has the joint physics of ``sim:lite`` (issue 26): ``robocal sweep --auto`` in
another process finds the hard stops of a joint, over CAN (python-can's udp_multicast in a private network
namespace), and leaves the motor limp with its CAN timeout disarmed.

Judged by the simulator's state (its control socket): the offset robocal found equals the motor's true homing
offset (the reading minus the joint position seen through the motor's direction), the span the profile's.
Before, the standalone Lite had no plant: every ``sweep --auto`` against it ended ``span_mismatch`` (span 0°).
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from robocal.backends.sim.lite import LITE_JOINTS

from .test_sim_lite_cli import NETNS_SETUP, _netns_available

pytestmark = pytest.mark.timeout(600)

JOINT = "left_wrist_roll"


@pytest.mark.slow
def test_sweep_auto_finds_the_stops_of_the_standalone_lite(tmp_path: Path) -> None:
    reason = _netns_available()
    if reason:
        pytest.skip(reason)
    pytest.importorskip("msgpack", reason="python-can's udp_multicast needs msgpack")
    driver = Path(__file__).with_name("lite_physics_netns_driver.py")
    r = subprocess.run(
        ["unshare", "--net", "sh", "-c", f'{NETNS_SETUP} && exec "$0" "$@"', sys.executable, str(driver),
         str(tmp_path), JOINT],
        capture_output=True, text=True, timeout=550,
    )  # fmt: skip
    assert r.returncode == 0, r.stderr[-3000:]
    out = json.loads(r.stdout.strip().splitlines()[-1])
    assert out["code"] in (0, 1), out["err"]  # 1: a warning (the power-on wrap point inside the travel)
    auto = out["report"]["auto"]["joints"][JOINT]
    assert auto["code"] == "ok", auto
    assert auto["span_deg"] == pytest.approx(auto["expected_span_deg"], abs=0.5)
    after = out["after"]
    direction = next(j.direction for j in LITE_JOINTS if j.name == JOINT)
    truth = after["reading"] - direction * after["position"]
    assert out["report"]["joints"][JOINT]["homing_offset"] == pytest.approx(truth, abs=2e-3)
    assert after["enabled"] is False and after["torque"] is False  # limp at the end
    assert after["can_timeout"] == 0  # the CAN timeout disarmed again
    assert after["watchdog_trips"] == []
    assert (tmp_path / "cal.yaml").exists()


@pytest.mark.parametrize("upper_rad", [0.5, 1.2])
def test_a_lite_joint_pressed_at_its_search_torque_rests_on_its_stop(upper_rad: float) -> None:
    """The plant both Lites share: the search torque moves the joint and the 600 N·m/rad stop holds it there."""
    from robocal.backends.sim.lite_physics import lite_plant_params
    from robocal.backends.sim.physics import Drive, JointPlant

    cap_nm = 2.0
    params = lite_plant_params("rs-05", -0.5, upper_rad, cap_nm)
    assert (params.inertia_kgm2, params.stiction_nm, params.counts_per_rev) == (0.005, 0.1, 16384)
    plant = JointPlant(params, q0_rad=0.0)
    plant.run_until(3.0, Drive(tau_ff_nm=cap_nm, tau_max_nm=cap_nm))
    # the stop spring balances the push less friction: q = upper + (cap − coulomb)/600 at rest
    assert plant.read().q_rad == pytest.approx(upper_rad + (cap_nm - params.coulomb_nm) / 600.0, abs=2e-3)
