"""viewer/access.py: only the page's own Host and Origin are served, names are text, bad clients are one line.

Real clients against a real served page: ``websockets`` for the websocket (a foreign Origin is answered 403,
the page's own origin gets the page's messages), ``http.client`` for HTTP with a hand-written Host header (DNS
rebinding), raw malformed frames on an open websocket.
"""

from __future__ import annotations

import asyncio
import http.client
import logging
from collections.abc import Iterator
from pathlib import Path

import pytest

pytest.importorskip("viser")
pytest.importorskip("yourdfpy")

import viser
import websockets

from robocal.cli.main import main
from robocal.errors import UsageError
from robocal.viewer.access import PageAccess, exposure_warning, outward_address, parse_allowed_origins
from robocal.viewer.app import ViewerApp
from robocal.viewer.model import load_robot_model
from robocal.viewer.scene import page_url

from .conftest import TWO_JOINT, wait_for

SUBPROTOCOL = f"viser-v{viser.__version__}"


class _Lines(logging.Handler):
    def __init__(self) -> None:
        super().__init__(logging.DEBUG)
        self.lines: list[str] = []

    def emit(self, record: logging.LogRecord) -> None:
        self.lines.append(record.getMessage())


@pytest.fixture
def page_log() -> Iterator[list[str]]:
    """Lines the served pages report on the ``robocal.viewer`` logger."""
    logger = logging.getLogger("robocal.viewer")
    handler = _Lines()
    logger.addHandler(handler)
    try:
        yield handler.lines
    finally:
        logger.removeHandler(handler)


def _serve(tmp_path: Path, urdf_text: str = TWO_JOINT, allowed: tuple[str, ...] = ()) -> ViewerApp:
    p = tmp_path / "robot.urdf"
    p.write_text(urdf_text)
    return ViewerApp(load_robot_model(p), port=0, allowed_origins=allowed).start(loop=False)


@pytest.fixture
def served(tmp_path: Path) -> Iterator[ViewerApp]:
    app = _serve(tmp_path)
    yield app
    app.stop()


def _ws(app: ViewerApp, origin: str | None) -> tuple[int | None, int]:
    """Open the page's websocket with ``origin``: (HTTP status if refused, else None; messages received)."""

    async def run() -> tuple[int | None, int]:
        url = f"ws://127.0.0.1:{app.port}/"
        try:
            async with websockets.connect(
                url, subprotocols=[SUBPROTOCOL], origin=origin, max_size=None, open_timeout=60  # type: ignore[arg-type]
            ) as ws:
                frame = await asyncio.wait_for(ws.recv(), timeout=60)
                return None, len(frame)
        except websockets.exceptions.InvalidStatus as exc:
            return exc.response.status_code, 0

    return asyncio.run(run())


def _http(app: ViewerApp, host: str, origin: str | None = None) -> tuple[int, bytes]:
    conn = http.client.HTTPConnection("127.0.0.1", app.port, timeout=60)
    try:
        conn.putrequest("GET", "/", skip_host=True)
        conn.putheader("Host", host)
        if origin is not None:
            conn.putheader("Origin", origin)
        conn.endheaders()
        resp = conn.getresponse()
        return resp.status, resp.read()
    finally:
        conn.close()


def test_websocket_from_a_foreign_origin_is_refused_and_the_pages_own_works(
    served: ViewerApp, page_log: list[str]
) -> None:
    port = served.port
    assert _ws(served, "http://evil.example") == (403, 0)
    assert _ws(served, "http://evil.example") == (403, 0)  # reported once, refused every time
    assert _ws(served, "null") == (403, 0)  # a file:// page or a sandboxed frame
    assert _ws(served, f"http://127.0.0.1:{port + 1}") == (403, 0)  # another local page (other port)
    status, size = _ws(served, f"http://127.0.0.1:{port}")
    assert status is None and size > 0
    assert _ws(served, f"http://localhost:{port}") == (403, 0)  # Host 127.0.0.1: another origin to a browser
    status, size = _ws(served, None)  # a script (no browser): no Origin
    assert status is None and size > 0
    assert page_log == [
        f"page: refused a request from 127.0.0.1:{p}: Origin {o!r} is not the page's own (--allow-origin allows "
        "others)"
        for p, o in zip(
            _ports(page_log),
            ["http://evil.example", "null", f"http://127.0.0.1:{port + 1}", f"http://localhost:{port}"],
            strict=True,
        )
    ]


def _ports(lines: list[str]) -> list[str]:
    return [line.split("127.0.0.1:", 1)[1].split(":", 1)[0] for line in lines]


def test_http_with_a_foreign_host_is_refused(served: ViewerApp, page_log: list[str]) -> None:
    """DNS rebinding: the browser sends the attacker's name in Host; the page answers 403 and nothing else."""
    status, body = _http(served, f"rebind.evil.example:{served.port}")
    assert status == 403 and body == b"refused: Host 'rebind.evil.example:%d' is not this machine's\n" % served.port
    status, body = _http(served, f"localhost:{served.port}")
    assert status == 200 and b"<html" in body.lower()
    status, _ = _http(served, f"127.0.0.1:{served.port}")
    assert status == 200
    status, _ = _http(served, f"127.0.0.1:{served.port}", origin="http://evil.example")
    assert status == 403
    assert len(page_log) == 2 and "Host 'rebind.evil.example" in page_log[0] and "Origin" in page_log[1]


def test_allow_origin_lets_another_origin_in(tmp_path: Path) -> None:
    app = _serve(tmp_path, allowed=("http://proxy.example:9000",))
    try:
        status, size = _ws(app, "http://proxy.example:9000")
        assert status is None and size > 0
        assert _http(app, "proxy.example:9000", origin="http://proxy.example:9000")[0] == 200
        assert _ws(app, "http://proxy.example:9001") == (403, 0)
    finally:
        app.stop()
    assert parse_allowed_origins(["HTTP://Proxy.Example:80/", "*"]) == ("http://proxy.example", "*")
    for bad in ("proxy.example", "http://proxy.example/path", "ftp://x", "http://"):
        with pytest.raises(UsageError, match="--allow-origin"):
            parse_allowed_origins([bad])


def test_access_rules() -> None:
    loop = PageAccess("127.0.0.1")
    assert loop.refusal("127.0.0.1:8080", None) is None
    assert loop.refusal("[::1]:8080", "http://[::1]:8080") is None
    assert loop.refusal("localhost:9000", "http://localhost:9000") is None  # an ssh -L tunnel on another port
    assert loop.refusal("evil.example:8080", None) == "Host 'evil.example:8080' is not this machine's"
    assert loop.refusal(None, None) == "Host None is not this machine's"
    assert loop.refusal("127.0.0.1:8080", "http://127.0.0.1:8081") is not None
    anyone = PageAccess("127.0.0.1", ("*",))
    assert anyone.refusal("evil.example", "http://evil.example") is None


def test_names_from_files_are_shown_as_text(tmp_path: Path) -> None:
    """A robot name with markdown / HTML is shown as those characters: no image fetched, no element made."""
    name = '![](http://evil.example/x.png) <img src="http://evil.example/y.png">'
    attr = name.replace("<", "&lt;").replace(">", "&gt;").replace('"', "&quot;")
    urdf = TWO_JOINT.replace('<robot name="two">', f'<robot name="{attr}">')
    app = _serve(tmp_path, urdf)
    try:
        assert app.title_el is not None
        assert type(app.title_el).__name__ == "GuiHtmlHandle"
        assert app.title_el.content == (
            "<b>![](http://evil.example/x.png) &lt;img src=&quot;http://evil.example/y.png&quot;&gt;</b>"
        )
        # what a browser receives: the name only inside an HTML element, escaped; no markdown element carries it
        messages = _page_messages(app)
        carrying = [(m["type"], str(m)) for m in messages if "evil.example" in str(m)]
        assert [t for t, _ in carrying] == ["GuiHtmlMessage"] * len(carrying) and carrying
        for _, text in carrying:
            assert "<img" not in text, text
        assert "GuiMarkdownMessage" not in {m["type"] for m in messages}
    finally:
        app.stop()


def _page_messages(app: ViewerApp) -> list[dict[str, object]]:
    """Every message a new client gets when it opens the page (the replayed page state)."""
    import msgspec
    import zstandard

    async def run() -> list[dict[str, object]]:
        out: list[dict[str, object]] = []
        async with websockets.connect(
            f"ws://127.0.0.1:{app.port}/", subprotocols=[SUBPROTOCOL], max_size=None, open_timeout=60
        ) as ws:
            while not any(m.get("type") == "ReplayDoneMessage" for m in out):
                frame = await asyncio.wait_for(ws.recv(), timeout=60)
                assert isinstance(frame, bytes)
                size = int.from_bytes(frame[0:8], "little")
                compressed = int.from_bytes(frame[8:16], "little")
                inner = zstandard.ZstdDecompressor().decompress(frame[16 : 16 + compressed], max_output_size=size)
                out += list(msgspec.msgpack.decode(inner)["messages"])
        return out

    return asyncio.run(run())


def test_malformed_messages_are_one_line_per_client_and_no_traceback(
    served: ViewerApp, page_log: list[str], capfd: pytest.CaptureFixture[str]
) -> None:
    async def send(payload: bytes | str) -> int | None:
        async with websockets.connect(
            f"ws://127.0.0.1:{served.port}/", subprotocols=[SUBPROTOCOL], max_size=None, open_timeout=60
        ) as ws:
            await ws.send(payload)
            try:
                while True:
                    await asyncio.wait_for(ws.recv(), timeout=60)
            except websockets.exceptions.ConnectionClosed as exc:
                return exc.rcvd.code if exc.rcvd is not None else None

    assert asyncio.run(send(b"\x00\xffnot msgpack")) == 1003
    assert asyncio.run(send(b"\x92\x01\x02")) == 1003  # msgpack, but not a message
    assert asyncio.run(send("text frame")) == 1003
    wait_for(lambda: len(page_log) >= 1)
    assert len(page_log) == 1
    assert page_log[0].startswith("page: closed the connection of 127.0.0.1: it sent a message the page cannot read (")
    assert page_log[0].endswith("further ones from it are not reported")
    err = capfd.readouterr().err
    assert "Traceback" not in err and "connection handler failed" not in err
    status, size = _ws(served, None)  # the page still serves
    assert status is None and size > 0


def test_exposure_warning_names_the_real_address(two_joint_urdf: Path, page_log: list[str]) -> None:
    assert exposure_warning("127.0.0.1", "http://127.0.0.1:8080/") is None
    assert exposure_warning("localhost", "http://localhost:8080/") is None
    addr = outward_address()
    assert addr != "localhost"
    assert page_url("0.0.0.0", 8080) == f"http://{addr}:8080/"
    app = ViewerApp(load_robot_model(two_joint_urdf), host="0.0.0.0", port=0).start(loop=False)
    try:
        url = app.url
        assert url == f"http://{addr}:{app.port}/"
        assert page_log == [
            f"the page is served on every network interface of this machine ({url}): anyone who can reach this "
            "machine on that port can watch the robot and use the page's controls (serve on 127.0.0.1 and tunnel, "
            "e.g. ssh -L, to keep it private)"
        ]
    finally:
        app.stop()


def test_cli_prints_the_exposure_warning_and_refuses_a_bad_allow_origin(
    two_joint_urdf: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from .conftest import LITE_URDF

    args = ["view", "--urdf", str(LITE_URDF), "--source", "sim:lite", "--port", "0", "--duration", "0.3"]
    assert main([*args, "--host", "0.0.0.0"]) == 0
    out, err = capsys.readouterr()
    addr = outward_address()
    assert out.startswith(f"robocal view: serving http://{addr}:")
    assert err.startswith("warning: the page is served on every network interface of this machine (http://")
    assert err.count("\n") == 1
    assert main([*args, "--allow-origin", "proxy:8080"]) == 2
    assert capsys.readouterr().err == (
        "error: --allow-origin 'proxy:8080': expected an origin such as http://robot-pc.local:8080 (scheme, host, "
        "optional port; no path), or * for any\n"
    )


def test_ur_page_has_the_same_rules_and_shows_its_source_as_text(page_log: list[str]) -> None:
    from robocal.core.ur import nominal_dh
    from robocal.viewer.ur_page import UrViewModel, UrViewPage

    page = UrViewPage(
        UrViewModel(nominal_dh("ur5e"), "ur5e"),
        source="![](http://evil.example/x.png).yaml",
        samples=10,
        port=0,
        allowed_origins=("http://proxy.example:9000",),
    ).start()
    try:
        assert _ws(page, "http://evil.example") == (403, 0)  # type: ignore[arg-type]
        status, size = _ws(page, "http://proxy.example:9000")  # type: ignore[arg-type]
        assert status is None and size > 0
        carrying = [m for m in _page_messages(page) if "evil.example" in str(m)]  # type: ignore[arg-type]
        assert carrying and {m["type"] for m in carrying} <= {"GuiHtmlMessage", "GuiUpdateMessage"}
        assert all("<img" not in str(m) for m in carrying)
    finally:
        page.stop()
    assert len(page_log) == 1 and "Origin 'http://evil.example'" in page_log[0]
