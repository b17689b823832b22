"""``robocal view`` under a 1 kHz source: page update rate seen by a real browser and server CPU per update.

The Lite (14 joints) is posed by a 1 kHz generated source (every joint moving) for ``WINDOW_S`` seconds while
headless Chromium shows the page. Measured:

* page rate: distinct page updates the browser showed per second (``#robocal-status[data-updates]`` polled
  in the page every 4 ms; a 320×240 canvas, because on a software renderer the browser's drawing, not the
  server, sets the pace);
* server CPU per update: CPU time of the whole server process (page loop, 1 kHz feed, viser's websocket
  thread) over the window, divided by the page updates made;
* frames in / dropped by the newest-frame mailbox, and the largest wait of a shown frame.

Baseline, measured in the same run on the same machine: a bare viser page with the same link frames, posed
by a plain loop at the same page rate with no robocal work (no calibration mapping, no joint panel, no page
state), fed by nothing. Printed as ratios: robocal / baseline.

``python benchmarks/run.py view`` (about 40 s). Without Chromium the browser-side rate is not measured and
the server-side numbers are still printed.
"""

from __future__ import annotations

import contextlib
import io
import math
import resource
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO / "tests" / "browser"))

import browserlib  # noqa: E402

from robocal.viewer import ViewerApp, load_robot_model  # noqa: E402
from robocal.viewer.scene import _wxyz  # noqa: E402
from robocal.viewer.feeds import CallableFeed  # noqa: E402

LITE_URDF = REPO / "examples" / "lite" / "lite_bimanual.urdf"
WINDOW_S = 8.0
SOURCE_HZ = 1000.0
PAGE_HZ = 30.0

OBSERVE = """(id) => {
    window.__robocalSeen = [];
    let last = null;
    setInterval(() => {
        const e = document.getElementById(id);
        const n = e ? e.getAttribute('data-updates') : null;
        if (n !== null && n !== last) { last = n; window.__robocalSeen.push([performance.now(), Number(n)]); }
    }, 4);
}"""
"""Records each new update count the page shows (polled every 4 ms in the page)."""
BENCH_VIEWPORT = {"width": 320, "height": 240}
"""A small canvas: on a software renderer (no GPU) the browser's drawing, not the server, limits the rate."""


def _cpu_s() -> float:
    r = resource.getrusage(resource.RUSAGE_SELF)
    return r.ru_utime + r.ru_stime


def _page_rate(page: Any, window_s: float) -> float:
    """Distinct update counts the page saw per second over the last ``window_s``."""
    seen = page.evaluate("() => window.__robocalSeen")
    if not seen:
        return math.nan
    t_end = seen[-1][0]
    counts = {n for t, n in seen if t >= t_end - window_s * 1000.0}
    return len(counts) / window_s


def _motion(n: int) -> Any:
    phase = np.linspace(0.0, 2.0, n)

    def fn(t_s: float) -> np.ndarray:
        return 0.5 * np.sin(2.0 * math.pi * 0.5 * t_s + phase)

    return fn


def run_robocal(page: Any | None) -> dict[str, float]:
    model = load_robot_model(LITE_URDF)
    app = ViewerApp(model, port=0, rate_hz=PAGE_HZ).start()
    feed = CallableFeed(app, _motion(len(model.actuated)), SOURCE_HZ)
    try:
        if page is not None:
            browserlib.open_viser(page, app.url)
            browserlib.next_frames(
                page, 30
            )  # the first frames compile shaders (seconds on a software renderer)
            page.evaluate(OBSERVE, "robocal-status")
        feed.start()
        time.sleep(1.0)  # settle
        u0, c0, f0 = app.updates, _cpu_s(), app.slot.frames_in
        time.sleep(WINDOW_S)
        u1, c1, f1 = app.updates, _cpu_s(), app.slot.frames_in
        rate = _page_rate(page, WINDOW_S - 1.0) if page is not None else math.nan
        return {
            "updates_per_s": (u1 - u0) / WINDOW_S,
            "page_rate_hz": rate,
            "cpu_per_update_ms": 1e3 * (c1 - c0) / max(1, u1 - u0),
            "source_hz": (f1 - f0) / WINDOW_S,
            "dropped_fraction": app.slot.dropped / max(1, app.slot.frames_in),
            "max_wait_ms": 1e3 * app.max_latency_s,
        }
    finally:
        feed.stop()
        app.stop()


def run_baseline(page: Any | None) -> dict[str, float]:
    """A bare viser page: one frame per link, posed by a plain loop at the page rate."""
    import viser

    model = load_robot_model(LITE_URDF)
    with contextlib.redirect_stdout(io.StringIO()):
        server = viser.ViserServer(host="127.0.0.1", port=0, verbose=False)
    parent_of = {j.child: j.parent for j in model.joints}
    paths: dict[str, str] = {}
    frames = {}
    for k, link in enumerate(model.links):
        parent = parent_of.get(link)
        paths[link] = f"/robot/L{k}" if parent is None else f"{paths[parent]}/L{k}"
        frames[link] = server.scene.add_frame(paths[link], show_axes=False)
    for k, shape in enumerate(model.shapes):
        server.scene.add_mesh_simple(
            f"{paths[shape.link]}/s{k}", shape.vertices, shape.faces, color=shape.rgba[:3]
        )
    counter = server.gui.add_html('<div id="baseline" data-updates="0"></div>')
    fn = _motion(len(model.actuated))
    try:
        if page is not None:
            page.goto(f"http://127.0.0.1:{server.get_port()}")
            browserlib.wait_until(lambda: page.evaluate("() => !!document.getElementById('baseline')"))
            browserlib.next_frames(
                page, 30
            )  # the first frames compile shaders (seconds on a software renderer)
            page.evaluate(OBSERVE, "baseline")
        n = 0
        period = 1.0 / PAGE_HZ
        start = time.monotonic()
        c0 = None
        while True:
            now = time.monotonic() - start
            if c0 is None and now >= 1.0:
                c0, n0 = _cpu_s(), n
            if now >= 1.0 + WINDOW_S:
                break
            _, local = model.poses(fn(now))
            with server.atomic():
                for link, T in local.items():
                    frames[link].wxyz = _wxyz(T[:3, :3])
                    frames[link].position = tuple(float(v) for v in T[:3, 3])
                n += 1
                counter.content = f'<div id="baseline" data-updates="{n}"></div>'
            time.sleep(max(0.0, start + (n + 1) * period - time.monotonic() - 0.0))
        assert c0 is not None
        c1 = _cpu_s()
        rate = _page_rate(page, WINDOW_S - 1.0) if page is not None else math.nan
        return {
            "updates_per_s": (n - n0) / WINDOW_S,
            "page_rate_hz": rate,
            "cpu_per_update_ms": 1e3 * (c1 - c0) / max(1, n - n0),
        }
    finally:
        with contextlib.redirect_stdout(io.StringIO()):
            server.stop()


def main() -> None:
    chromium = browserlib.find_chromium()
    results: dict[str, dict[str, float]] = {}
    with contextlib.ExitStack() as stack:
        page = None
        if chromium is None:
            print("no Chromium: the page rate seen by a browser is not measured")
        else:
            from playwright.sync_api import sync_playwright

            pw = stack.enter_context(sync_playwright())
            profile = stack.enter_context(tempfile.TemporaryDirectory(prefix="robocal-bench-chromium-"))
            ctx = pw.chromium.launch_persistent_context(
                profile,
                executable_path=chromium,
                headless=True,
                args=browserlib.CHROMIUM_ARGS,
                viewport=BENCH_VIEWPORT,
            )
            stack.callback(ctx.close)
            page = ctx.new_page()
        for name, fn in (("baseline (bare viser, same links)", run_baseline), ("robocal view", run_robocal)):
            if page is not None:
                page.goto("about:blank")
            results[name] = fn(page)
    base, rob = results["baseline (bare viser, same links)"], results["robocal view"]
    print(f"14 joints, source {SOURCE_HZ:.0f} Hz, page loop {PAGE_HZ:.0f} Hz, window {WINDOW_S:.0f} s")
    print(f"{'':36s} {'updates/s':>10s} {'page Hz':>8s} {'CPU ms/update':>14s}")
    for name, r in results.items():
        print(
            f"{name:36s} {r['updates_per_s']:10.1f} {r['page_rate_hz']:8.1f} {r['cpu_per_update_ms']:14.2f}"
        )
    print(
        f"robocal view: source ran at {rob['source_hz']:.0f} Hz, {100 * rob['dropped_fraction']:.1f} % of the frames "
        f"dropped as stale (newest frame wins), largest wait of a shown frame {rob['max_wait_ms']:.1f} ms"
    )
    print(
        f"ratios robocal / baseline: page rate {rob['page_rate_hz'] / base['page_rate_hz']:.2f}, "
        f"server CPU per update {rob['cpu_per_update_ms'] / base['cpu_per_update_ms']:.2f}"
    )


if __name__ == "__main__":
    main()
