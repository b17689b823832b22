"""Issue 26 item 2: a run that could not restore (SIGKILL mid-search) leaves its snapshot in the state folder; the
next command on that port says what was left changed, and ``lerobot restore-previous`` writes it back.

The oracle is the simulated SO-101 in its own process (``tests/autocal/arm_host.py``): its registers after the
restore equal those from before the killed run, every motor limp.
"""

from __future__ import annotations

import json
import signal
import time
from pathlib import Path

import pytest

from .guardlib import HANG_GUARD_S, ArmHost, Robocal, auto_args, kept_registers, torque_on

pytestmark = [pytest.mark.timeout(600)]


@pytest.mark.slow
def test_after_sigkill_the_next_command_says_what_is_left_and_restore_previous_writes_it_back(
    arm: ArmHost, tmp_path: Path
) -> None:
    env = {"XDG_STATE_HOME": str(tmp_path / "state")}
    before = arm.state()
    run = Robocal(auto_args(arm.port, tmp_path, joints="shoulder_lift"), tmp_path, env=env)
    run.wait_for("searching its stops")
    deadline = time.monotonic() + HANG_GUARD_S
    while "shoulder_lift" not in torque_on(arm.state()):  # pushing, Homing_Offset and limits changed
        assert time.monotonic() < deadline and run.proc.poll() is None, run.stderr
    run.signal(signal.SIGKILL)  # nothing can run: the snapshot stays
    assert run.finish() == -signal.SIGKILL
    left = arm.state()
    assert torque_on(left) == ["shoulder_lift"]
    assert left["shoulder_lift"]["Homing_Offset"] != before["shoulder_lift"]["Homing_Offset"]
    kept = list((tmp_path / "state" / "robocal" / "left-changed").iterdir())
    assert len(kept) == 1

    # the next command on the port (here without a terminal) says what was left and how to write it back
    cal = tmp_path / "cal" / "robots" / "so_follower"
    cal.mkdir(parents=True)
    (cal / "g.json").write_text(
        json.dumps(
            {
                m: {"id": i + 1, "drive_mode": 0, "homing_offset": 0, "range_min": 0, "range_max": 4095}
                for i, m in enumerate(before)
            }
        )
    )
    check = Robocal(
        ["lerobot", "check", "--robot", "so101_follower", "--port", arm.port, "--id", "g", "--calibration-dir",
         str(tmp_path / "cal")],
        tmp_path,
        env=env,
    )  # fmt: skip
    check.finish()
    notes = [line for line in check.err_lines if line.startswith("note: ")]
    assert len(notes) == 2, check.stderr
    was = before["shoulder_lift"]["Homing_Offset"]
    now = left["shoulder_lift"]["Homing_Offset"]
    assert "shoulder_lift: " in notes[0] and f"Homing_Offset {now} (was {was})" in notes[0]
    assert "torque on: shoulder_lift" in notes[0]
    assert notes[1] == (
        "note: not written back (no terminal to ask); `robocal lerobot restore-previous --robot so101_follower "
        f"--port {arm.port}` writes the previous values back"
    )
    assert kept[0].exists()  # only said, nothing written
    assert arm.state()["shoulder_lift"]["Homing_Offset"] == now

    restore = Robocal(
        ["lerobot", "restore-previous", "--robot", "so101_follower", "--port", arm.port], tmp_path, env=env
    )
    assert restore.finish() == 0, restore.stderr
    after = arm.state()
    assert torque_on(after) == []
    assert kept_registers(after, "feetech") == kept_registers(before, "feetech")
    assert not kept[0].exists()
    again = Robocal(
        ["lerobot", "restore-previous", "--robot", "so101_follower", "--port", arm.port], tmp_path, env=env
    )
    assert again.finish() == 0
    assert again.out.strip() == f"nothing left changed on {arm.port}"


def test_the_kept_snapshot_is_found_by_the_next_run_on_that_port_until_it_is_removed(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The quick representative: the state file a killed run leaves, read back exactly, and gone once resolved."""
    from robocal.workflows.motion.snapshot import SnapshotStore, find_left_changed

    monkeypatch.setenv("XDG_STATE_HOME", str(tmp_path / "state"))
    port = str(tmp_path / "ttyACM0")
    assert find_left_changed(port) is None
    store = SnapshotStore(port, "lerobot calibrate --auto")
    store.save(
        {"shoulder_lift": {"Homing_Offset": -1203, "Max_Position_Limit": 4095}}, robot="so101_follower"
    )
    left = find_left_changed(port)
    assert left is not None
    assert left.path == tmp_path / "state" / "robocal" / "left-changed" / store.path.name
    assert (left.port, left.command) == (port, "lerobot calibrate --auto")
    assert left.registers == {"shoulder_lift": {"Homing_Offset": -1203, "Max_Position_Limit": 4095}}
    assert left.about == {"robot": "so101_follower"}
    assert find_left_changed(str(tmp_path / "ttyACM1")) is None  # another bus has its own file
    assert [p.name for p in store.path.parent.iterdir()] == [store.path.name]  # no temporary file left
    store.remove()
    assert find_left_changed(port) is None
