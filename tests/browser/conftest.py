"""Fixtures for the browser tests: one headless Chromium per test module, a fresh page per test.

The tests here skip, with the reason, only when no Chromium binary is on the machine (``.ci/run`` installs the
distribution's ``chromium`` package when it can). Playwright and viser come with ``pip install -e '.[test]'``;
when they are missing the tests fail, because that is a broken install, not a machine without a browser.
"""

from __future__ import annotations

import sys
import tempfile
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

_HERE = str(Path(__file__).parent)
if _HERE not in sys.path:
    sys.path.insert(0, _HERE)

import browserlib  # noqa: E402


@pytest.fixture(scope="session")
def chromium_path() -> str:
    path = browserlib.find_chromium()
    if path is None:
        pytest.skip(
            "no Chromium on this machine (install the distribution's 'chromium' package, as .ci/run does, "
            "or set ROBOCAL_CHROMIUM)"
        )
    return path


@pytest.fixture(scope="module")
def browser(chromium_path: str) -> Iterator[Any]:
    # Module scope, not session: Playwright's sync API keeps an asyncio loop running in the main thread while
    # it is open, and later tests that call asyncio.run() would fail ("cannot be called from a running event
    # loop"). One Chromium per test module costs a few seconds.
    from playwright.sync_api import sync_playwright

    with tempfile.TemporaryDirectory(prefix="robocal-chromium-") as profile, sync_playwright() as pw:
        # A persistent context is how Playwright takes a --user-data-dir: a fresh, empty profile per session.
        context = pw.chromium.launch_persistent_context(
            profile,
            executable_path=chromium_path,
            headless=True,
            args=browserlib.CHROMIUM_ARGS,
            viewport=browserlib.VIEWPORT,
            device_scale_factor=1,
        )
        try:
            yield context
        finally:
            context.close()


@pytest.fixture
def page(browser: Any) -> Iterator[Any]:
    p = browser.new_page()
    p.set_viewport_size(browserlib.VIEWPORT)
    try:
        yield p
    finally:
        p.close()
