"""``robocal view`` under a 1 kHz source: updates the browser receives and renders per second, server CPU per update.

The Lite (14 joints) is posed by a 1 kHz generated source (every joint moving) for ``WINDOW_S`` seconds while
headless Chromium shows the page. Measured in the page (a script installed before the page loads):

* received: distinct page updates that reached the page per second (the update counter of each GUI message
  that viser's websocket worker hands to the page, ``#robocal-frame[data-updates]``);
* rendered: distinct page updates on screen per second (the counter in the DOM at each animation frame in
  which WebGL drew), and the frames drawn per second;

and in the server: page updates made per second, CPU per update of the whole server process (page loop, 1 kHz
feed, viser's websocket thread) and of the page loop alone, frames in / dropped by the newest-frame mailbox and
the largest wait of a shown frame.

Baseline, measured in the same run on the same machine and browser: a bare viser page with the same link frames
and shapes, posed by a plain loop at the same page rate and with the same pacing rule (no robocal work: no
calibration mapping, no joint panel, no page state; fed by nothing), with the same kind of counter element.
Printed as ratios robocal/baseline.

``python benchmarks/run.py view`` (about three minutes: ``VIEW_BENCH_REPEATS`` alternating runs of each, default 3,
medians and their ratios printed; ``VIEW_BENCH_WINDOW_S`` changes the window, ``VIEW_BENCH_SOURCE_HZ`` the source).
Without Chromium only the server-side numbers are printed.
"""

from __future__ import annotations

import contextlib
import io
import math
import os
import resource
import statistics
import sys
import tempfile
import threading
import time
from pathlib import Path
from typing import Any

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO / "tests" / "browser"))

import browserlib  # noqa: E402

from robocal.viewer import ViewerApp, load_robot_model  # noqa: E402
from robocal.viewer.feeds import CallableFeed  # noqa: E402
from robocal.viewer.latest import next_tick  # noqa: E402
from robocal.viewer.scene import wxyz_from_matrix  # noqa: E402

LITE_URDF = REPO / "examples" / "lite" / "lite_bimanual.urdf"
WINDOW_S = float(os.environ.get("VIEW_BENCH_WINDOW_S", "8"))
SETTLE_S = 1.0
REPEATS = int(os.environ.get("VIEW_BENCH_REPEATS", "3"))
SOURCE_HZ = float(os.environ.get("VIEW_BENCH_SOURCE_HZ", "1000"))
PAGE_HZ = 30.0
BENCH_VIEWPORT = {"width": 320, "height": 240}
"""A small canvas: on a software renderer (no GPU) the browser's drawing is part of what is measured."""

INSTRUMENT = """(() => {
    // Installed before the page's own scripts. Counts, per page update counter value:
    //  - received: GUI messages carrying the counter element, as viser's websocket worker hands them over;
    //  - shown: the counter in the DOM at each animation frame in which WebGL drew.
    window.__rx = []; window.__shown = []; window.__frames = []; window.__counterId = null;
    const re = /data-updates="(\\d+)"/;
    const W = window.Worker;
    window.Worker = class extends W {
        constructor(...a) {
            super(...a);
            this.addEventListener('message', (e) => {
                const d = e.data, id = window.__counterId;
                if (!id || !d || d.type !== 'message_batch') return;
                for (const m of d.messages) {
                    const c = m && m.updates && m.updates.content;
                    if (m.type === 'GuiUpdateMessage' && typeof c === 'string' && c.includes('id="' + id + '"')) {
                        const k = re.exec(c);
                        if (k) window.__rx.push([performance.now(), Number(k[1])]);
                    }
                }
            });
        }
    };
    let drew = false;
    for (const C of [window.WebGL2RenderingContext, window.WebGLRenderingContext]) {
        if (!C) continue;
        for (const f of ['drawElements', 'drawArrays', 'drawElementsInstanced', 'drawArraysInstanced']) {
            const o = C.prototype[f];
            if (!o) continue;
            C.prototype[f] = function (...a) { drew = true; return o.apply(this, a); };
        }
    }
    let last = null;
    const tick = () => {
        if (drew) {
            drew = false;
            const t = performance.now();
            window.__frames.push(t);
            const id = window.__counterId, e = id && document.getElementById(id);
            const n = e ? e.getAttribute('data-updates') : null;
            if (n !== null && n !== last) { last = n; window.__shown.push([t, Number(n)]); }
        }
        requestAnimationFrame(tick);
    };
    requestAnimationFrame(tick);
})();"""


def _cpu_s() -> float:
    r = resource.getrusage(resource.RUSAGE_SELF)
    return r.ru_utime + r.ru_stime


def _start_counting(page: Any, counter_id: str) -> float:
    """Reset the page's counters, start counting ``counter_id``; the page clock (ms) at the start."""
    return float(
        page.evaluate(
            "(id) => { window.__rx = []; window.__shown = []; window.__frames = []; window.__counterId = id;"
            " return performance.now(); }",
            counter_id,
        )
    )


def _page_rates(page: Any | None, t0_ms: float, window_s: float) -> dict[str, float]:
    """Received and rendered updates per second, frames drawn per second over ``window_s`` from ``t0_ms``."""
    if page is None:
        return {"received_hz": math.nan, "rendered_hz": math.nan, "frames_hz": math.nan}
    got = page.evaluate("() => [window.__rx, window.__shown, window.__frames]")
    t1 = t0_ms + 1000.0 * window_s

    def distinct(rows: list[list[float]]) -> int:
        return len({int(n) for t, n in rows if t0_ms <= t < t1})

    return {
        "received_hz": distinct(got[0]) / window_s,
        "rendered_hz": distinct(got[1]) / window_s,
        "frames_hz": sum(1 for t in got[2] if t0_ms <= t < t1) / window_s,
    }


def _motion(n: int) -> Any:
    phase = np.linspace(0.0, 2.0, n)

    def fn(t_s: float) -> np.ndarray:
        return 0.5 * np.sin(2.0 * math.pi * 0.5 * t_s + phase)

    return fn


def _page_clock(page: Any | None) -> float:
    return float(page.evaluate("() => performance.now()")) if page is not None else math.nan


def run_robocal(page: Any | None) -> dict[str, float]:
    model = load_robot_model(LITE_URDF)
    app = ViewerApp(model, port=0, rate_hz=PAGE_HZ).start()
    feed = CallableFeed(app, _motion(len(model.actuated)), SOURCE_HZ)
    loop_cpu = [0.0]
    tick = getattr(app, "tick", app.step)  # an older page loop ran step()

    def timed_tick() -> bool:  # the page loop's own CPU (its thread only)
        c = time.thread_time()
        try:
            return bool(tick())
        finally:
            loop_cpu[0] += time.thread_time() - c

    app.tick = app.step = timed_tick  # type: ignore[method-assign]
    try:
        counter = "robocal-frame"
        if page is not None:
            browserlib.open_viser(page, app.url)
            browserlib.next_frames(
                page, 30
            )  # the first frames compile shaders (seconds on a software renderer)
            if not page.evaluate("() => !!document.getElementById('robocal-frame')"):
                counter = "robocal-status"  # an older page: the counter is on the page state
        feed.start()
        time.sleep(SETTLE_S)
        t0 = _start_counting(page, counter) if page is not None else math.nan
        u0, c0, f0, l0 = app.updates, _cpu_s(), app.slot.frames_in, loop_cpu[0]
        time.sleep(WINDOW_S)
        u1, c1, f1, l1 = app.updates, _cpu_s(), app.slot.frames_in, loop_cpu[0]
        n = max(1, u1 - u0)
        return {
            "updates_hz": (u1 - u0) / WINDOW_S,
            **_page_rates(page, t0, WINDOW_S),
            "cpu_per_update_ms": 1e3 * (c1 - c0) / n,
            "loop_cpu_per_update_ms": 1e3 * (l1 - l0) / n,
            "source_hz": (f1 - f0) / WINDOW_S,
            "dropped_fraction": app.slot.dropped / max(1, app.slot.frames_in),
            "max_wait_ms": 1e3 * app.max_latency_s,
        }
    finally:
        feed.stop()
        app.stop()


def run_baseline(page: Any | None) -> dict[str, float]:
    """A bare viser page: one frame per link and the same shapes, posed by a plain loop at the page rate."""
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
    stop = threading.Event()
    count = [0]
    loop_cpu = [0.0]

    def loop() -> None:  # paced like the robocal page loop (same rule: no catching up in a burst)
        period = 1.0 / PAGE_HZ
        start = deadline = time.monotonic()
        while not stop.is_set():
            c = time.thread_time()
            _, local = model.poses(fn(time.monotonic() - start))
            with server.atomic():
                for link, T in local.items():
                    frames[link].wxyz = wxyz_from_matrix(T[:3, :3])
                    frames[link].position = tuple(float(v) for v in T[:3, 3])
                count[0] += 1
                counter.content = f'<div id="baseline" data-updates="{count[0]}"></div>'
            loop_cpu[0] += time.thread_time() - c
            deadline, wait = next_tick(deadline, time.monotonic(), period)
            stop.wait(wait)

    thread = threading.Thread(target=loop, daemon=True)
    try:
        if page is not None:
            page.goto(f"http://127.0.0.1:{server.get_port()}")
            browserlib.wait_until(lambda: page.evaluate("() => !!document.getElementById('baseline')"))
            browserlib.next_frames(page, 30)
        thread.start()
        time.sleep(SETTLE_S)
        t0 = _start_counting(page, "baseline") if page is not None else math.nan
        n0, c0, l0 = count[0], _cpu_s(), loop_cpu[0]
        time.sleep(WINDOW_S)
        n1, c1, l1 = count[0], _cpu_s(), loop_cpu[0]
        n = max(1, n1 - n0)
        return {
            "updates_hz": (n1 - n0) / WINDOW_S,
            **_page_rates(page, t0, WINDOW_S),
            "cpu_per_update_ms": 1e3 * (c1 - c0) / n,
            "loop_cpu_per_update_ms": 1e3 * (l1 - l0) / n,
        }
    finally:
        stop.set()
        thread.join(timeout=5.0)
        with contextlib.redirect_stdout(io.StringIO()):
            server.stop()


def _load() -> str:
    try:
        one, five, _ = os.getloadavg()
    except OSError:
        return "load unknown"
    return f"load average {one:.1f} (1 min), {five:.1f} (5 min) on {os.cpu_count()} cores"


BASE = "baseline (bare viser, same links)"
ROBOCAL = "robocal view"
KEYS = (
    "updates_hz",
    "received_hz",
    "rendered_hz",
    "frames_hz",
    "cpu_per_update_ms",
    "loop_cpu_per_update_ms",
)


def _median(runs: list[dict[str, float]]) -> dict[str, float]:
    out: dict[str, float] = {}
    for k in runs[0]:
        vals = [r[k] for r in runs if math.isfinite(r[k])]
        out[k] = statistics.median(vals) if vals else math.nan
    return out


def _row(name: str, r: dict[str, float]) -> str:
    return f"{name:40s} " + " ".join(f"{r[k]:11.2f}" for k in KEYS)


def main() -> None:
    chromium = browserlib.find_chromium()
    runs: dict[str, list[dict[str, float]]] = {BASE: [], ROBOCAL: []}
    with contextlib.ExitStack() as stack:
        page = None
        if chromium is None:
            print("no Chromium: the rates seen by a browser are not measured")
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
            ctx.add_init_script(INSTRUMENT)
            page = ctx.new_page()
        print(f"before: {_load()}")
        for _ in range(REPEATS):  # alternating, so that a change of the machine's load hits both alike
            for name, fn in ((BASE, run_baseline), (ROBOCAL, run_robocal)):
                if page is not None:
                    page.goto("about:blank")
                runs[name].append(fn(page))
        print(f"after: {_load()}")
    print(
        f"14 joints, source {SOURCE_HZ:.0f} Hz, page loop {PAGE_HZ:.0f} Hz, {REPEATS} alternating runs of "
        f"{WINDOW_S:.0f} s each"
    )
    cols = ("updates/s", "received/s", "rendered/s", "frames/s", "CPU ms/upd", "loop ms/upd")
    print(f"{'':40s} " + " ".join(f"{c:>11s}" for c in cols))
    for k in range(REPEATS):
        for name in (BASE, ROBOCAL):
            print(_row(f"{name} #{k + 1}", runs[name][k]))
    base, rob = _median(runs[BASE]), _median(runs[ROBOCAL])
    print(_row(f"{BASE} median", base))
    print(_row(f"{ROBOCAL} median", rob))
    print(
        f"robocal view: source ran at {rob['source_hz']:.0f} Hz, {100 * rob['dropped_fraction']:.1f} % of the frames "
        f"dropped as stale (newest frame wins), largest wait of a shown frame {rob['max_wait_ms']:.1f} ms"
    )

    def ratio(key: str) -> str:
        b = base[key]
        return f"{rob[key] / b:.2f}" if b and math.isfinite(b) and math.isfinite(rob[key]) else "n/a"

    print(
        f"ratios robocal / baseline (medians): updates made {ratio('updates_hz')}, received "
        f"{ratio('received_hz')}, rendered {ratio('rendered_hz')}, server CPU per update "
        f"{ratio('cpu_per_update_ms')} (page loop alone {ratio('loop_cpu_per_update_ms')})"
    )


if __name__ == "__main__":
    main()
