"""The explicit loop's step factor interpolation is numpy's ``interp`` to the last bit."""

from __future__ import annotations

import numba
import numpy as np

from rodnet.kernels.explicit import _interp


@numba.njit(cache=False)
def _many(xs, xp, fp):  # pragma: no cover - compiled
    out = np.empty_like(xs)
    for i in range(xs.shape[0]):
        out[i] = _interp(xs[i], xp, fp)
    return out


@numba.njit(cache=False)
def _many_numba(xs, xp, fp):  # pragma: no cover - compiled
    out = np.empty_like(xs)
    for i in range(xs.shape[0]):
        out[i] = np.interp(xs[i], xp, fp)   # what the loop called before
    return out


def test_interp_is_numpy_interp_bit_for_bit() -> None:
    rng = np.random.default_rng(3)
    xp = np.linspace(0.0, 0.985 * 2.0 * np.pi, 34)        # the rotation table's angles
    fp = 1.0 / np.sqrt(np.maximum(1.0, np.maximum.accumulate(1.0 + rng.random(34))))
    fp[5:9] = fp[5]                                          # flat stretches, as the table has
    xs = np.concatenate([rng.uniform(-1.0, 7.0, 5000), xp, [np.nan, np.inf, -np.inf, 0.0]])
    got = _many(xs, xp, fp)
    for want in (np.interp(xs, xp, fp), _many_numba(xs, xp, fp)):
        assert np.array_equal(got.view(np.int64), want.view(np.int64))   # every bit, NaN too
