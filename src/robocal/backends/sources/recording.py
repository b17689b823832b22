"""Sources that replay a recording (CSV or rosbag2 ``JointState``), streamed in blocks or from memory."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from ...core.arrays import FloatArray
from ...errors import UsageError
from .spec import Sample

__all__ = ["ReplaySource", "StreamReplaySource"]



class StreamReplaySource:
    """Samples streamed from a recording (CSV or rosbag2) in blocks: memory does not grow with its length.

    The first block is read when the source is made, so a file that is malformed from its start is refused
    before the sweep begins; an error further on is raised when the reading reaches it (nothing is written).

    Args:
        joint_names: The joints in URDF order.
        recording: The opened :class:`robocal.backends.replay.Recording`.
        frame: ``"identity"`` or ``"motor"``.
    """

    def __init__(self, joint_names: Sequence[str], recording: Any, frame: str) -> None:
        self.joint_names = tuple(joint_names)
        self.frame = frame
        self.recording = recording
        self._t: FloatArray = np.empty(0)
        self._pos: FloatArray = np.empty((0, len(self.joint_names)))
        self._i = 0
        self._done = False
        try:  # the first block now: a malformed start of the file is refused before the sweep begins
            self._fill()
        except BaseException:
            self.close()
            raise

    def _fill(self) -> bool:
        """Make sure rows are buffered; False at the end of the recording."""
        while self._i >= len(self._t):
            if self._done:
                return False
            try:
                self._t, self._pos = next(self.recording)
            except StopIteration:
                self._done = True
                return False
            self._i = 0
        return True

    @property
    def exhausted(self) -> bool:
        """True after the last row (reads ahead one block to know)."""
        return not self._fill()

    @property
    def progress(self) -> tuple[int, int, str, int]:
        """``(done, total, unit, rows)``: bytes (CSV) or messages (bag) read of the total, rows delivered."""
        r = self.recording
        return int(r.done), int(r.total), str(r.unit), int(r.rows)

    def read(self) -> Sample | None:
        """The next row, or None at the end."""
        if not self._fill():
            return None
        i = self._i
        self._i += 1
        return Sample(float(self._t[i]), self._pos[i].copy())

    def read_block(self, max_rows: int = 1 << 30) -> tuple[FloatArray, FloatArray]:
        """Up to ``max_rows`` rows at once (at most one buffered block): ``(t (T,), positions (T, N))``."""
        if not self._fill():
            return self._t[:0], self._pos[:0]
        i = self._i
        j = min(len(self._t), i + max_rows)
        self._i = j
        return self._t[i:j], self._pos[i:j]

    def zero_sta(self) -> dict[str, int]:
        """A recording does not say."""
        return {}

    def begin_sweep(self) -> None:
        """Nothing to do."""

    def prompt_positive(self, joint: str) -> None:
        """A recording cannot answer prompts."""
        raise UsageError("--direction-check needs a live or simulated source, not a replay")

    def close(self) -> None:
        """Release the file."""
        self.recording.close()


class ReplaySource(StreamReplaySource):
    """Samples from a recording already loaded into memory: one block, read as a streamed one.

    Args:
        joint_names: The joints in URDF order.
        t_s: Shape ``(T,)``, s.
        positions_rad: Shape ``(T, N)`` in ``frame`` (NaN where a joint is missing).
        frame: ``"identity"`` or ``"motor"``.
    """

    def __init__(
        self, joint_names: Sequence[str], t_s: FloatArray, positions_rad: FloatArray, frame: str
    ) -> None:
        from ..replay import Recording

        self.t_s = t_s
        self.positions_rad = positions_rad
        blocks = iter([(t_s, positions_rad)])
        super().__init__(joint_names, Recording(Path("<memory>"), "memory", 0, "rows", blocks), frame)
