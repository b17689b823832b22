"""LeRobot 0.6.1's ``lerobot-find-port`` (its own module, run as its console script runs it) finds a simulated arm
served with ``--link /dev/ttyROBOCAL…``: the port that disappears when the simulated USB cable is pulled (issue 29).

The control socket of a link in ``/dev`` goes to a temporary folder, so ``/dev/tty*`` lists the link alone.
"""

from __future__ import annotations

import os
from pathlib import Path

import pytest

from robocal.backends.sim.control import SimControl
from robocal.backends.sim.serve import in_dev
from robocal.errors import UsageError
from robocal.workflows.sim.job import serve_arm

from .conftest import HARNESS, Interactive

pytestmark = [pytest.mark.interop, pytest.mark.timeout(300)]

FIND_PORT = (
    "import interop_stubs, runpy; runpy.run_module('lerobot.scripts.lerobot_find_port', run_name='__main__')"
)
"""``lerobot-find-port`` is ``lerobot.scripts.lerobot_find_port:main``; this runs that module unchanged after the
harness's stand-ins for torch & co. (its package imports them)."""


def test_a_link_in_dev_keeps_its_control_socket_elsewhere_and_unplugs() -> None:
    """In process: the served arm's control socket is not beside its /dev link; ``usb`` removes and restores the
    link and silences the servos meanwhile."""
    if not os.access("/dev", os.W_OK):
        pytest.skip("/dev is not writable here")
    link = f"/dev/ttyROBOCALU{os.getpid()}"
    assert in_dev(link) and not in_dev("/tmp/ttyX") and in_dev("/dev/../dev/ttyX")
    with serve_arm("so101_follower", link=link) as device:
        lines = dict(line.split(": ", 1) for line in device.lines if ": " in line)
        control = Path(lines["control"])
        assert control.parent != Path("/dev") and not os.path.lexists(f"{link}.control")
        port = os.readlink(link)
        with SimControl(control) as ctl:
            assert ctl.usb(False) is False and not os.path.lexists(link)
            assert not any(j["attached"] for j in ctl.state().values())  # nothing answers while it is out
            assert ctl.usb(True) is True and os.readlink(link) == port
            assert all(j["attached"] for j in ctl.state().values())
            with pytest.raises(UsageError, match="'plugged' must be true or false"):
                ctl.request("usb", plugged="no")
        assert device.usb is not None and device.usb() is False and device.usb() is True
    assert not os.path.lexists(link) and not control.exists()


@pytest.mark.slow
def test_lerobot_find_port_finds_the_linked_simulator(lerobot_python, sim_process, tmp_path: Path) -> None:  # type: ignore[no-untyped-def]
    if not os.access("/dev", os.W_OK):
        pytest.skip("/dev is not writable here (the link must be there for lerobot-find-port)")
    link = f"/dev/ttyROBOCAL{os.getpid()}"
    sim = sim_process(["so101_follower", "--link", link])
    assert sim.info["link"] == f"{link} -> {sim.info['port']}"
    control = Path(sim.info["control"])
    assert control.parent != Path("/dev") and control.exists()
    assert sorted(str(p) for p in Path("/dev").glob(f"ttyROBOCAL{os.getpid()}*")) == [link]
    run = Interactive(
        [str(lerobot_python), "-c", FIND_PORT],
        tmp_path,
        dict(os.environ, PYTHONPATH=str(HARNESS), PYTHONNOUSERSITE="1"),
    )
    with SimControl(control) as ctl:
        run.expect("Remove the USB cable from your MotorsBus and press Enter when done.")
        assert ctl.usb(False) is False
        assert not os.path.lexists(link)
        run.send()
        code, out = run.finish()
        assert code == 0, out[-3000:]
        assert f"The port of this MotorsBus is '{link}'" in out
        assert ctl.usb(True) is True
    assert os.readlink(link) == sim.info["port"]
