from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from robocal.dataset import StatAccumulator
from robocal.dataset._stats import episode_stats


@pytest.mark.slow
@given(
    st.lists(st.integers(1, 40), min_size=1, max_size=6),
    st.integers(0, 2**31 - 1),
    st.booleans(),
)
def test_episode_stats_equal_numpy(lengths: list[int], seed: int, equal: bool) -> None:
    if equal:
        lengths = [lengths[0]] * len(lengths)
    rng = np.random.default_rng(seed)
    n = sum(lengths)
    values = rng.normal(size=(n, 3)).astype(np.float32).astype(np.float64)
    episodes = np.repeat(np.arange(len(lengths), dtype=np.int64) + 7, lengths)
    stats = episode_stats(episodes, {"action": values})
    start = 0
    for e, length in enumerate(lengths):
        seg = values[start : start + length]
        acc = stats[e + 7]["action"]
        assert acc.count == length
        np.testing.assert_array_equal(acc.min, seg.min(axis=0))
        np.testing.assert_array_equal(acc.max, seg.max(axis=0))
        np.testing.assert_allclose(acc.mean, seg.mean(axis=0), rtol=1e-12, atol=1e-15)
        np.testing.assert_allclose(acc.std, seg.std(axis=0), rtol=1e-9, atol=1e-12)
        for name, f in (("q01", 0.01), ("q50", 0.5), ("q99", 0.99)):
            np.testing.assert_array_equal(acc.get(name), np.quantile(seg, f, axis=0))
        start += length


def test_merge_is_pooled() -> None:
    x = np.arange(12, dtype=np.float64).reshape(6, 2)
    merged = StatAccumulator.of(x[:2]).merge(StatAccumulator.of(x[2:]))
    assert merged.count == 6
    np.testing.assert_allclose(merged.mean, [5.0, 6.0])
    np.testing.assert_allclose(merged.std, x.std(axis=0))
    assert merged.get("min") == [0.0, 1.0] and merged.get("max") == [10.0, 11.0]
    assert merged.get("count") == [6]
    assert merged.get("q42") is None
