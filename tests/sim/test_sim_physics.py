"""The 1-DOF joint plant behind the simulated motors: physics numbers, faults, determinism."""

from __future__ import annotations

import math

import pytest

from robocal.backends.sim.physics import (
    Drive,
    JointPlant,
    OverloadLatch,
    PlantParams,
    Scenario,
    SimClock,
    make_plant,
)
from robocal.errors import UsageError

EXACT = {"counts_per_rev": 0, "noise_rad": 0.0}


def push(tau: float) -> Drive:
    return Drive(tau_ff_nm=tau, tau_max_nm=abs(tau))


@pytest.mark.parametrize("k", [10.0, 15.0, 100.0, 600.0, 1000.0])
@pytest.mark.parametrize("inertia", [1e-4, 0.005, 0.05])
def test_stop_deflection_is_push_over_stiffness_and_integration_is_stable(k: float, inertia: float) -> None:
    p = PlantParams(inertia_kgm2=inertia, stiffness_upper=k, stiction_nm=0.0, coulomb_nm=0.0, **EXACT)
    plant = JointPlant(p, q0_rad=0.9)
    plant.advance(3.0, push(1.5))
    # at rest in the stop: 1.5 N·m against the spring (viscous friction vanishes at rest)
    assert plant.q_rad == pytest.approx(1.0 + 1.5 / k, rel=0, abs=1e-6)
    assert abs(plant.v_rad_s) < 1e-6
    assert plant.tau_wall_nm == pytest.approx(-1.5, abs=1e-3)


def test_stiction_holds_below_breakaway_and_running_friction_is_lower() -> None:
    p = PlantParams(stiction_nm=1.2, coulomb_nm=0.6, viscous_nms_rad=0.0, stop_upper_rad=None, **EXACT)
    plant = JointPlant(p, q0_rad=0.0)
    plant.advance(2.0, push(1.19))
    assert plant.q_rad == 0.0 and plant.v_rad_s == 0.0
    plant.advance(0.1, push(1.21))
    # broke away: accelerates at (1.21 - 0.6)/J
    assert plant.v_rad_s == pytest.approx((1.21 - 0.6) / p.inertia_kgm2 * 0.1, rel=0.01)
    # once moving, 0.7 N·m (below breakaway, above running friction) keeps it moving
    v = plant.v_rad_s
    plant.advance(0.1, push(0.7))
    assert plant.v_rad_s == pytest.approx(v + 0.1 / p.inertia_kgm2 * 0.1, rel=0.01)


def test_pd_contact_torque_is_kp_lag_clipped_at_the_limit() -> None:
    p = PlantParams(stiffness_upper=600.0, stiction_nm=0.0, coulomb_nm=0.0, **EXACT)
    plant = JointPlant(p, q0_rad=0.95)
    plant.advance(2.0, Drive(kp_nm_rad=10.0, kd_nms_rad=0.2, q_ref_rad=1.05, tau_max_nm=1.5))
    lag = 1.05 - plant.q_rad
    assert plant.tau_motor_nm == pytest.approx(10.0 * lag, rel=1e-4)  # below the limit: kp·lag
    assert plant.q_rad == pytest.approx(1.0 + plant.tau_motor_nm / 600.0, abs=1e-6)
    plant.advance(2.0, Drive(kp_nm_rad=10.0, kd_nms_rad=0.2, q_ref_rad=1.5, tau_max_nm=1.5))
    assert plant.tau_motor_nm == 1.5  # kp·lag = 5 N·m, clipped
    assert plant.q_rad == pytest.approx(1.0 + 1.5 / 600.0, abs=1e-6)


def test_gravity_equilibrium_and_backlash_shift_the_stop_reading() -> None:
    g = PlantParams(gravity_nm=0.5, stiction_nm=0.0, coulomb_nm=0.0, viscous_nms_rad=0.05, **EXACT)
    plant = JointPlant(g, q0_rad=0.6)
    plant.advance(30.0, push(0.25))  # 0.25 = 0.5·sin(q) → q = 30°
    assert plant.q_rad == pytest.approx(math.radians(30.0), abs=1e-4)
    b = math.radians(1.0)
    lash = PlantParams(
        backlash_rad=b, stiction_nm=0.0, coulomb_nm=0.0, stiffness_lower=1e3, stiffness_upper=1e3
    )
    plant = JointPlant(replace_exact(lash), q0_rad=0.0)
    plant.advance(3.0, push(1.0))
    up = plant.q_rad
    plant.advance(3.0, push(-1.0))
    down = plant.q_rad
    # the motor-side encoder sees the span grow by the play; the link-side encoder does not
    assert up - down == pytest.approx(2.0 + b + 2 * 1.0 / 1e3, abs=1e-6)
    assert plant.link_rad == pytest.approx(-1.0 - 1.0 / 1e3, abs=1e-6)


def replace_exact(p: PlantParams) -> PlantParams:
    from dataclasses import replace

    return replace(p, **EXACT)


def test_encoder_quantisation_and_seeded_noise() -> None:
    p = PlantParams(counts_per_rev=4096, noise_rad=0.002)
    a = [JointPlant(p, seed=7, q0_rad=0.1234).read().q_rad for _ in range(3)]
    plant = JointPlant(p, seed=7, q0_rad=0.1234)
    b = [plant.read().q_rad for _ in range(50)]
    assert a == [b[0]] * 3  # same seed, same first draw
    step = 2 * math.pi / 4096
    assert all(abs(x / step - round(x / step)) < 1e-9 for x in b)
    assert len(set(b)) > 3 and all(abs(x - 0.1234) < 0.01 for x in b)
    quiet = JointPlant(PlantParams(counts_per_rev=4096), q0_rad=0.1234).read().q_rad
    assert quiet == round(0.1234 / step) * step


def test_overload_latch_after_protection_time_and_clear() -> None:
    latch = OverloadLatch(threshold_nm=1.0, protection_s=0.5)
    plant = JointPlant(PlantParams(**EXACT), q0_rad=0.99, overload=latch)
    plant.advance(0.49, push(1.2))
    assert not plant.read().overload
    plant.advance(0.02, push(1.2))
    r = plant.read()
    assert r.overload and r.tau_nm == 0.0  # torque cut (latched limit 0)
    plant.advance(1.0, push(1.2))
    assert plant.read().tau_nm == 0.0 and plant.read().overload
    plant.clear_overload()
    plant.advance(0.01, push(1.2))
    assert not plant.read().overload and plant.read().tau_nm == 1.2


def test_silent_at_stop_and_missing_stop() -> None:
    sc = Scenario(silent_at_stop=True, missing_stop="lower")
    plant = make_plant(sc, PlantParams(**EXACT), search_torque_nm=1.0)
    plant.advance(2.0, push(1.0))
    assert not plant.read().answers
    plant.advance(0.5, push(-1.0))
    assert plant.read().answers
    plant.advance(5.0, push(-1.0))
    assert plant.q_rad < -10.0  # nothing stops it below


def test_scenarios_obstacle_snag_stiction_soft() -> None:
    nominal = PlantParams(stop_lower_rad=-1.0, stop_upper_rad=1.0, **EXACT)
    ob = make_plant(Scenario(obstacle=True), nominal, search_torque_nm=1.0)
    ob.advance(3.0, push(1.0))
    assert ob.q_rad == pytest.approx(0.5 + 1.0 / 300.0, abs=0.02 / 300 + 1e-6)
    snag = make_plant(Scenario(cable_snag=True), nominal, search_torque_nm=1.0)
    snag.advance(5.0, push(1.0))
    # held where the cable pulls back the whole push: 0.2 + 20 % of the travel, well before the stop
    assert snag.q_rad == pytest.approx(0.6, abs=0.005) and abs(snag.v_rad_s) < 1e-6
    soft = Scenario(soft_stop=True).params(nominal, search_torque_nm=1.0)
    assert (soft.stiffness_lower, soft.stiffness_upper) == (15.0, 15.0)
    st = make_plant(Scenario(stiction_ratio=0.8), nominal, search_torque_nm=1.0)
    st.advance(1.0, push(0.79))
    assert st.q_rad == 0.0
    asym = Scenario(asymmetric_stops=True).params(nominal, search_torque_nm=1.0, seed=5)
    assert asym == Scenario(asymmetric_stops=True).params(nominal, search_torque_nm=1.0, seed=5)
    assert asym.stop_lower_rad != -1.0 and abs(asym.stop_lower_rad + 1.0) <= math.radians(5.0)  # type: ignore[operator]
    assert asym.stiffness_upper < asym.stiffness_lower


def test_seeded_runs_are_identical() -> None:
    def run(seed: int) -> list[float]:
        sc = Scenario(asymmetric_stops=True, gravity_nm=0.3, backlash_rad=0.01)
        plant = make_plant(sc, PlantParams(noise_rad=1e-3), search_torque_nm=1.5, seed=seed)
        out = []
        for i in range(200):
            plant.advance(0.01, Drive(kp_nm_rad=10, kd_nms_rad=0.2, q_ref_rad=0.01 * i, tau_max_nm=1.5))
            out.append(plant.read().q_rad)
        return out

    assert run(3) == run(3)
    assert run(3) != run(4)


def test_bad_parameters_and_clock() -> None:
    with pytest.raises(UsageError, match="stiction_nm"):
        PlantParams(stiction_nm=0.01, coulomb_nm=0.02)
    with pytest.raises(UsageError, match="lower < upper"):
        PlantParams(stop_lower_rad=1.0, stop_upper_rad=0.0)
    with pytest.raises(UsageError, match="inertia_kgm2"):
        PlantParams(inertia_kgm2=float("nan"))
    with pytest.raises(UsageError, match="missing_stop"):
        Scenario(missing_stop="left")  # type: ignore[arg-type]
    clock = SimClock()
    clock.sleep(0.25)
    assert clock.advance(0.5) == 0.75
    with pytest.raises(UsageError):
        clock.advance(-1.0)
