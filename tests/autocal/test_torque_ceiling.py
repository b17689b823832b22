"""Torque caps come from the motor model's rating; no profile or caller can push past the model's hard ceiling.

Issue 26 item 3. The model table is pinned here (rated and stall torque per model, with a source); every shipped
profile and hypothesis-generated profiles are either refused when read or give caps within the ceiling; and what
the drivers put on the wire (Feetech ``Torque_Limit``, Dynamixel ``Goal_Current`` / ``Goal_PWM``, Robstride
``limit_torque`` and the MIT feed-forward torque) stays within the ceiling whatever cap they are asked for.
"""

from __future__ import annotations

import copy
import math
from importlib import resources
from typing import Any

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from robocal.backends.robstride.joint_driver import LIMIT_TORQUE, MAX_LAG_RAD, RobstrideJointDriver
from robocal.backends.servo_ratings import PWM_FULL, RATINGS
from robocal.core.motor_models import HARD_MAX_TORQUE_FRACTION, MOTOR_MODELS, find_motor_model
from robocal.core.profile_auto import AutoSection
from robocal.core.stop_search import Command
from robocal.errors import FileFormatError
from robocal.formats.profiles import load_profile, parse_profile
from robocal.workflows.autocal.model import JointCaps, joint_driver_class

PINNED = {  # model: (rated N·m, stall/peak N·m, family)
    "RS00": (5.0, 14.0, "robstride"),
    "RS01": (6.0, 17.0, "robstride"),
    "RS02": (6.0, 17.0, "robstride"),
    "RS03": (20.0, 60.0, "robstride"),
    "RS04": (40.0, 120.0, "robstride"),
    "RS05": (1.6, 5.5, "robstride"),
    "RS06": (11.0, 36.0, "robstride"),
    "STS3215": (1.91, 1.91, "feetech"),  # 19.5 kg·cm at 7.4 V
    "STS3215-12V": (2.942, 2.942, "feetech"),  # 30 kg·cm at 12 V
    "XL330-M077": (0.228, 0.228, "dynamixel"),
    "XL330-M288": (0.52, 0.52, "dynamixel"),
    "XL430-W250": (1.5, 1.5, "dynamixel"),
    "XM430-W350": (4.1, 4.1, "dynamixel"),
    "DM4310": (3.0, 7.0, "damiao"),
    "DM4340": (9.0, 27.0, "damiao"),
    "DM8009": (20.0, 40.0, "damiao"),
}
SHIPPED = sorted(
    p.name.removesuffix(".yaml") for p in resources.files("robocal.data.profiles").iterdir() if p.name.endswith(".yaml")
)
SHIPPED_AUTO = [n for n in SHIPPED if load_profile(n).auto is not None]


@pytest.mark.parametrize("name", sorted(PINNED))
def test_model_table_pins_the_datasheet_numbers_with_their_source(name: str) -> None:
    rated, stall, family = PINNED[name]
    m = find_motor_model(name)
    assert m is not None and (m.rated_nm, m.stall_nm, m.family) == (rated, stall, family)
    assert m.ceiling_nm == pytest.approx(HARD_MAX_TORQUE_FRACTION * rated)
    assert len(m.source) > 20 and ("manual" in m.source.lower() or "datasheet" in m.source.lower()
                                   or "e-manual" in m.source.lower())


def test_lookup_takes_the_names_profiles_and_buses_use() -> None:
    assert find_motor_model("rs-05") is find_motor_model("RS05")
    assert find_motor_model("sts3215-c018") is find_motor_model("STS3215-12V")
    assert find_motor_model("xl330-m288") is find_motor_model("XL330-M288")
    assert find_motor_model("rs-99") is None and find_motor_model(None) is None
    assert HARD_MAX_TORQUE_FRACTION == 0.5
    for m in MOTOR_MODELS:  # servo ratings come from the one table
        if m.bus_model in RATINGS and m.name != "STS3215-12V":
            assert RATINGS[m.bus_model].stall_torque_nm == m.stall_nm


def test_the_shipped_profiles_with_a_search() -> None:
    assert SHIPPED_AUTO == [
        "bhl_arms", "koch_follower", "openarm_follower_left", "openarm_follower_right", "openarm_leader_left",
        "openarm_leader_right", "so101_follower",
    ]


@pytest.mark.parametrize("name", SHIPPED_AUTO)
def test_every_shipped_profile_caps_within_the_models_ceiling(name: str) -> None:
    profile = load_profile(name)
    assert profile.auto is not None
    for j in profile.auto.searched_joints:
        model = find_motor_model(j.motor)
        assert model is not None, j.name
        assert j.rated_nm <= model.rated_nm
        assert 0 < j.torque_cap_nm <= model.ceiling_nm + 1e-12, j.name
        assert j.cap_percent_of_model == pytest.approx(100 * j.torque_cap_nm / model.rated_nm)


def test_a_profile_may_name_the_12v_variant_and_lower_a_rating() -> None:
    doc = {
        "format": "robocal-robot-profile",
        "version": 2,
        "name": "t",
        "joints": [{"name": "a", "model": "sts3215"}, {"name": "b", "model": "rs-05"}],
        "auto_calibration": {
            "joints": [{"name": "a", "motor": "sts3215-12v"}, {"name": "b", "rated_nm": 1.0}],
        },
    }
    a, b = parse_profile(doc, "t.yaml").auto.joints  # type: ignore[union-attr]
    assert (a.motor, a.rated_nm, a.torque_cap_nm) == ("STS3215-12V", 2.942, pytest.approx(0.25 * 2.942))
    assert (b.motor, b.rated_nm, b.torque_cap_nm) == ("RS05", 1.0, 0.25)
    assert b.cap_percent_of_model == pytest.approx(100 * 0.25 / 1.6)
    caps = JointCaps([a, b])
    assert dict(caps) == {"a": pytest.approx(0.7355), "b": 0.25}
    assert caps.models == {"a": ("STS3215-12V", 2.942), "b": ("RS05", 1.6)}


# --------------------------------------------------------------------------------- hypothesis profiles
BUS_MODELS = ["rs-00", "rs-02", "rs-04", "rs-05", "rs-06", "sts3215", "xl330-m288", "xl430-w250", "xm430-w350",
              "mystery-9"]
numbers = st.one_of(
    st.floats(min_value=-10, max_value=200, allow_nan=False),
    st.sampled_from([0.0, 1e-9, 1e9, 1e30, 40.0, 5.5, 120.0]),
    st.integers(min_value=-5, max_value=10**6),
)


@st.composite
def profiles(draw: Any) -> dict[str, Any]:
    n = draw(st.integers(min_value=1, max_value=4))
    models = [draw(st.sampled_from(BUS_MODELS)) for _ in range(n)]
    rows = []
    for i, _m in enumerate(models):
        row: dict[str, Any] = {"name": f"j{i}", "stops": "both"}
        if draw(st.booleans()):
            row["rated_nm"] = draw(numbers)
        if draw(st.booleans()):
            row["torque_fraction"] = draw(st.floats(min_value=0.01, max_value=0.6))
        if draw(st.booleans()):
            row["motor"] = draw(st.sampled_from(["sts3215-12v", "rs-04", "xm430-w350", "nope"]))
        rows.append(row)
    section: dict[str, Any] = {"joints": rows}
    if draw(st.booleans()):
        section["max_torque_fraction"] = draw(st.floats(min_value=0.01, max_value=0.7))
    return {
        "format": "robocal-robot-profile",
        "version": 2,
        "name": "h",
        "joints": [{"name": f"j{i}", "model": m} for i, m in enumerate(models)],
        "auto_calibration": section,
    }


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(profiles())
def test_generated_profiles_are_refused_or_capped_within_the_ceiling(doc: dict[str, Any]) -> None:
    try:
        profile = parse_profile(copy.deepcopy(doc), "h.yaml")
    except FileFormatError as exc:
        assert str(exc).startswith("profile h.yaml: auto_calibration")
        return
    assert profile.auto is not None
    for j in profile.auto.searched_joints:
        model = find_motor_model(j.motor)
        assert model is not None
        assert j.torque_cap_nm <= model.ceiling_nm + 1e-12
        _check_driver_writes(j.motor or "", j.rated_nm, j.torque_cap_nm)


# ------------------------------------------------------------------------- what the drivers put on the wire
class _ServoBus:
    """Records every register a servo driver writes; the motor reads still at mid-turn."""

    def __init__(self, model: str) -> None:
        self.motors = {1: model}
        self.writes: list[tuple[str, int]] = []

    def resolution(self, motor_id: int) -> int:
        return 4096

    def sync_write(self, register: str, values: dict[int, int]) -> None:
        self.writes.extend((register, v) for v in values.values())

    def write(self, register: str, motor_id: int, value: int) -> None:
        self.writes.append((register, value))

    def sync_read_block(self, registers: Any, ids: Any) -> dict[int, dict[str, int]]:
        return {1: {r: (2048 if r == "Present_Position" else 0) for r in registers}}

    def sync_read(self, register: str, ids: Any) -> dict[int, int]:
        return {1: 0}

    def read(self, register: str, motor_id: int) -> int:
        return 0


class _CanBus:
    """Records the MIT frames and parameter writes of a Robstride driver."""

    def __init__(self, model: str) -> None:
        self.motors = {"j": type("Spec", (), {"model": model})()}
        self.mit: list[float] = []
        self.params: dict[int, float] = {LIMIT_TORQUE: 1e3}
        self.timeout_s = 0.0

    def _fb(self) -> Any:
        return type("Fb", (), {"faults": 0, "position_rad": 0.0, "velocity_rad_s": 0.0, "torque_nm": 0.0})()

    def read_param(self, name: str, index: int) -> float:
        return self.params[index]

    def write_param(self, name: str, index: int, value: float) -> Any:
        self.params[index] = value
        return self._fb()

    def enable(self, name: str) -> Any:
        return self._fb()

    def stop(self, name: str, clear_faults: bool = False) -> Any:
        return self._fb()

    def mit_command(self, name: str, p: float, v: float, kp: float, kd: float, t: float) -> Any:
        self.mit.append(t)
        return self._fb()


class _Clock:
    def now(self) -> float:
        return 0.0

    def sleep(self, s: float) -> None:
        pass


ASKS = (1e9, 1e3, 40.0, 1.0, 0.05)


def _commands(asked_nm: float) -> list[Command]:
    return [
        Command("drive", 0.5, 0.1, asked_nm),
        Command("push", 3.0, 0.0, asked_nm),
        Command("push", -3.0, 0.0, asked_nm),
        Command("hold", 0.2, 0.0, asked_nm),
        Command("reread", 0.2),
        Command("drive", 0.1, 0.0, 0.0),  # 0: the driver's own cap
    ]


def _check_driver_writes(motor: str, rated_nm: float, cap_nm: float) -> None:
    model = find_motor_model(motor)
    assert model is not None
    if model.family == "robstride":
        bus = _CanBus(model.bus_model)
        drv = RobstrideJointDriver(bus, "j", 1, cap_nm, MAX_LAG_RAD, _Clock())  # type: ignore[arg-type]
        for asked in ASKS:
            for cmd in _commands(asked):
                drv.execute(cmd)
            assert bus.params[LIMIT_TORQUE] <= model.ceiling_nm + 1e-9
            assert max(abs(t) for t in bus.mit) <= model.ceiling_nm + 1e-9
        return
    bus2 = _ServoBus(model.bus_model)
    cls = joint_driver_class(model.family)
    drv2 = cls(bus2, "j", 1, rated_nm=rated_nm, cap_nm=cap_nm, clock=_Clock(), motor=model.name)  # type: ignore[arg-type]
    for asked in ASKS:
        for cmd in _commands(asked):
            drv2.send(cmd)
    rating = RATINGS[model.bus_model]
    for reg, value in bus2.writes:
        if reg == "Torque_Limit":
            assert value * model.stall_nm / 1000 <= model.ceiling_nm + 1e-9
        elif reg == "Goal_Current":
            assert value * rating.current_unit_a / rating.stall_current_a * model.stall_nm <= model.ceiling_nm + 1e-9
        elif reg == "Goal_PWM":
            assert value / PWM_FULL * model.stall_nm <= model.ceiling_nm + 1e-9
    assert any(r in ("Torque_Limit", "Goal_Current", "Goal_PWM") for r, _ in bus2.writes)


@pytest.mark.parametrize("motor", [m.name for m in MOTOR_MODELS if m.bus_model in RATINGS or m.family == "robstride"])
def test_no_driver_writes_a_torque_above_the_ceiling_whatever_it_is_asked(motor: str) -> None:
    model = find_motor_model(motor)
    assert model is not None
    _check_driver_writes(motor, 1e9, 1e9)  # a caller that claims a huge rating and cap
    _check_driver_writes(motor, model.rated_nm, model.ceiling_nm)


def test_prompt_states_the_cap_in_nm_and_percent_of_the_rating() -> None:
    from robocal.cli._autocal import cap_text

    section = load_profile("bhl_arms").auto
    assert isinstance(section, AutoSection)
    caps = JointCaps(section.searched_joints)
    assert cap_text("left_wrist_roll", caps) == "cap 0.40 N·m = 25 % of the RS05's 1.6 N·m rating"
    assert cap_text("left_shoulder_pitch", caps) == "cap 1.80 N·m = 30 % of the RS02's 6 N·m rating"
    assert cap_text("x", {"x": 0.5}) == "cap 0.50 N·m"
    assert math.isclose(caps["left_elbow_pitch"], 1.25)


# ---------------------------------------------------------------- the simulators' own torque, end to end
@pytest.mark.slow
@pytest.mark.timeout(600)
@pytest.mark.parametrize("robot", ["so101_follower", "koch_follower"])
def test_a_shipped_arm_search_never_pushes_past_the_ceiling_at_the_simulated_motor(robot: str) -> None:
    from robocal.workflows.lerobot import robot_spec
    from robocal.workflows.lerobot.auto import AutoCalibrationRequest, auto_calibrate, auto_section
    from robocal.workflows.lerobot.auto_sim import open_auto_arm

    spec = robot_spec(robot)
    section = auto_section(robot)
    joints = [j.name for j in section.searched_joints][:2]
    with open_auto_arm(spec, "sim?seed=3&transport=inproc", section) as arm:
        auto_calibrate(
            arm.bus,
            AutoCalibrationRequest(
                spec,
                section,
                joints=joints,
                path=None,
            ),
            clock=arm.clock,
        )
        assert arm.plants is not None
        for name in joints:
            j = section.joint(name)
            assert j is not None
            model = find_motor_model(j.motor)
            assert model is not None
            peak = arm.plants[name].peak_tau_motor_nm
            assert 0.5 * j.torque_cap_nm < peak <= min(1.02 * j.torque_cap_nm, model.ceiling_nm), name


@pytest.mark.slow
@pytest.mark.timeout(600)
def test_the_lite_search_never_pushes_past_the_ceiling_at_the_simulated_motor(tmp_path: Any) -> None:
    pytest.importorskip("can")
    from robocal.backends.sim.lite import lite_urdf_text
    from robocal.workflows.autocal.sim import SimAutoLite, sim_opener
    from robocal.workflows.autocal.sweep import SweepAutoRequest, run_sweep_auto

    urdf = tmp_path / "lite.urdf"
    urdf.write_text(lite_urdf_text())
    holder: list[SimAutoLite] = []
    joints = ["left_wrist_roll", "left_elbow_pitch"]
    run_sweep_auto(
        SweepAutoRequest(
            urdf,
            "sim:lite?seed=2",
            tmp_path / "c.yaml",
            robot="bhl_arms",
            joints=joints,
        ),
        open_drivers_fn=sim_opener(holder),
    )
    section = load_profile("bhl_arms").auto
    assert section is not None
    for name in joints:
        j = section.joint(name)
        model = find_motor_model(j.motor if j else None)
        assert j is not None and model is not None
        peak = holder[0].motors[name].plant.peak_tau_motor_nm
        # limit_torque is 1.05·cap (within the ceiling): the motor never pushes harder
        assert 0.5 * j.torque_cap_nm < peak <= min(1.05 * j.torque_cap_nm, model.ceiling_nm) + 1e-9, name


@pytest.mark.parametrize("rated", [5e-324, 1e-9, 0.0009])
def test_a_rating_too_small_to_give_a_cap_is_refused(rated: float) -> None:
    """A denormal ``rated_nm`` made the cap 0.0 N·m (found by hypothesis): the profile is refused instead."""
    doc = {
        "format": "robocal-robot-profile",
        "version": 2,
        "name": "h",
        "joints": [{"name": "j0", "model": "sts3215"}],
        "auto_calibration": {"joints": [{"name": "j0", "stops": "both", "rated_nm": rated}]},
    }
    with pytest.raises(FileFormatError, match=r"rated_nm must be a positive number \(N·m\) of at least 0.001"):
        parse_profile(doc, "h.yaml")
