"""Headless-Chromium harness for robocal's web views (viser pages), driven by Playwright.

The browser is the distribution's Chromium (``/usr/bin/chromium`` on Debian; ``.ci/run`` installs it when
missing), started by Playwright through ``executable_path`` so that Playwright never downloads a browser of
its own. ``ROBOCAL_CHROMIUM`` names another binary.

What a test reads back:

* pixels: :func:`screenshot` gives the page as an ``(H, W, 3)`` uint8 array; :func:`color_mask`,
  :func:`centroid` and :func:`scene_region` look at what the WebGL canvas drew;
* page state: :func:`page_state` parses the JSON that a robocal view publishes in the page (an element with
  ``id="robocal-status"`` and a ``data-status`` attribute, sent over viser's websocket like everything else),
  and :func:`gui_value` reads the value of a labelled control in viser's panel.

Every wait is bounded (:data:`DEFAULT_TIMEOUT_S`) and polls; nothing depends on the machine's speed.
"""

from __future__ import annotations

import io
import json
import os
import shutil
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any, TypeVar

import numpy as np

T = TypeVar("T")

CHROMIUM_ARGS = [
    "--no-sandbox",
    "--disable-gpu",
    "--disable-quic",
    "--no-first-run",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    "--enable-unsafe-swiftshader",
]
"""Flags for a headless Chromium run as root on a machine without GPU or internet; WebGL runs on SwiftShader."""

DEFAULT_TIMEOUT_S = 40.0
"""Upper bound of every wait: generous, because the suite shares two cores with other work."""

VIEWPORT = {"width": 960, "height": 600}


def find_chromium() -> str | None:
    """Return the Chromium binary to use, or ``None`` when the machine has none."""
    env = os.environ.get("ROBOCAL_CHROMIUM")
    if env:
        return env if Path(env).is_file() else None
    for name in ("chromium", "chromium-browser", "google-chrome", "google-chrome-stable"):
        found = shutil.which(name)
        if found:
            return found
    return "/usr/bin/chromium" if Path("/usr/bin/chromium").is_file() else None


def _truthy(value: Any) -> bool:
    """False for None, False, 0 and empty containers; an array (an image) counts as a value, so it is True."""
    if isinstance(value, np.ndarray):
        return True
    return bool(value)


def wait_until(predicate: Callable[[], T], timeout_s: float = DEFAULT_TIMEOUT_S, what: str = "") -> T:
    """Poll ``predicate`` until it returns a truthy value (any array counts as one) and return that value.

    Raises:
        AssertionError: after ``timeout_s`` without success, naming ``what`` and the last value seen.
    """
    deadline = time.monotonic() + timeout_s
    last: Any = None
    while True:
        last = predicate()
        if _truthy(last):
            return last
        if time.monotonic() > deadline:
            raise AssertionError(
                f"timed out after {timeout_s:.0f} s waiting for {what or predicate!r}; last: {last!r}"
            )
        time.sleep(0.1)


def open_viser(page: Any, url: str, timeout_s: float = DEFAULT_TIMEOUT_S) -> None:
    """Load a robocal viser page; wait until its state arrived over the websocket and the canvas drew a frame.

    The "Software WebGL rendering detected" notice that viser shows on SwiftShader is closed so that it does
    not cover the scene; other notifications (robocal's own messages) are left alone.
    """
    page.set_default_timeout(timeout_s * 1000)
    page.goto(url)
    wait_until(lambda: page_state(page) is not None, timeout_s, "the page state (#robocal-status)")
    wait_until(lambda: _canvas_size(page)[0] > 0, timeout_s, "the WebGL canvas")
    dismiss_webgl_notice(page)
    next_frames(page)


def dismiss_webgl_notice(page: Any) -> None:
    """Close viser's "Software WebGL rendering detected" notification if it is shown."""
    page.evaluate(
        """() => {
        for (const n of document.querySelectorAll('.mantine-Notification-root')) {
            if (n.textContent.includes('Software WebGL')) {
                const b = n.querySelector('button'); if (b) b.click();
            }
        }
    }"""
    )


def _canvas_size(page: Any) -> tuple[int, int]:
    size = page.evaluate(
        "() => { let best=[0,0]; for (const c of document.querySelectorAll('canvas'))"
        " if (c.width*c.height > best[0]*best[1]) best=[c.width,c.height]; return best; }"
    )
    return int(size[0]), int(size[1])


def next_frames(page: Any, n: int = 3) -> None:
    """Wait for ``n`` animation frames, so that what the page received is drawn."""
    page.evaluate(
        "(n) => new Promise(r => { const f = k => k <= 0 ? r() : requestAnimationFrame(() => f(k - 1)); f(n); })",
        n,
    )


def screenshot(page: Any, path: str | Path | None = None) -> np.ndarray:
    """The visible page as an ``(H, W, 3)`` uint8 RGB array; also written to ``path`` when given."""
    from PIL import Image

    png = page.screenshot()
    if path is not None:
        Path(path).write_bytes(png)
    with Image.open(io.BytesIO(png)) as im:
        return np.asarray(im.convert("RGB"))


def scene_region(page: Any, img: np.ndarray) -> np.ndarray:
    """``img`` with viser's control panel painted white, so only the 3D view's pixels count (same shape).

    The panel may be docked (a column) or floating (a box over the canvas); only its rectangle is blanked.
    """
    rect = page.evaluate(
        "() => { const p = document.querySelector('.mantine-Paper-root');"
        " if (!p) return null; const r = p.getBoundingClientRect(); return [r.left, r.top, r.right, r.bottom]; }"
    )
    out = img.copy()
    if rect:
        x0, y0, x1, y1 = (max(0, int(v)) for v in rect)
        out[y0 : max(y0, y1), x0 : max(x0, x1)] = 255
    return out


def color_mask(img: np.ndarray, rgb: tuple[int, int, int], tol: int = 40) -> np.ndarray:
    """Boolean ``(H, W)`` mask of the pixels within ``tol`` (per channel) of ``rgb``."""
    diff = np.abs(img.astype(np.int16) - np.asarray(rgb, dtype=np.int16))
    return np.asarray(np.all(diff <= tol, axis=-1))


def shade_mask(
    img: np.ndarray, rgb: tuple[int, int, int], tol: float = 0.18, min_value: int = 50
) -> np.ndarray:
    """Pixels of the hue of ``rgb`` whatever their lighting: colours compared after dividing by their maximum.

    A lit or shaded face of an orange mesh is a brighter or darker orange; white, grey and black pixels (and
    pixels darker than ``min_value``) never match a saturated colour.
    """
    px = img.astype(np.float64)
    v = px.max(axis=-1)
    ref = np.asarray(rgb, dtype=np.float64)
    ref = ref / ref.max()
    with np.errstate(invalid="ignore", divide="ignore"):
        norm = px / v[..., None]
    return np.asarray((v >= min_value) & np.all(np.abs(norm - ref) <= tol, axis=-1))


def reddish_mask(img: np.ndarray) -> np.ndarray:
    """Pixels that a person would call red, whatever the shading: R high, G and B much lower."""
    r, g, b = (img[..., k].astype(np.int16) for k in range(3))
    return np.asarray((r > 120) & (r - g > 70) & (r - b > 70))


def centroid(mask: np.ndarray) -> tuple[float, float] | None:
    """``(x, y)`` mean pixel position of a mask, or ``None`` when it is empty."""
    ys, xs = np.nonzero(mask)
    if xs.size == 0:
        return None
    return float(xs.mean()), float(ys.mean())


def page_state(page: Any, element: str = "robocal-status", attribute: str = "data-status") -> dict[str, Any] | None:
    """The JSON a robocal view publishes in its page, or ``None`` before it arrived.

    robocal's views put it in ``#robocal-status[data-status]`` (sent over viser's websocket with the scene
    updates, so a state that arrived means the scene updates before it arrived too); the sweep and auto pages
    also publish theirs (``#robocal-sweep[data-sweep]``, ``#robocal-autocal[data-autocal]``).
    """
    raw = page.evaluate(
        "([id, attr]) => { const e = document.getElementById(id); return e ? e.getAttribute(attr) : null; }",
        [element, attribute],
    )
    return None if raw is None else dict(json.loads(raw))


def shot(name: str, tmp_path: Path) -> Path:
    """Where a screenshot goes: ``$ROBOCAL_SCREENSHOT_DIR`` (to refresh docs/img) or the test's folder."""
    folder = os.environ.get("ROBOCAL_SCREENSHOT_DIR")
    return Path(folder) / name if folder else tmp_path / name


def wait_state(
    page: Any,
    predicate: Callable[[dict[str, Any]], bool],
    timeout_s: float = DEFAULT_TIMEOUT_S,
    what: str = "",
) -> dict[str, Any]:
    """Wait until the page state satisfies ``predicate``, then for the frames that draw it; return the state."""

    def probe() -> dict[str, Any] | None:
        s = page_state(page)
        return s if s is not None and predicate(s) else None

    state = wait_until(probe, timeout_s, what or "the page state")
    next_frames(page)
    return state


def gui_value(page: Any, label: str) -> str | None:
    """The value of the viser control labelled ``label`` (its text input), or ``None`` when absent."""
    value = page.evaluate(
        """(label) => {
        for (const l of document.querySelectorAll('label')) {
            if (l.textContent.trim() !== label) continue;
            const row = l.closest('.mantine-Flex-root');
            const input = row && row.querySelector('input');
            if (input) return input.value;
        }
        return null;
    }""",
        label,
    )
    return None if value is None else str(value)
