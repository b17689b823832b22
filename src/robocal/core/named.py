"""Look up an item by its ``name`` in a sequence of named values (joints of a profile, a sweep, a run)."""

from __future__ import annotations

from collections.abc import Iterable
from typing import Protocol, TypeVar

__all__ = ["Named", "find_named", "get_named"]


class Named(Protocol):
    """Anything with a ``name`` (a joint, a motor, a result row)."""

    @property
    def name(self) -> str:
        """The item's name."""
        ...


_N = TypeVar("_N", bound=Named)


def find_named(items: Iterable[_N], name: str) -> _N | None:
    """The first of ``items`` whose ``name`` is ``name``, or None when none is.

    Args:
        items: Named values, searched in order.
        name: The exact name looked for.
    """
    for item in items:
        if item.name == name:
            return item
    return None


def get_named(items: Iterable[_N], name: str) -> _N:
    """The first of ``items`` whose ``name`` is ``name`` (for ``__getitem__``).

    Raises:
        KeyError: No item has that name (the key is ``name``).
    """
    item = find_named(items, name)
    if item is None:
        raise KeyError(name)
    return item
