"""Helpers for the sweep tests: the Lite URDF written into tmp_path and source injection."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest

from robocal.backends.sim.lite import LITE_JOINTS, SimLite, lite_urdf_text
from robocal.backends.sources import JointSpec, Sample, SimLiteSource

NAMES = [j.name for j in LITE_JOINTS]
DIRS = {j.name: j.direction for j in LITE_JOINTS}


@pytest.fixture
def urdf(tmp_path: Path) -> Path:
    p = tmp_path / "lite.urdf"
    p.write_text(lite_urdf_text())
    return p


def sim_opener(sim: SimLite) -> Callable[..., SimLiteSource]:
    """An ``open_source_fn`` that serves ``sim`` (restarted on every call)."""

    def open_fn(spec: Any, joints: list[JointSpec], **_: Any) -> SimLiteSource:
        sim.start()
        return SimLiteSource(joints, sim)

    return open_fn


class Recorder:
    """Wraps a source, keeps every sample, optionally raises KeyboardInterrupt at read ``n`` and on close."""

    def __init__(self, inner: Any, interrupt_at: int | None = None, interrupt_close: bool = False) -> None:
        self.inner = inner
        self.samples: list[Sample] = []
        self.interrupt_at = interrupt_at
        self.interrupt_close = interrupt_close
        self.joint_names = inner.joint_names
        self.frame = inner.frame
        self.closed = 0

    @property
    def exhausted(self) -> bool:
        return bool(self.inner.exhausted)

    def read(self) -> Sample | None:
        if self.interrupt_at is not None and len(self.samples) == self.interrupt_at:
            raise KeyboardInterrupt
        s = self.inner.read()
        if s is not None:
            self.samples.append(s)
        return s

    def zero_sta(self) -> dict[str, int]:
        return dict(self.inner.zero_sta())

    def begin_sweep(self) -> None:
        self.inner.begin_sweep()

    def prompt_positive(self, joint: str) -> None:
        self.inner.prompt_positive(joint)

    def close(self) -> None:
        self.closed += 1
        self.inner.close()
        if self.interrupt_close and self.closed == 1:
            raise KeyboardInterrupt


def recording_opener(sim: SimLite, **kw: Any) -> tuple[Callable[..., Recorder], list[Recorder]]:
    made: list[Recorder] = []
    base = sim_opener(sim)

    def open_fn(spec: Any, joints: list[JointSpec], **k: Any) -> Recorder:
        r = Recorder(base(spec, joints, **k), **kw)
        made.append(r)
        return r

    return open_fn, made


class Helpers:
    names = NAMES
    dirs = DIRS
    sim_opener = staticmethod(sim_opener)
    recording_opener = staticmethod(recording_opener)
    Recorder = Recorder


@pytest.fixture
def h() -> type[Helpers]:
    return Helpers
