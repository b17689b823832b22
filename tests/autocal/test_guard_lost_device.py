"""Issue 26: a serial adapter that vanishes under pyserial raises ``termios.error`` (not an ``OSError``): robocal maps
it to a device error (exit 3), never an internal error (exit 70)."""

from __future__ import annotations

import termios
from pathlib import Path
from typing import Any

import pytest

import robocal.workflows.lerobot.auto_sim as auto_sim
from robocal.backends.sim.lerobot_arms import SimArm
from robocal.cli.main import main
from robocal.errors import DeviceError
from robocal.workflows.lerobot import open_bus, robot_spec

pytestmark = pytest.mark.timeout(600)


class _GoneSerial:
    """A pyserial port whose USB adapter was unplugged: every call raises ``termios.error`` (EIO)."""

    def __getattr__(self, name: str) -> Any:
        def gone(*args: Any, **kwargs: Any) -> Any:
            raise termios.error(5, "Input/output error")

        return gone


def test_termios_error_on_any_transfer_is_a_device_error() -> None:
    with SimArm(robot_spec("so101_follower")) as arm:
        bus = open_bus(arm.spec, arm.port)
        try:
            assert bus.read("Torque_Enable", 1) == 0
            real = bus._port_handler.ser  # type: ignore[attr-defined]
            bus._port_handler.ser = _GoneSerial()  # type: ignore[attr-defined]
            for call in (
                lambda: bus.read("Homing_Offset", 1),
                lambda: bus.write("Torque_Enable", 1, 0),
                lambda: bus.sync_write("Torque_Enable", {1: 0, 2: 0}),
                lambda: bus.sync_read("Present_Position", [1, 2]),
            ):
                with pytest.raises(DeviceError, match="the device is gone or not answering"):
                    call()
            bus._port_handler.ser = real  # type: ignore[attr-defined]
            assert bus.read("Torque_Enable", 1) == 0  # a transfer cut short left the port usable
        finally:
            bus.close()


def test_cli_auto_with_the_adapter_gone_mid_search_exits_3_not_70(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    import robocal.cli._lerobot_auto as cli_auto

    buses: list[Any] = []
    real_open = auto_sim.open_sim_bus

    def opened(*args: Any, **kwargs: Any) -> Any:
        buses.append(real_open(*args, **kwargs))
        return buses[-1]

    monkeypatch.setattr(auto_sim, "open_sim_bus", opened)
    real_view = cli_auto.AutoLiveView

    class Unplugged(real_view):  # type: ignore[misc,valid-type]
        def joint_start(self, name: str, cap_nm: float, speed_rad_s: float) -> None:
            super().joint_start(name, cap_nm, speed_rad_s)
            buses[0]._port_handler.ser = _GoneSerial()  # the cable is pulled as the search starts

    monkeypatch.setattr(cli_auto, "AutoLiveView", Unplugged)
    args = ["lerobot", "calibrate", "--auto", "--yes", "--robot", "so101_follower", "--port", "sim", "--id", "g",
            "--calibration-dir", str(tmp_path), "--joints", "shoulder_lift"]  # fmt: skip
    assert main(args) == 3
    err = capsys.readouterr().err
    lines = [x for x in err.splitlines() if x.startswith("error:")]
    assert len(lines) == 1 and "internal error" not in err
    assert "the device is gone or not answering" in lines[0]
    assert "auto-calibration aborted, the device is gone: " in lines[0]  # never "every motor limp"
    assert "the device is lost (the port failed: " in lines[0]
    assert "may still hold torque (switch the arm's power off before touching it)" in lines[0]
    assert not (tmp_path / "robots" / "so_follower" / "g.json").exists()
