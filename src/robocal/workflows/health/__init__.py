"""Calibration health jobs (issue 30): ``health watch`` (the live monitor on a device, read-only)."""

from __future__ import annotations

from .watch import WatchRequest, WatchResult, watch

__all__ = ["WatchRequest", "WatchResult", "watch"]
