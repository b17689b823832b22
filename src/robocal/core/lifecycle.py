"""The two context-manager shapes of robocal's resources, written once.

* :class:`ClosesOnExit`: ``with bus:`` gives the open object and calls its ``close()`` at the end (buses,
  clients, sessions, a calibrated robot).
* :class:`StartsOnEnter`: ``with sim:`` calls ``start()`` (which returns the object) and ``stop()`` at the end
  (simulators and servers that run a thread).

Both end the resource also when the block raises (``__exit__`` returns None, so the exception propagates).
"""

from __future__ import annotations

from typing import Any, Protocol, TypeVar

__all__ = ["ClosesOnExit", "StartsOnEnter"]


class _Closable(Protocol):
    def close(self) -> None: ...


class _Startable(Protocol):
    def start(self) -> Any: ...

    def stop(self) -> None: ...


_C = TypeVar("_C", bound=_Closable)
_S = TypeVar("_S", bound=_Startable)


class ClosesOnExit:
    """Mixin of a class with ``close()``: ``with obj as o:`` gives ``obj`` and closes it at the end."""

    def __enter__(self: _C) -> _C:
        return self

    def __exit__(self: _Closable, *exc: object) -> None:
        self.close()


class StartsOnEnter:
    """Mixin of a class with ``start()`` and ``stop()``: ``with obj as o:`` starts it and stops it at the end."""

    def __enter__(self: _S) -> _S:
        self.start()
        return self

    def __exit__(self: _Startable, *exc: object) -> None:
        self.stop()
