"""Fixtures of the auto-calibration and motion-guard tests."""

from __future__ import annotations

from collections.abc import Iterator

import pytest

from .guardlib import ArmHost


@pytest.fixture
def arm() -> Iterator[ArmHost]:
    """A simulated SO-101 follower in a process of its own (:class:`ArmHost`), closed after the test."""
    host = ArmHost("so101_follower")
    try:
        yield host
    finally:
        host.close()
