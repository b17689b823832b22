"""robocal.health.Monitor (issue 30 item 3): each flag on hand-made readings, with its joint, tick and value."""

from __future__ import annotations

import math
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from robocal.errors import UsageError
from robocal.health import FLAG_KINDS, HealthFlag, Monitor, MonitorConfig, monitor_config

DEG = math.pi / 180
DT = 0.01


def _monitor(speed: float = 3.0, **kw: object) -> Monitor:
    """Two joints a and b, stops ±1 rad, 3 rad/s, 50 rad/s², noise 0.003 rad."""
    args: dict[str, object] = {"noise_rad": 0.003}
    args.update(kw)
    return Monitor(monitor_config(["a", "b"], [-1.0, -1.0], [1.0, 1.0], speed, **args))  # type: ignore[arg-type]


def _feed(m: Monitor, a: list[float], b: float = 0.0, t0: float = 0.0) -> list[list[HealthFlag]]:
    """Joint a's readings ``a`` (b held at ``b``), one per tick of 10 ms; the flags of each tick."""
    return [list(m.update(t0 + k * DT, np.array([x, b]))) for k, x in enumerate(a)]


def test_facade_reexports_the_core_classes_and_imports_numpy_alone() -> None:
    from robocal.core.health import Monitor as CoreMonitor

    assert Monitor is CoreMonitor
    src = Path(__file__).resolve().parents[2] / "src"
    code = (
        "import sys, robocal.health, robocal.core.health.monitor\n"
        "print(sorted(m for m in ('typer', 'rich', 'scipy', 'pyarrow', 'lxml', 'can') if m in sys.modules))"
    )
    out = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, check=True, env={"PYTHONPATH": str(src)}
    )
    assert out.stdout.strip() == "[]"


def test_a_reading_past_a_stop_is_flagged_on_its_first_tick_and_once_per_excursion() -> None:
    m = _monitor(speed=10.0, max_accel_rad_s2=1e4)  # only the stops here
    limit = 1.0 + 2 * DEG
    path = [0.9, 0.95, 1.0, 1.02, 1.03, 1.04, 1.05, 1.04, 1.03, 1.0, 0.98, 1.01, 1.04]
    flags = _feed(m, path)
    hits = [(k, f.kind, f.joint) for k, fs in enumerate(flags) for f in fs]
    assert hits == [(5, "outside_stops", "a"), (12, "outside_stops", "a")]
    first = flags[5][0]
    assert first.value_rad == 1.04 and first.limit_rad == pytest.approx(limit)
    assert first.t_s == pytest.approx(5 * DT)
    assert first.message == "a: reading +59.59° is past its stop (+59.30° with the margin)"
    assert m.counts == {"outside_stops": 2, "step": 0, "wrong_branch": 0, "pinned": 0}


def test_a_reading_below_the_lower_stop_names_the_lower_bound() -> None:
    m = _monitor()
    m.update(0.0, np.array([0.0, -1.2]))
    (flag,) = m.history
    assert (flag.joint, flag.kind, flag.value_rad) == ("b", "outside_stops", -1.2)
    assert flag.limit_rad == pytest.approx(-1.0 - 2 * DEG)


def test_a_wrapping_joint_a_whole_turn_off_is_on_the_wrong_branch_not_outside() -> None:
    m = _monitor(wraps=[True, False])
    flags = m.update(0.0, np.array([0.5 + 2 * math.pi, 0.0]))
    assert [(f.joint, f.kind) for f in flags] == [("a", "wrong_branch")]
    assert flags[0].value_rad == pytest.approx(0.5 + 2 * math.pi)
    assert flags[0].limit_rad == pytest.approx(0.5)  # where the reading belongs
    # the same reading on a joint that cannot wrap is outside its stops
    m2 = _monitor()
    assert [f.kind for f in m2.update(0.0, np.array([0.5 + 2 * math.pi, 0.0]))] == ["outside_stops"]


def test_a_jump_of_one_turn_mid_motion_is_one_wrong_branch_flag() -> None:
    m = _monitor(wraps=True)
    path = [0.1 + 0.01 * k for k in range(10)]
    path += [path[-1] + 0.01 - 2 * math.pi]
    flags = _feed(m, path)
    assert [f.kind for f in flags[-1]] == ["wrong_branch"]
    assert sum(len(f) for f in flags) == 1


@pytest.mark.parametrize("jump_deg", [2.0, -2.0, 17.0])
def test_a_jump_while_moving_is_flagged_on_its_tick_with_its_size(jump_deg: float) -> None:
    m = _monitor()
    path = [0.2 + 0.01 * k for k in range(20)]  # 1 rad/s
    path += [p + jump_deg * DEG for p in [0.2 + 0.01 * k for k in range(20, 30)]]
    flags = _feed(m, path)
    hits = [(k, f.kind) for k, fs in enumerate(flags) for f in fs]
    assert hits == [(20, "step")]
    assert flags[20][0].value_rad == pytest.approx(jump_deg * DEG, abs=1e-9)
    # 50 rad/s² · (10.2 ms)² + 3 rad/s · 0.04 · 10 ms + 2 · 0.003 rad
    assert flags[20][0].limit_rad == pytest.approx(50 * 0.0102**2 + 3 * 0.04 * 0.01 + 0.006)


def test_a_jump_back_that_looks_like_a_stop_is_flagged_when_the_motion_goes_on() -> None:
    m = _monitor(speed=5.0)
    v = 0.04  # 4 rad/s: 2.3° a tick
    path = [-0.5 + v * k for k in range(20)]
    path += [p - 2 * DEG for p in [-0.5 + v * k for k in range(20, 30)]]  # the tick of the jump: +2.3° − 2°
    flags = _feed(m, path)
    hits = [(k, f.kind) for k, fs in enumerate(flags) for f in fs]
    assert hits == [(21, "step")]  # one tick late: 10 ms
    assert flags[21][0].value_rad == pytest.approx(-2 * DEG, abs=1e-9)


def test_a_joint_that_meets_a_stop_and_stays_is_not_flagged() -> None:
    m = _monitor()
    v = 0.03
    path = [0.2 + v * k for k in range(20)]
    path += [path[-1] + 0.5 * v] + [path[-1] + 0.5 * v] * 20
    assert sum(len(f) for f in _feed(m, path)) == 0


def test_a_start_from_rest_towards_a_far_command_is_explained_without_it_a_step() -> None:
    path = [0.0] * 10 + [0.03, 0.06, 0.09]
    cmd = np.array([0.5, 0.0])
    for with_cmd, expect in [(True, []), (False, [(10, "step")])]:
        m = _monitor()
        hits = []
        for k, x in enumerate(path):
            fs = m.update(k * DT, np.array([x, 0.0]), cmd if with_cmd else None)
            hits += [(k, f.kind) for f in fs]
        assert hits == expect


def test_the_hold_off_silences_a_second_step_for_half_a_second() -> None:
    m = _monitor()
    path = [0.0] * 10 + [0.05] * 30 + [0.10] * 30 + [0.15] * 10
    flags = _feed(m, path)
    hits = [k for k, fs in enumerate(flags) for f in fs]
    assert hits == [10, 70]  # the step at tick 40 is 0.3 s after the first: held off


def test_a_follower_pinned_while_its_leader_goes_on_is_flagged_once_after_the_pin_time() -> None:
    m = _monitor(leader_paired=[True, False])
    hits = []
    for k in range(100):
        t = k * DT
        leader = 0.5 + 0.004 * k  # 0.4 rad/s away
        follower = min(leader, 0.6)  # held at 0.6 rad from tick 25 on
        fs = m.update(t, np.array([follower, 0.0]), np.array([leader, 0.0]), np.array([leader, 0.0]))
        hits += [(k, f) for f in fs]
    assert len(hits) == 1
    k, flag = hits[0]
    assert (flag.joint, flag.kind) == ("a", "pinned")
    # far from the leader (> 5°) from tick 47 on; still since then; 0.3 s later, at the next 50 ms check
    assert 47 + 30 <= k <= 47 + 30 + 5
    assert flag.value_rad == pytest.approx(0.5 + 0.004 * k - 0.6)
    assert flag.message.startswith("a: follower pinned +")


def test_an_unpaired_joint_is_never_pinned() -> None:
    m = _monitor()
    for k in range(100):
        lead = np.array([0.5 + 0.004 * k, 0.0])
        assert m.update(k * DT, np.array([0.5, 0.0]), None, lead) == ()


def test_readings_of_nan_raise_nothing_and_the_checks_resume() -> None:
    m = _monitor()
    path = [0.1, 0.1, math.nan, 0.1, 0.1, 0.1, 0.5]
    flags = _feed(m, path)
    assert [(k, f.kind) for k, fs in enumerate(flags) for f in fs] == [(6, "step")]


def test_time_that_does_not_advance_is_refused() -> None:
    m = _monitor()
    m.update(1.0, np.zeros(2))
    with pytest.raises(UsageError, match=r"monitor: time 1.0 s is not after the previous tick's 1.0 s"):
        m.update(1.0, np.zeros(2))


def test_a_change_of_tick_period_does_not_flag_a_steady_motion() -> None:
    m = _monitor()
    t, x, hits = 0.0, 0.0, 0
    for k in range(200):
        dt = 0.01 if k < 100 else 0.02 if k < 150 else 0.005
        t += dt
        x += 2.0 * dt
        hits += len(m.update(t, np.array([math.sin(x) * 0.9, 0.0])))
    assert hits == 0


def test_reset_forgets_the_last_readings() -> None:
    m = _monitor()
    _feed(m, [0.0, 0.0, 0.0])
    m.reset()
    assert m.update(5.0, np.array([0.8, 0.0])) == ()
    assert m.ticks == 4


def test_history_keeps_the_newest_flags_up_to_its_size() -> None:
    cfg = monitor_config(["a"], [-1.0], [1.0], 3.0)
    m = Monitor(MonitorConfig(**{**cfg.__dict__, "history": 2}))
    for k in range(3):
        m.update(2 * k, np.array([2.0]))
        m.update(2 * k + 1, np.array([0.0]))
    assert [f.t_s for f in m.history] == [2, 4]
    assert m.counts["outside_stops"] == 3
    assert set(m.counts) == set(FLAG_KINDS)


def _refusal(kw: dict[str, object]) -> str:
    """The UsageError message of ``monitor_config`` for two joints with ``kw`` changed."""
    args: dict[str, object] = {
        "joint_names": ["a", "b"],
        "lower_rad": [-1.0, -1.0],
        "upper_rad": [1.0, 1.0],
        "max_speed_rad_s": 3.0,
    }
    args.update(kw)
    with pytest.raises(UsageError) as err:
        monitor_config(**args)  # type: ignore[arg-type]
    return str(err.value)


@pytest.mark.parametrize(
    ("kw", "message"),
    [
        ({"joint_names": ["a", "a"]}, "monitor: a joint name is given twice"),
        ({"lower_rad": [1.0, -1.0]}, "monitor: joint a: lower stop 1.0 rad is not below upper stop 1.0 rad"),
        ({"upper_rad": [1.0]}, "monitor: upper_rad has 1 values for 2 joints"),
        ({"max_speed_rad_s": 0.0}, "monitor: max_speed_rad_s must be > 0 for every joint"),
        ({"noise_rad": [0.0, math.nan]}, "monitor: noise_rad must be finite numbers"),
        ({"wraps": [True]}, "monitor: wraps has 1 values for 2 joints"),
        ({"margin_rad": -0.1}, "monitor: margin_rad must be a finite number >= 0, got -0.1"),
        ({"joint_names": []}, "monitor: lower_rad has 2 values for 0 joints"),
    ],
)
def test_bad_configurations_are_refused_naming_the_field(kw: dict[str, object], message: str) -> None:
    assert _refusal(kw) == message


def test_the_docstring_examples_hold() -> None:
    import doctest

    import robocal.core.health.monitor as core_monitor
    import robocal.health as facade

    for module in (facade, core_monitor):
        assert doctest.testmod(module).failed == 0


def test_numpy_arrays_configure_per_joint_values_as_in_the_docs() -> None:
    """docs/health.md builds the config from ``np.radians([...])``; before, a numpy array was taken for one value
    and ``monitor_config`` raised ``TypeError: only 0-dimensional arrays can be converted to Python scalars``."""
    cfg = monitor_config(
        ["a", "b"],
        lower_rad=np.radians([-110.0, -10.0]),
        upper_rad=np.radians([110.0, 115.0]),
        max_speed_rad_s=np.array([6.0, 3.0]),
        wraps=np.array([False, True]),
        leader_paired=np.array([True, False]),
    )
    assert cfg.lower_rad == (math.radians(-110.0), math.radians(-10.0))
    assert cfg.max_speed_rad_s == (6.0, 3.0)
    assert (cfg.wraps, cfg.leader_paired) == ((False, True), (True, False))
    with pytest.raises(UsageError, match=r"^monitor: upper_rad has 3 values for 2 joints$"):
        monitor_config(["a", "b"], np.zeros(2) - 1.0, np.ones(3), 1.0)


@pytest.mark.parametrize(
    ("call", "message"),
    [
        ({"q_rad": np.array([0.5])}, "monitor: q_rad has shape (1,); expected (2,), one value per joint (a, b)"),
        ({"q_rad": 0.5}, "monitor: q_rad has shape (); expected (2,), one value per joint (a, b)"),
        ({"q_rad": np.zeros(3)}, "monitor: q_rad has shape (3,); expected (2,), one value per joint (a, b)"),
        ({"q_rad": np.zeros((2, 2))}, "monitor: q_rad has shape (2, 2); expected (2,), one value per joint (a, b)"),
        ({"q_cmd_rad": 0.0}, "monitor: q_cmd_rad has shape (); expected (2,), one value per joint (a, b)"),
        ({"q_leader_rad": np.zeros(1)}, "monitor: q_leader_rad has shape (1,); expected (2,), one value per joint (a, b)"),
        ({"t_s": math.nan}, "monitor: time nan s is not a finite number"),
        ({"t_s": math.inf}, "monitor: time inf s is not a finite number"),
    ],
)
def test_readings_that_are_not_one_number_per_joint_and_times_that_are_not_finite_are_refused(
    call: dict[str, object], message: str
) -> None:
    """Before, a (1,) reading or a scalar command was broadcast to every joint (no error, flags for every joint or
    none), a (3,) reading raised numpy's "operands could not be broadcast", a (1,) leader an IndexError from the
    pinned check; a NaN time was taken as a fresh start and an infinite one refused every later tick."""
    m = _monitor(leader_paired=True)
    _feed(m, [0.0, 0.0])
    args: dict[str, object] = {"t_s": 1.0, "q_rad": np.zeros(2), "q_cmd_rad": None, "q_leader_rad": None}
    args.update(call)
    with pytest.raises(UsageError) as err:
        m.update(**args)  # type: ignore[arg-type]
    assert str(err.value) == message
    assert m.update(1.0, [0.0, 0.0], q_cmd_rad=[0.0, 0.0], q_leader_rad=[0.0, math.nan]) == ()  # lists still do


@pytest.mark.parametrize(
    ("values", "kind"),
    [
        (np.array(["0.1", "0.2"]), "str"),
        (np.array([b"0.1", b"0.2"]), "bytes"),
        (["0.1", "0.2"], "str"),
        (np.array([0.1 + 1j, 0.2]), "complex"),
        ([0.1 + 1j, 0.2], "complex"),
        (np.array(["0.1", 0.2], dtype=object), "str"),
        (np.array(["2026-01-01", "2026-01-02"], dtype="datetime64[D]"), "datetime64"),
    ],
)
@pytest.mark.parametrize("what", ["q_rad", "q_cmd_rad", "q_leader_rad"])
def test_readings_of_strings_or_complex_numbers_are_refused_naming_the_argument(
    values: object, kind: str, what: str
) -> None:
    """Before, a (2,) array of strings or complex numbers got past the shape check and numpy raised its own
    ``UFuncTypeError`` (or a list of numeric strings was parsed as numbers); now the one UsageError, nothing
    recorded, and the next tick is checked as if the bad call had not happened."""
    m = _monitor(leader_paired=True)
    _feed(m, [0.0, 0.0])
    args: dict[str, object] = {"t_s": 1.0, "q_rad": np.zeros(2)}
    args[what] = values
    with pytest.raises(UsageError) as err:
        m.update(**args)  # type: ignore[arg-type]
    assert str(err.value) == f"monitor: {what} is not real numbers ({kind}); expected one float per joint (a, b)"
    assert (m.ticks, len(m.history)) == (2, 0)
    assert m.update(1.0, np.array([0.0, 0.0]), q_cmd_rad=np.zeros(2), q_leader_rad=np.zeros(2)) == ()
    assert m.update(1.01, np.array([0.0, 0.0], dtype=np.float32)) == ()
    assert m.update(1.02, np.array([0, 0])) == ()


@pytest.mark.parametrize(
    ("kw", "message"),
    [
        ({"wraps": "ab"}, "monitor: wraps is a string ('ab'); expected True/False or one per joint"),
        ({"leader_paired": "no"}, "monitor: leader_paired is a string ('no'); expected True/False or one per joint"),
        ({"wraps": b"\x01\x00"}, "monitor: wraps is a string (b'\\x01\\x00'); expected True/False or one per joint"),
        ({"lower_rad": "12"}, "monitor: lower_rad is a string ('12'); expected a number or one per joint"),
        ({"max_speed_rad_s": "3"}, "monitor: max_speed_rad_s is a string ('3'); expected a number or one per joint"),
        ({"noise_rad": b"00"}, "monitor: noise_rad is a string (b'00'); expected a number or one per joint"),
        ({"joint_names": "ab"}, "monitor: joint_names is a string ('ab'); expected one name per joint"),
        ({"wraps": ["no", "no"]}, "monitor: wraps of joint a is 'no' (str); expected True/False"),
        ({"leader_paired": [True, 2]}, "monitor: leader_paired of joint b is 2 (int); expected True/False"),
        ({"max_accel_rad_s2": ["50", "50"]}, "monitor: max_accel_rad_s2 of joint a is '50' (str); expected a number"),
        ({"upper_rad": np.array(["1", "1"])}, "monitor: upper_rad of joint a is '1' (str); expected a number"),
        ({"upper_rad": [1.0, None]}, "monitor: upper_rad of joint b is None (NoneType); expected a number"),
        ({"noise_rad": [0.0, 1j]}, "monitor: noise_rad of joint b is 1j (complex); expected a number"),
        ({"max_speed_rad_s": None}, "monitor: max_speed_rad_s is None (NoneType); expected a number or one per joint"),
        ({"lower_rad": np.zeros((2, 1))}, "monitor: lower_rad has shape (2, 1); expected (2,), one value per joint"),
        ({"margin_rad": "0.1"}, "monitor: margin_rad is '0.1' (str); expected a number"),
    ],
)
def test_strings_and_other_non_numbers_for_per_joint_values_are_refused_naming_the_field(
    kw: dict[str, object], message: str
) -> None:
    """Before, a string was read one value per character: ``wraps="ab"`` made both joints wrap, ``lower_rad="12"``
    gave stops (1.0, 2.0), ``max_speed_rad_s="3"`` a length error, ``wraps=["no", "no"]`` two True flags, and
    ``joint_names="ab"`` two joints; elements that were not numbers raised Python's TypeError or ValueError."""
    assert _refusal(kw) == message


@pytest.mark.parametrize(
    ("kw", "message"),
    [
        ({"wraps": "ab"}, "monitor: wraps is a string ('ab'); expected True/False or one per joint"),
        ({"joint_names": "ab"}, "monitor: joint_names is a string ('ab'); expected one name per joint"),
        ({"lower_rad": "12"}, "monitor: lower_rad is a string ('12'); expected a number or one per joint"),
        ({"margin_rad": "0.1"}, "monitor: margin_rad is '0.1' (str); expected a number"),
        ({"history": "5"}, "monitor: history is '5'; expected a whole number of flags"),
    ],
)
def test_a_config_built_directly_is_checked_as_monitor_config_checks_it(kw: dict[str, object], message: str) -> None:
    """``MonitorConfig(...)`` without :func:`monitor_config` used to check lengths only: ``wraps="ab"`` (two
    characters for two joints) made a monitor whose wrap flags were the characters."""
    base: dict[str, object] = {
        "joint_names": ("a", "b"),
        "lower_rad": (-1.0, -1.0),
        "upper_rad": (1.0, 1.0),
        "max_speed_rad_s": (3.0, 3.0),
        "max_accel_rad_s2": (50.0, 50.0),
        "noise_rad": (0.001, 0.001),
        "wraps": (False, True),
        "leader_paired": (False, False),
    }
    with pytest.raises(UsageError) as err:
        MonitorConfig(**{**base, **kw})  # type: ignore[arg-type]
    assert str(err.value) == message
    direct = MonitorConfig(**{**base, "wraps": [0, np.bool_(True)], "lower_rad": np.array([-1, -1])})  # type: ignore[arg-type]
    assert (direct.wraps, direct.lower_rad) == ((False, True), (-1.0, -1.0))  # tuples of bools and floats


def test_numpy_scalars_and_zero_dimensional_arrays_are_one_value_for_every_joint() -> None:
    cfg = monitor_config(
        ["a", "b"], [-1.0, -1.0], np.array([1.0, 2.0]), np.float32(3.0), noise_rad=np.array(0.01),
        wraps=np.bool_(True), leader_paired=[1, np.bool_(False)], margin_rad=np.float64(0.1),
    )
    assert (cfg.max_speed_rad_s, cfg.noise_rad, cfg.upper_rad) == ((3.0, 3.0), (0.01, 0.01), (1.0, 2.0))
    assert (cfg.wraps, cfg.leader_paired, cfg.margin_rad) == ((True, True), (True, False), 0.1)


_TYPED_USAGE = '''
from typing import Any

import numpy as np

from robocal.health import Monitor, monitor_config

follower: Any
leader: Any
running = False
cfg = monitor_config(
    np.array(["a", "b"]),
    lower_rad=np.radians([-110.0, -10.0]),
    upper_rad=np.array([1.9, 2.0]),
    max_speed_rad_s=np.full(2, 6.0),
    max_accel_rad_s2=np.float32(50.0),
    noise_rad=(0.003, 0.004),
    wraps=np.array([False, True]),
    leader_paired=np.bool_(True),
    margin_rad=np.float64(0.03),
)
'''


@pytest.mark.slow
def test_numpy_arrays_for_per_joint_values_type_check_under_mypy_strict_as_in_the_docs(tmp_path: Path) -> None:
    """monitor_config took numpy arrays at run time but was typed ``Sequence[float]`` / ``Sequence[bool]``: the
    docs' ``np.radians([...])`` stops failed ``mypy --strict`` with ``incompatible type "ndarray..."``. The docs'
    control-loop example (its robot objects declared) and the typed usage above now check clean."""
    doc = (Path(__file__).resolve().parents[2] / "docs" / "health.md").read_text(encoding="utf-8")
    section = doc[doc.index("### In a control loop") :]
    example = section[section.index("```python\n") + len("```python\n") : section.index("```\n", 10)]
    (tmp_path / "usage.py").write_text(_TYPED_USAGE + example, encoding="utf-8")
    src = Path(__file__).resolve().parents[2] / "src"
    out = subprocess.run(
        [sys.executable, "-m", "mypy", "--strict", "--no-error-summary", "--cache-dir", str(tmp_path / "cache"), "usage.py"],
        capture_output=True,
        text=True,
        cwd=tmp_path,
        env={**os.environ, "MYPYPATH": str(src)},
    )
    assert out.stdout.splitlines() == []
    assert out.returncode == 0
