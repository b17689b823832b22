"""Issue 26: Ctrl-C that lands inside a packet exchange (between the instruction and its status packet).

The vendor SDKs mark the port busy while a packet is out and clear the mark only once the reply is read; a
``KeyboardInterrupt`` raised in between left the mark set, so every later packet was refused ("port is in use") —
the torque-off and the restore included. That is how a single Ctrl-C under load left ``shoulder_lift`` energised
with its ``Homing_Offset`` and limits changed. The signal here is a real SIGINT sent to this process right after an
instruction went out during the search; the oracle is the simulated servos' registers.
"""

from __future__ import annotations

import os
import signal
from pathlib import Path
from typing import Any

import pytest

import robocal.workflows.lerobot.auto_sim as auto_sim
from robocal.backends.sim.lerobot_arms import SimArm
from robocal.cli.main import main

pytestmark = pytest.mark.timeout(600)


@pytest.mark.parametrize("nth_packet", [1, 7, 40])
def test_ctrl_c_inside_a_packet_still_ends_limp_and_restored(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str], nth_packet: int
) -> None:
    arms: list[SimArm] = []
    before: list[dict[str, dict[str, int]]] = []
    real_enter = SimArm.__enter__

    def enter(self: SimArm) -> SimArm:
        arms.append(self)
        out = real_enter(self)
        return out

    monkeypatch.setattr(SimArm, "__enter__", enter)
    buses: list[Any] = []
    real_open = auto_sim.open_sim_bus

    def opened(*args: Any, **kwargs: Any) -> Any:
        bus = real_open(*args, **kwargs)
        buses.append(bus)
        before.append({m.name: dict(arms[0].servo(m.name).eeprom_snapshot()) for m in arms[0].spec.motors})
        return bus

    monkeypatch.setattr(auto_sim, "open_sim_bus", opened)
    import robocal.cli._lerobot_auto as cli_auto

    real_view = cli_auto.AutoLiveView
    sent: list[int] = []

    class CtrlCInAPacket(real_view):  # type: ignore[misc,valid-type]
        def joint_start(self, name: str, cap_nm: float, speed_rad_s: float) -> None:
            super().joint_start(name, cap_nm, speed_rad_s)
            handler = buses[0]._port_handler
            real_write = handler.writePort
            count = [0]

            def write_then_ctrl_c(packet: Any) -> Any:
                n = real_write(packet)  # the instruction is out; the SDK waits for its status packet next
                count[0] += 1
                if count[0] == nth_packet and not sent:
                    sent.append(count[0])
                    os.kill(os.getpid(), signal.SIGINT)
                return n

            handler.writePort = write_then_ctrl_c

    monkeypatch.setattr(cli_auto, "AutoLiveView", CtrlCInAPacket)
    args = ["lerobot", "calibrate", "--auto", "--yes", "--robot", "so101_follower", "--port", "sim", "--id", "g",
            "--calibration-dir", str(tmp_path), "--joints", "shoulder_lift"]  # fmt: skip
    code = main(args)
    err = capsys.readouterr().err
    assert sent == [nth_packet]
    arm = arms[0]
    torque = {m.name: arm.servo(m.name).get_reg("Torque_Enable") for m in arm.spec.motors}
    assert set(torque.values()) == {0}, torque
    after = {m.name: dict(arm.servo(m.name).eeprom_snapshot()) for m in arm.spec.motors}
    assert after == before[0]
    assert arm.servo("shoulder_lift").get_reg("Torque_Limit") == 1000  # the search's RAM cap put back too
    assert code == 130, err
    assert "port is in use" not in err
    assert not (tmp_path / "robots" / "so_follower" / "g.json").exists()
