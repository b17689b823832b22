"""``robocal sim openarm``: two simulated OpenArm v10 arms in another process, reached over its socketcand server
with robocal's own DamiaoBus on python-can's ``socketcand`` interface (real frames over loopback TCP)."""

from __future__ import annotations

import math
import time
from pathlib import Path

import pytest

from robocal.backends.damiao.bus import DamiaoBus, DamiaoMotor
from robocal.backends.damiao.openarm import OPENARM_V10
from robocal.backends.damiao.protocol import MitCommand
from robocal.backends.sim.control import SimControl
from robocal.errors import UsageError
from robocal.workflows.sim.job import serve_openarm

from .conftest import SimProcess, robocal

pytestmark = pytest.mark.timeout(180)

SPECS = [DamiaoMotor(j.name, j.esc_id, j.mst_id, j.model) for j in OPENARM_V10]
STEP_RAD = 25.0 / 65535 + math.tau / 16384


def _bus(address: str, channel: str, **kw: object) -> DamiaoBus:
    host, port = address.rsplit(":", 1)
    return DamiaoBus(
        channel,
        SPECS,
        interface="socketcand",
        timeout_s=5.0,  # a reply crosses TCP and another process on a loaded machine
        bus_kwargs={"host": host, "port": int(port)},
        **kw,  # type: ignore[arg-type]
    )


def test_both_arms_answer_and_move_in_real_time(sim_process: type[SimProcess], tmp_path: Path) -> None:
    sim = sim_process(["openarm", "--port", "0", "--zeroed", "--seed", "3"])
    assert sim.info["source"].startswith("can:socketcand:can0,can1?host=127.0.0.1&port=")
    assert sim.info["buses"] == "can0 = right arm, can1 = left arm (ids 0x01-0x08, replies 0x11-0x18)"
    address = sim.info["socketcand"]
    with _bus(address, "can1") as left:
        states = left.refresh()
        assert left.range_sources == dict.fromkeys(states, "registers")
        assert states["joint_4"].position_rad == pytest.approx(math.radians(2.0), abs=math.radians(0.05))
        assert states["gripper"].position_rad == pytest.approx(math.radians(-2.0), abs=2 * STEP_RAD)
        assert states["joint_1"].position_rad == pytest.approx(0.0, abs=STEP_RAD)
    with _bus(address, "can0", allow_motion=True) as right:
        right.enable(["joint_5"])
        right.mit("joint_5", MitCommand(0.4, 0.0, 20.0, 0.5, 0.0))
        deadline = time.monotonic() + 60.0  # a hang guard: the joint gets there within ~0.5 s
        position = right.read_state("joint_5").position_rad
        while abs(position - 0.4) > 0.01 and time.monotonic() < deadline:
            time.sleep(0.05)
            position = right.mit("joint_5", MitCommand(0.4, 0.0, 20.0, 0.5, 0.0)).position_rad
        assert position == pytest.approx(0.4, abs=0.01)
        right.disable(["joint_5"])
    code, err = sim.stop()
    assert (code, err.strip().splitlines()[-1]) == (0, "simulator stopped")


def test_the_control_socket_moves_a_joint_by_its_profile_name(sim_process: type[SimProcess]) -> None:
    sim = sim_process(["openarm", "--port", "0", "--zeroed", "--side", "right"])
    assert sim.info["buses"] == "can0 = right arm (ids 0x01-0x08, replies 0x11-0x18)"
    with SimControl(sim.info["control"]) as control:
        joints = control.state()
        assert list(joints) == [f"openarm_right_joint{i}" for i in range(1, 8)] + ["openarm_right_gripper_motor"]
        assert joints["openarm_right_joint4"]["high"] == pytest.approx(math.radians(140))
        assert (joints["openarm_right_joint3"]["esc_id"], joints["openarm_right_joint3"]["motor"]) == (3, "joint_3")
        at = control.move("openarm_right_joint3", to=0.5)
        pushed = control.push("openarm_right_joint5", stop="max")
    assert at == pytest.approx(0.5, abs=0.01)
    assert pushed["openarm_right_joint5"] == pytest.approx(math.pi / 2, abs=0.01)
    with _bus(sim.info["socketcand"], "can0") as bus:  # the motors read the hand's placements (no gravity on J3/J5)
        states = bus.refresh(["joint_3", "joint_5"])
    assert states["joint_3"].position_rad == pytest.approx(0.5, abs=0.01)
    assert states["joint_5"].position_rad == pytest.approx(math.pi / 2, abs=0.01)


def test_bad_options_are_one_error_line(tmp_path: Path) -> None:
    r = robocal("sim", "openarm", "--side", "up", cwd=tmp_path)
    assert (r.returncode, r.stderr.strip(), r.stdout) == (2, "error: --side 'up': expected both, right or left", "")
    with pytest.raises(UsageError, match=r"^--seed -1: expected a number >= 0$"), serve_openarm(seed=-1):
        pass
