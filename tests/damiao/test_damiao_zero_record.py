"""A zero ``sweep --auto --write-zero`` stored in flash but no file holds is kept in the state folder and named by
the next run on that bus (issues 26, 31).

A Damiao zero (0xFE) is the position the motor is at when it is stored: no write takes it back. So the bus's
left-changed record (the one that keeps the armed TIMEOUT) names the motors about to be re-zeroed before the first
flash write, each one's state around its 0xFE and the motor's reading where the zero goes; it goes once the file
is written. A run that never writes its file (killed) leaves it, and the next run's one ``note:`` says which motors
have a new zero, that no file was written, and what to do. Judged by the simulated motors' stored zeros and flash
write counts and by the state folder's file.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Iterator
from importlib import resources
from pathlib import Path
from typing import Any

import pytest

pytest.importorskip("can")

from robocal.backends.damiao.openarm import SimOpenArm
from robocal.backends.sources.spec import parse_source
from robocal.formats.profiles import resolve_profile
from robocal.formats.urdf import read_urdf
from robocal.workflows.autocal.damiao import open_damiao
from robocal.workflows.autocal.model import limp_all
from robocal.workflows.autocal.zero import store_zeros, zeros_written
from robocal.workflows.motion.damiao_watchdog import WatchdogRecord, bus_key, left_zeros, note_left_zeros
from robocal.workflows.motion.snapshot import find_left_changed, state_dir
from robocal.workflows.sweep.joint_specs import joints_from_urdf

GRIPPER = "openarm_right_gripper_motor"


@pytest.fixture
def arm(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Iterator[SimOpenArm]:
    monkeypatch.setenv("XDG_STATE_HOME", str(tmp_path / "state"))
    a = SimOpenArm(f"oa-zero-record-{id(tmp_path)}", side="right", seed=4).start()
    yield a
    a.stop()


def _zero_gripper(arm: SimOpenArm, *, write_file: bool) -> tuple[float, list[str]]:
    """Open the bus as ``sweep --auto`` does, store the gripper's zero where it is (its 0: where it stands now),
    and tell the record the file is written or not (a kill); the motor's reading there, degrees, and the notes."""
    urdf = read_urdf(Path(str(resources.files("robocal").joinpath("data", "openarm_v10_right.urdf"))))
    profile = resolve_profile("openarm_follower_right", urdf)
    assert profile is not None and profile.auto is not None
    specs = joints_from_urdf(urdf, profile, None)
    records: list[logging.LogRecord] = []
    handler = logging.Handler()
    handler.emit = records.append  # type: ignore[method-assign]
    logging.getLogger("robocal.notes").addHandler(handler)
    try:
        drivers, _clock, close = open_damiao(parse_source(f"can:virtual:{arm.channel}"), specs, profile)
    finally:
        logging.getLogger("robocal.notes").removeHandler(handler)
    try:
        d: Any = drivers[GRIPPER]
        s_now = d.read().q_rad
        zeros = store_zeros({GRIPPER: d}, {GRIPPER: s_now}, profile.auto, max_lag_rad=d.MAX_LAG_RAD)
        assert list(zeros) == [GRIPPER]
        if write_file:
            zeros_written(drivers, list(zeros))
    finally:
        limp_all(list(drivers.values()))
        close()
    return math.degrees(d.direction * (s_now + zeros[GRIPPER])), [r.getMessage() for r in records]


def test_a_zero_stored_without_its_file_is_named_by_the_next_run_until_a_file_holds_it(arm: SimOpenArm) -> None:
    key = bus_key("virtual", arm.channel)
    grip = arm.motors["gripper"]
    writes0, zero0 = grip.flash_writes, grip.zero_abs_rad
    reading_deg, notes = _zero_gripper(arm, write_file=False)  # killed before its file: nothing tells the record
    assert grip.flash_writes == writes0 + 1 and grip.zero_abs_rad != zero0 and notes == []
    kept = find_left_changed(key)
    assert kept is not None
    left = left_zeros(kept)
    assert list(left) == [GRIPPER] and left[GRIPPER]["state"] == "stored"
    assert left[GRIPPER]["reading_deg"] == pytest.approx(reading_deg, abs=1e-6)
    assert abs(reading_deg) > 1.0  # the factory zero is far from the joint's: the readings move visibly

    _, notes = _zero_gripper(arm, write_file=True)  # the next run: its note, then its own zero and file
    assert len(notes) == 1, notes
    assert notes[0].startswith("a previous `robocal sweep --auto --write-zero` (pid ")
    assert f"stored a new zero in flash on {GRIPPER} (readings {-reading_deg:+.2f}°)" in notes[0]
    assert "wrote no calibration file" in notes[0] and "run `robocal sweep --auto --write-zero` again" in notes[0]
    assert grip.flash_writes == writes0 + 2
    assert find_left_changed(key) is None  # its file holds the gripper's zero: the record went


def test_a_clean_run_leaves_no_record(arm: SimOpenArm) -> None:
    key = bus_key("virtual", arm.channel)
    _, notes = _zero_gripper(arm, write_file=True)
    assert notes == [] and find_left_changed(key) is None
    assert list((state_dir() / "left-changed").glob("*.json")) == []  # the TIMEOUT put back, the zero in the file


def test_the_record_names_each_zero_by_its_state_and_carries_a_left_one_on(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, caplog: pytest.LogCaptureFixture
) -> None:
    monkeypatch.setenv("XDG_STATE_HOME", str(tmp_path / "state"))
    key = bus_key("socketcand", "can0", {"host": "127.0.0.1", "port": 29536})
    record = WatchdogRecord(key)
    record.zero("g", "planned", math.radians(10.0))
    record.zero("j6", "planned", math.radians(-4.0))
    kept = find_left_changed(key)
    assert kept is not None and left_zeros(kept) == {}  # planned: nothing in flash yet, the next run says nothing
    record.zero("g", "storing", math.radians(10.0))
    record.zero("g", "stored", math.radians(10.0))
    record.zero("j6", "storing", math.radians(-4.0))  # killed during j6's 0xFE: it may be in flash
    with caplog.at_level(logging.INFO, logger="robocal.notes"):
        left = note_left_zeros(key)
    assert {m: z["state"] for m, z in left.items()} == {"g": "stored", "j6": "storing"}
    (note,) = [r.getMessage() for r in caplog.records if r.name == "robocal.notes"]
    assert "stored a new zero in flash on g (readings -10.00°) and was storing one on j6 (readings +4.00°)" in note

    again = WatchdogRecord(key, zeros=left)  # the next run carries them on
    again.changed("g", 0.0)  # it arms a TIMEOUT and puts it back: the zeros stay
    again.changed("g", None)
    again.zero("g", "planned", math.radians(1.0))  # planning and sparing g again never hides its stored zero
    again.zero("g", "unchanged")
    again.zero("j6", "planned", math.radians(2.0))
    again.zero("j6", "unchanged")  # a carried "storing" stays too
    kept = find_left_changed(key)
    assert kept is not None and {m: z["state"] for m, z in left_zeros(kept).items()} == {"g": "stored", "j6": "storing"}
    again.zero("g", "storing", math.radians(1.0))
    again.zero("g", "stored", math.radians(1.0))  # stored once more: readings moved 10° + 1° since the file
    kept = find_left_changed(key)
    assert kept is not None and left_zeros(kept)["g"]["reading_deg"] == pytest.approx(11.0)
    again.zero("g", "written")
    again.zero("j6", "written")
    assert find_left_changed(key) is None


@pytest.mark.parametrize("auto", [["--auto", "--write-zero", "--yes"], []], ids=["auto", "hand"])
def test_the_next_run_names_a_left_zero_before_it_opens_the_bus(
    auto: list[str], tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """``sweep --auto`` and the hand sweep (which reads the motors against their stored zeros) say first what a
    killed run left there, even when the bus then does not answer."""
    from robocal.cli.main import main

    monkeypatch.setenv("XDG_STATE_HOME", str(tmp_path / "state"))
    channel = f"nobody-{id(tmp_path)}"  # no motor answers: the sweep ends exit 3 after the note
    WatchdogRecord(bus_key("virtual", channel)).zero(GRIPPER, "stored", math.radians(7.5))
    urdf = Path(str(resources.files("robocal").joinpath("data", "openarm_v10_right.urdf")))
    code = main(["sweep", *auto, "--robot", "openarm_follower_right", "--urdf", str(urdf), "--source",
                 f"can:virtual:{channel}", "--out", str(tmp_path / "c.yaml")])  # fmt: skip
    err = capsys.readouterr().err
    notes = [ln for ln in err.splitlines() if ln.startswith("note: a previous `robocal sweep --auto --write-zero`")]
    assert code == 3 and len(notes) == 1, err
    assert f"on damiao:virtual:{channel} stored a new zero in flash on {GRIPPER} (readings -7.50°)" in notes[0]
    assert not (tmp_path / "c.yaml").exists()


def test_a_fault_while_zeros_go_to_flash_says_which_are_there(arm: SimOpenArm) -> None:
    """J6 goes silent right after the gripper's zero reached flash: the run ends with a device error, and first a
    note names the gripper's zero in flash and J6's perhaps; the record keeps both for the next run."""
    urdf = read_urdf(Path(str(resources.files("robocal").joinpath("data", "openarm_v10_right.urdf"))))
    profile = resolve_profile("openarm_follower_right", urdf)
    assert profile is not None and profile.auto is not None
    drivers, _clock, close = open_damiao(
        parse_source(f"can:virtual:{arm.channel}"), joints_from_urdf(urdf, profile, None), profile
    )
    j6 = "openarm_right_joint6"
    records: list[logging.LogRecord] = []
    handler = logging.Handler()
    handler.emit = records.append  # type: ignore[method-assign]
    logging.getLogger("robocal.notes").addHandler(handler)
    try:
        d: Any = drivers
        hook = d[GRIPPER].on_zero

        def then_silence(motor: str, state: str, reading_rad: float = 0.0) -> None:
            hook(motor, state, reading_rad)
            if state == "stored":
                arm.silence("joint_6")  # the cable to J6 lost

        d[GRIPPER].on_zero = then_silence
        targets = {n: d[n].read().q_rad for n in (GRIPPER, j6)}
        with pytest.raises(Exception) as failed:
            store_zeros({n: d[n] for n in targets}, targets, profile.auto, max_lag_rad=d[GRIPPER].MAX_LAG_RAD)
        assert not isinstance(failed.value, AssertionError)
    finally:
        logging.getLogger("robocal.notes").removeHandler(handler)
        arm.silence("joint_6", False)
        limp_all(list(drivers.values()))
        close()
    notes = [r.getMessage() for r in records]
    assert notes == [
        f"the zero of {GRIPPER} is in flash, {j6}'s may be (its store failed); no calibration file was "
        "written: run `robocal sweep --auto --write-zero` again to write it"
    ]
    kept = find_left_changed(bus_key("virtual", arm.channel))
    assert kept is not None
    assert {m: z["state"] for m, z in left_zeros(kept).items()} == {GRIPPER: "stored", j6: "storing"}
    assert arm.motors["gripper"].flash_writes == 1
