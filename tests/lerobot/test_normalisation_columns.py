"""The column-group kernels (issue 27 item 7) give the bits of the whole-array formulas they replaced.

The reference below is the previous kernel's arithmetic (every mode computed on every column, then selected),
kept here as the specification: the same float operations in the same order, compared byte for byte on
random ranges, drive modes, mode layouts (runs and scattered columns), shapes, both ``compat`` and both
conventions.
"""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from robocal.core.lerobot.normalisation import normalize_array, unnormalize_array


def _reference(v, lo, hi, dm, mc, *, apply_drive_mode, compat, resolution, convention, inverse):  # type: ignore[no-untyped-def]
    dm = dm.astype(bool) & apply_drive_mode
    per_turn, dm_deg = (resolution - 1, np.zeros_like(dm)) if convention == "lerobot" else (resolution, dm)
    mid = (lo + hi) / 2
    if not inverse:
        frac = (np.minimum(hi, np.maximum(lo, v)) - lo) / (hi - lo)
        m100 = frac * 200 - 100
        m100 = np.where(dm, -m100, m100)
        p100 = frac * 100
        p100 = np.where(dm, 100 - p100, p100)
        deg = (v - mid) * 360 / per_turn
        deg = np.where(dm_deg, -deg, deg)
        return np.where(mc == 0, m100, np.where(mc == 1, p100, deg))
    vm = np.where(dm, -v, v)
    m100 = (np.minimum(100.0, np.maximum(-100.0, vm)) + 100) / 200 * (hi - lo) + lo
    vp = np.where(dm, 100 - v, v)
    p100 = np.minimum(100.0, np.maximum(0.0, vp)) / 100 * (hi - lo) + lo
    deg = np.where(dm_deg, -v, v) * per_turn / 360 + mid
    out = np.where(mc == 0, m100, np.where(mc == 1, p100, deg))
    out = np.trunc(out) if compat == "lerobot" else np.sign(out) * np.floor(np.abs(out) + 0.5)
    return out.astype(np.int64)


@pytest.mark.parametrize("seed", range(40))
def test_column_kernels_give_the_whole_array_formulas_bits(seed: int) -> None:
    rng = np.random.default_rng(seed)
    n = int(rng.integers(1, 8))
    lo = rng.integers(-200, 3000, n).astype(float)
    hi = lo + rng.integers(1, 4000, n)
    dm = rng.integers(0, 2, n)
    mc = np.full(n, seed % 3) if seed % 4 == 0 else rng.integers(0, 3, n)  # one mode, or runs and scattered
    shape = [(64, n), (n,), (3, 5, n)][seed % 3]
    raw = rng.integers(-5000, 9000, shape).astype(float) if seed % 2 else rng.uniform(-5000, 9000, shape)
    raw[..., 0] = lo[0]  # a range's own ends and its middle
    raw.reshape(-1, n)[-1] = hi
    values = rng.uniform(-400, 400, shape)
    values[..., ::2] = np.round(values[..., ::2])  # whole values: ±100, 0, 100 and the mode boundaries
    resolution = int(rng.choice([4096, 1024]))
    for adm, compat, convention in itertools.product([True, False], ["lerobot", "exact"], ["lerobot", "physical"]):
        kw = {"apply_drive_mode": adm, "compat": compat, "resolution": resolution, "convention": convention}
        got = normalize_array(raw, lo, hi, dm, mc, **kw)  # type: ignore[arg-type]
        want = _reference(raw, lo, hi, dm, mc, inverse=False, **kw)
        assert got.dtype == np.float64 and got.shape == raw.shape and got.tobytes() == want.tobytes(), kw
        back = unnormalize_array(values, lo, hi, dm, mc, **kw)  # type: ignore[arg-type]
        want_back = _reference(values, lo, hi, dm, mc, inverse=True, **kw)
        assert back.dtype == np.int64 and back.tobytes() == want_back.tobytes(), kw


def test_kernels_leave_the_callers_arrays_alone() -> None:
    raw = np.array([[1000.0, 2000.0, 3000.0]])
    lo, hi = np.array([900.0, 900.0, 900.0]), np.array([3100.0, 3100.0, 3100.0])
    before = (raw.copy(), lo.copy(), hi.copy())
    normalize_array(raw, lo, hi, [1, 0, 1], [0, 1, 2])
    unnormalize_array(raw / 100, lo, hi, [1, 0, 1], [0, 1, 2])
    assert all(np.array_equal(a, b) for a, b in zip((raw, lo, hi), before, strict=True))
