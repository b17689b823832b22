"""A joint name that counts its equality comparisons: the scaling tests count them, as a quadratic name search
multiplies them by the joint count (time is measured by benchmarks, not by tests)."""

from __future__ import annotations


class CountingName(str):
    """A ``str`` whose ``==`` and ``!=`` add one to :attr:`comparisons` (reset it before counting)."""

    comparisons = 0
    __hash__ = str.__hash__

    def __eq__(self, other: object) -> bool:
        CountingName.comparisons += 1
        return str.__eq__(self, other)

    def __ne__(self, other: object) -> bool:
        return not self.__eq__(other)
