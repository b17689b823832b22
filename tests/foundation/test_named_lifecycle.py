"""core/named.py (look-up by name) and core/lifecycle.py (the two ``with`` shapes), as their users rely on them."""

from __future__ import annotations

from dataclasses import dataclass

import pytest

from robocal.core.lifecycle import ClosesOnExit, StartsOnEnter
from robocal.core.named import find_named, get_named


@dataclass(frozen=True)
class _Joint:
    name: str
    value: int


JOINTS = (_Joint("shoulder", 1), _Joint("elbow", 2), _Joint("elbow", 3))


def test_find_named_gives_the_first_match_or_none() -> None:
    assert find_named(JOINTS, "elbow") == _Joint("elbow", 2)
    assert find_named(JOINTS, "wrist") is None
    assert find_named(iter(JOINTS), "shoulder") == _Joint("shoulder", 1)


def test_get_named_raises_key_error_naming_the_key() -> None:
    assert get_named(JOINTS, "shoulder").value == 1
    with pytest.raises(KeyError) as err:
        get_named(JOINTS, "Elbow")
    assert err.value.args == ("Elbow",)


class _Bus(ClosesOnExit):
    def __init__(self) -> None:
        self.events: list[str] = []

    def close(self) -> None:
        self.events.append("close")


class _Sim(StartsOnEnter):
    def __init__(self) -> None:
        self.events: list[str] = []

    def start(self) -> _Sim:
        self.events.append("start")
        return self

    def stop(self) -> None:
        self.events.append("stop")


def test_closes_on_exit_gives_itself_and_closes_also_on_an_error() -> None:
    bus = _Bus()
    with bus as b:
        assert b is bus
        assert bus.events == []
    assert bus.events == ["close"]
    with pytest.raises(RuntimeError, match="boom"), bus:
        raise RuntimeError("boom")
    assert bus.events == ["close", "close"]


def test_starts_on_enter_starts_then_stops_also_on_an_error() -> None:
    sim = _Sim()
    with sim as s:
        assert s is sim
        assert sim.events == ["start"]
    assert sim.events == ["start", "stop"]
    with pytest.raises(KeyboardInterrupt), sim:
        raise KeyboardInterrupt
    assert sim.events == ["start", "stop", "start", "stop"]
