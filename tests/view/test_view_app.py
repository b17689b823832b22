"""The viewer page: scene state follows the joints, ghost, red beyond limits, frame dropping, replay, failures."""

from __future__ import annotations

import math
import re
import urllib.request
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("viser")  # robocal[view]; installed by the [test] extra
pytest.importorskip("yourdfpy")
pytest.importorskip("trimesh")

from tests.net import busy_port

from robocal.core.jointmap import RobotCalibration
from robocal.errors import DeviceError, UsageError
from robocal.viewer import JointMapper, LatestFrame, ViewerApp, load_robot_model
from robocal.viewer.app import GHOST_RGB, OUTSIDE_RGB
from robocal.viewer.feeds import PollFeed, ReplayFeed
from robocal.viewer.model import DEFAULT_RGBA

from .conftest import wait_for


class FakeClock:
    def __init__(self) -> None:
        self.t = 0.0

    def __call__(self) -> float:
        return self.t


def rgb01(mesh: object) -> np.ndarray:
    """A mesh handle's colour as 0..1 floats (viser keeps integers 0..255 or the floats assigned)."""
    c = np.asarray(mesh.color)  # type: ignore[attr-defined]
    return c / 255.0 if np.issubdtype(c.dtype, np.integer) else c.astype(float)


def y_rotation(q: float) -> np.ndarray:
    return np.array([math.cos(q / 2), 0.0, math.sin(q / 2), 0.0])


def test_latest_frame_keeps_only_the_newest() -> None:
    clock = FakeClock()
    slot = LatestFrame(clock)
    assert slot.take() is None
    for k in range(5):
        slot.put(k, [float(k)])
    f = slot.take()
    assert f is not None and f.seq == 5 and f.raw.tolist() == [4.0]
    assert slot.dropped == 4 and slot.take() is None
    slot.put(9, [9.0])
    assert slot.dropped == 4  # the shown frame was taken: nothing replaced unseen


def test_page_keeps_up_with_a_1khz_source_of_14_joints() -> None:
    """1 kHz frames, a page update every 50 ms (20 Hz): each update shows the newest frame, none queues."""
    clock = FakeClock()
    model = load_robot_model(Path(__file__).resolve().parents[2] / "examples" / "lite" / "lite_bimanual.urdf")
    assert len(model.actuated) == 14
    app = ViewerApp(model, clock=clock, port=0)  # not started: step() computes the page state only
    for k in range(2000):
        clock.t = k * 1e-3
        app.push(clock.t, np.full(14, 0.001 * k))
        if k % 50 == 49:
            assert app.step()
            assert app.last_update is not None and app.last_update.frame.t_s == clock.t
            assert app.last_latency_s == 0.0  # shown at once: no backlog
    assert app.updates == 40
    assert app.slot.frames_in == 2000 and app.slot.dropped == 2000 - 40
    assert app.max_latency_s == 0.0
    # the page falls 3 periods behind (a slow browser): still only the newest frame, latency one source tick
    for k in range(2000, 2150):
        clock.t = k * 1e-3
        app.push(clock.t, np.full(14, 0.001 * k))
    clock.t += 1e-3
    assert app.step() and app.last_update is not None and app.last_update.frame.t_s == pytest.approx(2.149)
    assert app.last_latency_s == pytest.approx(1e-3)
    assert not app.step()  # nothing new


@pytest.fixture
def served(two_joint_urdf: Path):
    model = load_robot_model(two_joint_urdf)
    cal = JointMapper(model.actuated, RobotCalibration.identity(model.actuated), "cal")
    flipped = JointMapper(
        model.actuated, RobotCalibration.identity(model.actuated).with_directions({"shoulder": -1}), "flip"
    )
    app = ViewerApp(model, calibration=cal, compare=flipped, port=0).start(loop=False)
    yield app
    app.stop()


def test_model_follows_the_joint_and_the_ghost_diverges_for_a_flipped_direction(served: ViewerApp) -> None:
    app = served
    assert app.robot is not None and app.ghost is not None
    upper = app.robot.frames["upper"]
    ghost_upper = app.ghost.frames["upper"]
    app.push(0.0, [0.0, 0.0])
    app.step()
    np.testing.assert_allclose(upper.wxyz, [1, 0, 0, 0], atol=1e-12)
    app.push(0.1, [0.6, -0.4])
    app.step()
    np.testing.assert_allclose(upper.wxyz, y_rotation(0.6), atol=1e-12)
    np.testing.assert_allclose(ghost_upper.wxyz, y_rotation(-0.6), atol=1e-12)  # the flipped joint
    # the elbow is the same in both (its map is the same): rotation origin rpy 0.3 then q = −0.4
    np.testing.assert_allclose(app.robot.frames["lower"].wxyz, y_rotation(-0.1), atol=1e-12)
    np.testing.assert_allclose(app.ghost.frames["lower"].wxyz, y_rotation(-0.1), atol=1e-12)
    np.testing.assert_allclose(app.robot.frames["lower"].position, [0, 0, 0.2], atol=1e-12)
    status = app.status()
    assert status["updates"] == 2 and status["compare"] == "flip"
    assert [j["q"] for j in status["joints"]] == [0.6, -0.4]
    assert [j["q_compare"] for j in status["joints"]] == [-0.6, -0.4]
    ghost_mesh = app.ghost.meshes["upper"][0][0]
    assert np.allclose(rgb01(ghost_mesh), GHOST_RGB, atol=0.01) and ghost_mesh.opacity == 0.35
    assert np.allclose(rgb01(app.robot.meshes["upper"][0][0]), DEFAULT_RGBA[:3], atol=0.01)


def test_joint_beyond_its_limit_turns_red_and_back(served: ViewerApp) -> None:
    app = served
    assert app.robot is not None
    mesh = app.robot.meshes["upper"][0][0]
    app.push(0.0, [1.2, 0.0])  # shoulder upper limit 1.0
    app.step()
    assert np.allclose(rgb01(mesh), OUTSIDE_RGB, atol=0.01)
    joints = app.status()["joints"]
    assert [(j["name"], j["outside"], j["color"]) for j in joints] == [
        ("shoulder", True, "red"),
        ("elbow", False, "normal"),
    ]
    assert 'data-joint="shoulder" data-outside="1"' in app._panel.content
    assert 'data-joint="elbow" data-outside="0"' in app._panel.content
    app.push(0.1, [0.9, 0.0])
    app.step()
    assert np.allclose(rgb01(mesh), DEFAULT_RGBA[:3], atol=0.01)
    assert app.status()["joints"][0]["outside"] is False


def test_page_is_served_from_the_installed_package(served: ViewerApp) -> None:
    with urllib.request.urlopen(served.url, timeout=30) as resp:
        assert resp.status == 200
        page = resp.read().decode("utf-8", "replace")
    assert "<html" in page.lower()
    # the client is inlined: no script, style sheet or font is loaded from another host
    loads = re.findall(r"<(?:script|link)\b[^>]*\b(?:src|href)=[\"']([^\"']+)", page, flags=re.I)
    assert [u for u in loads if re.match(r"(?:https?:)?//", u)] == []


def test_port_in_use_is_a_usage_error(two_joint_urdf: Path) -> None:
    model = load_robot_model(two_joint_urdf)
    with busy_port() as port, pytest.raises(UsageError, match=f"port {port} on 127.0.0.1 is in use"):
        ViewerApp(model, port=port).start()


def test_source_dying_is_shown_on_the_page_and_the_server_keeps_serving(served: ViewerApp) -> None:
    calls = {"n": 0}

    def poll() -> list[float]:
        calls["n"] += 1
        if calls["n"] > 3:
            raise DeviceError("no reply from motor 11 on can0")
        return [0.1 * calls["n"], 0.0]

    feed = PollFeed(served, poll, "test-bus", max_rate_hz=100.0).start()
    wait_for(lambda: served.source_state == "failed")
    feed.stop()
    assert isinstance(feed.error, DeviceError)
    status = served.status()
    assert status["source"] == "failed"
    assert status["messages"][-1] == {
        "level": "error",
        "text": "source test-bus stopped: no reply from motor 11 on can0",
    }
    assert served.step() and status["frames_in"] == 3  # the last pose is still there to show
    with urllib.request.urlopen(served.url, timeout=30) as resp:
        assert resp.status == 200


def test_replay_play_pause_seek(served: ViewerApp) -> None:
    clock = FakeClock()
    t = np.array([0.0, 0.5, 1.0, 1.5])
    raw = np.array([[0.0, 0.0], [0.1, -0.1], [0.2, -0.2], [0.3, -0.3]])
    feed = ReplayFeed(served, t, raw, "rec.csv", autoplay=False, clock=clock)
    served.attach_replay(feed)
    feed.push_current()
    assert served.step() and served.status()["t_s"] == 0.0
    feed.seek(1.2)
    served.step()
    assert served.status()["t_s"] == 1.0 and [j["q"] for j in served.status()["joints"]] == [0.2, -0.2]
    assert served._replay_gui["slider"].value == pytest.approx(1.2)
    feed.play()
    clock.t = 0.25
    feed.push_current()
    served.step()
    assert served.status()["t_s"] == 1.0 and served.status()["replay"]["playing"] is True
    clock.t = 0.35  # 1.2 + 0.35 = 1.55: past the end → the last row, stopped at the end
    feed.push_current()
    served.step()
    assert served.status()["t_s"] == 1.5 and served.status()["replay"] == {
        "playing": False,
        "position_s": 1.5,
        "start_s": 0.0,
        "end_s": 1.5,
    }
    feed.play()  # from the start again
    assert feed.position_s == 0.0
    feed.pause()
    clock.t = 5.0
    assert feed.position_s == 0.0
    with pytest.raises(UsageError):
        feed.seek(math.nan)


def test_a_websocket_client_receives_the_pose_and_the_red_joint(served: ViewerApp) -> None:
    """A real websocket client on viser's protocol: the messages carry the new orientation and the red row."""
    import asyncio

    import msgspec
    import viser
    import websockets
    import zstandard

    app = served
    assert app.robot is not None
    upper_path = app.robot.paths["upper"]

    def decode(frame: bytes) -> list[dict[str, object]]:
        size = int.from_bytes(frame[0:8], "little")
        compressed = int.from_bytes(frame[8:16], "little")
        inner = zstandard.ZstdDecompressor().decompress(frame[16 : 16 + compressed], max_output_size=size)
        return list(msgspec.msgpack.decode(inner)["messages"])

    async def run() -> tuple[list[float] | None, bool]:
        url = app.url.replace("http://", "ws://")
        async with websockets.connect(url, subprotocols=[f"viser-v{viser.__version__}"], max_size=None) as ws:
            app.push(0.0, [1.3, 0.0])  # shoulder beyond its +1.0 limit
            await asyncio.get_running_loop().run_in_executor(None, app.step)
            wxyz = None
            red = False
            end = asyncio.get_running_loop().time() + 60
            while (wxyz is None or not red) and asyncio.get_running_loop().time() < end:
                frame = await asyncio.wait_for(ws.recv(), timeout=60)
                assert isinstance(frame, bytes)
                for m in decode(frame):
                    if m.get("type") == "SetOrientationMessage" and m.get("name") == upper_path:
                        wxyz = list(m["wxyz"])  # type: ignore[call-overload]
                    updates = m.get("updates")
                    if isinstance(updates, dict) and 'data-joint="shoulder" data-outside="1"' in str(
                        updates.get("content", "")
                    ):
                        red = True
            return wxyz, red

    wxyz, red = asyncio.run(run())
    assert wxyz is not None
    np.testing.assert_allclose(wxyz, y_rotation(1.3), atol=1e-6)
    assert red


def test_page_url_of_every_page_names_a_host_a_browser_can_open() -> None:
    from robocal.viewer.scene import page_url

    assert page_url("127.0.0.1", 8080) == "http://127.0.0.1:8080/"
    from robocal.viewer.access import outward_address

    # a wildcard: the address other machines reach this one at (the page is open to them), not localhost
    addr = outward_address()
    assert page_url("0.0.0.0", 80) == f"http://{addr}:80/"
    assert page_url("", 81) == f"http://{addr}:81/"
    assert page_url("::", 82) == f"http://{addr}:82/"
    assert page_url("::1", 83) == "http://[::1]:83/"


def test_stop_thread_ends_a_loop_and_never_joins_the_calling_thread() -> None:
    import threading

    from robocal.viewer.scene import stop_thread

    stop = threading.Event()
    ran = threading.Event()

    def loop() -> None:
        ran.set()
        while not stop.wait(0.01):
            pass

    thread = threading.Thread(target=loop, daemon=True)
    thread.start()
    assert ran.wait(30)
    stop_thread(stop, thread, timeout_s=30)
    assert stop.is_set() and not thread.is_alive()
    own = threading.Event()
    stop_thread(own, threading.current_thread())  # a loop stopping itself returns at once
    assert own.is_set()
    stop_thread(threading.Event(), None)  # never started


def test_page_loop_sends_the_page_state_at_most_ten_times_a_second(two_joint_urdf: Path) -> None:
    """Per update the page gets the pose and a small counter; the page state (JSON) at most 10 Hz, when a joint
    crosses a limit, and once due after the updates stop (so the page always ends with the newest state)."""
    import html
    import json

    clock = FakeClock()
    app = ViewerApp(load_robot_model(two_joint_urdf), port=0, clock=clock).start(loop=False)

    def state() -> dict[str, object]:
        m = re.search(r'data-status="([^"]*)"', app._status_el.content)
        assert m is not None
        return dict(json.loads(html.unescape(m.group(1))))

    def state_updates() -> int:
        return int(state()["updates"])  # type: ignore[call-overload]

    def counter() -> int:
        m = re.search(r'id="robocal-frame" data-updates="(\d+)"', app._frame_el.content)
        assert m is not None
        return int(m.group(1))

    try:
        for k, t in enumerate((0.0, 0.03, 0.06)):
            clock.t = t
            app.push(t, [0.1 * k, 0.0])
            assert app.tick()
        assert counter() == 3  # every update reaches the page
        assert state_updates() == 1  # the page state of the first one only: the next were within 0.1 s
        clock.t = 0.08
        assert not app.tick() and state_updates() == 1  # idle, but not due yet
        clock.t = 0.101
        assert not app.tick() and state_updates() == 3  # idle and due: the newest state goes out
        assert not app.tick() and state_updates() == 3
        clock.t = 0.11
        app.push(0.11, [1.5, 0.0])  # the shoulder crosses its +1.0 limit: the state goes out at once
        assert app.tick() and counter() == 4 and state_updates() == 4
        assert app.status()["joints"][0]["outside"] is True
        clock.t = 0.12
        app.push(0.12, [1.4, 0.0])
        assert app.step() and state_updates() == 5  # step() (tests, scripts) sends the state every time
        app.message("hello")  # a message makes the state newer than the page's: sent when due
        clock.t = 0.3
        assert not app.tick()
        assert {"level": "info", "text": "hello"} in state()["messages"]  # type: ignore[operator]
    finally:
        app.stop()


def test_page_loop_keeps_its_rate_when_it_wakes_late() -> None:
    from robocal.viewer.latest import next_tick

    assert next_tick(1.0, 1.01, 0.1) == pytest.approx((1.1, 0.09))
    assert next_tick(1.0, 1.15, 0.1) == pytest.approx((1.1, 0.0))  # late: the next tick at once, same grid
    assert next_tick(1.1, 1.16, 0.1) == pytest.approx((1.2, 0.04))
    assert next_tick(1.0, 1.5, 0.1) == pytest.approx((1.5, 0.0))  # far behind: a new grid, no burst

    # A simulated loop at 30 Hz on a machine whose scheduler wakes it 12 ms late every time, for 10 s:
    # it still makes 30 ticks a second (restarting the schedule at each late wake made 1/(33.3+12 ms) = 22).
    period, latency = 1.0 / 30.0, 0.012
    now, deadline, ticks = 0.0, 0.0, 0
    while now < 10.0:
        ticks += 1
        now += 0.0016  # the update's own work
        deadline, wait = next_tick(deadline, now, period)
        now += wait + latency
    assert 295 <= ticks <= 301
