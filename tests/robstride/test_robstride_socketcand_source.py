"""robocal's own ``can:socketcand:…?host=H&port=P`` source against the simulated Lite behind the socketcand
server: python-can's socketcand client over a real loopback TCP socket (issue 29)."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from robocal.backends.sim.lite import LITE_JOINTS, SimLite
from robocal.backends.sim.socketcand import SocketcandServer
from robocal.backends.sources import JointSpec, open_source, parse_source
from robocal.backends.sources.spec import can_bus_options
from robocal.errors import UsageError

pytestmark = pytest.mark.timeout(120)

_n = itertools.count()
JOINTS = [JointSpec(j.name, j.can_id, j.model, j.direction, j.lower, j.upper) for j in LITE_JOINTS]


def test_parse_socketcand_source() -> None:
    s = parse_source("can:socketcand:can0,can1?port=29540&host=127.0.0.2")
    assert (s.interface, s.channels, dict(s.options)) == (
        "socketcand",
        ("can0", "can1"),
        {"port": "29540", "host": "127.0.0.2"},
    )
    assert can_bus_options(s) == {"host": "127.0.0.2", "port": 29540}
    assert can_bus_options(parse_source("can:socketcand:can0")) == {"host": "127.0.0.1", "port": 29536}
    assert can_bus_options(parse_source("can:virtual:x")) == {}
    for bad, msg in [
        ("can:socketcand:can0?port=0", "port must be 1..65535, got '0'"),
        ("can:socketcand:can0?port=70000", "port must be 1..65535"),
        ("can:socketcand:can0?port=x", "port must be 1..65535, got 'x'"),
        ("can:socketcand:can0?host=", "host is empty"),
        ("can:socketcand:can0?bitrate=1", "unknown option 'bitrate'"),
        ("can:socketcan:can0?port=1", "host and port apply to can:socketcand only"),
        ("can:socketcand:?port=1", "expected can:<interface>"),
    ]:
        with pytest.raises(UsageError, match=msg):
            parse_source(bad)


def test_one_channel_over_socketcand_reads_the_motors() -> None:
    sim = SimLite(5, noise_rad=0.0, channel_prefix=f"scd-src-{next(_n)}")
    left = [js for js, j in zip(JOINTS, LITE_JOINTS, strict=True) if j.bus == "can0"]
    with sim, SocketcandServer({"can0": sim.channels["can0"]}) as server:
        src = open_source(f"can:socketcand:can0?port={server.port}", left, timeout_s=5.0)
        try:
            s = src.read()
            assert s is not None and src.frame == "motor"
            expected = [sim.motors[j.name].reading_rad(noisy=False) for j in left]
            np.testing.assert_allclose(s.position_rad, expected, atol=4e-4)  # 16-bit feedback
            assert all(sim.motors[j.name].requests == {1: 1} for j in left)  # one MIT poll each, nothing else
        finally:
            src.close()


@pytest.mark.slow
def test_two_channels_over_socketcand_find_every_joint() -> None:
    sim = SimLite(6, noise_rad=0.0, channel_prefix=f"scd-src-{next(_n)}")
    with sim, SocketcandServer({"can0": sim.channels["can0"], "can1": sim.channels["can1"]}) as server:
        src = open_source(f"can:socketcand:can0,can1?port={server.port}", JOINTS, timeout_s=1.0)
        try:
            assert [sorted(b.motors) for b in src.buses] == [
                sorted(j.name for j in LITE_JOINTS if j.bus == "can0"),
                sorted(j.name for j in LITE_JOINTS if j.bus == "can1"),
            ]
            s = src.read()
            expected = [sim.motors[j.name].reading_rad(noisy=False) for j in LITE_JOINTS]
            np.testing.assert_allclose(s.position_rad, expected, atol=4e-4)
        finally:
            src.close()
