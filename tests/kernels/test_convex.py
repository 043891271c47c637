"""Projected Newton's element blocks: indefinite blocks projected on the positive semidefinite
ones, the others left exactly as they are."""

from __future__ import annotations

import numpy as np

from rodnet.kernels.convex import convex_blocks, indefinite


def _blocks(rng: np.random.Generator, n: int, k: int, negative: bool) -> np.ndarray:
    """Blocks ``A + N`` with ``A`` symmetric of known spectrum (rank-deficient, as an element's
    stiffness with its rigid motions) and ``N`` skew (the tangent's non-symmetric part)."""
    out = np.empty((n, k, k))
    for e in range(n):
        Q, _ = np.linalg.qr(rng.standard_normal((k, k)))
        w = np.concatenate([np.zeros(k // 2), rng.uniform(1.0, 1e6, k - k // 2)])
        if negative:
            w[0] = -rng.uniform(1e-3, 1e3)
        S = rng.standard_normal((k, k))
        out[e] = Q @ np.diag(w) @ Q.T + (S - S.T)
    return out


def test_cholesky_test_finds_exactly_the_blocks_with_a_negative_eigenvalue() -> None:
    rng = np.random.default_rng(3)
    K = np.concatenate([_blocks(rng, 40, 12, False), _blocks(rng, 40, 12, True)])
    sym = 0.5 * (K + K.transpose(0, 2, 1))
    expected = np.linalg.eigvalsh(sym)[:, 0] < -1e-9 * np.abs(np.linalg.eigvalsh(sym)).max(axis=1)
    np.testing.assert_array_equal(indefinite(np.ascontiguousarray(sym), 1e-12), expected)
    assert expected.sum() == 40


def test_convex_blocks_project_indefinite_blocks_and_keep_the_others() -> None:
    rng = np.random.default_rng(4)
    good, bad = _blocks(rng, 10, 12, False), _blocks(rng, 10, 12, True)
    out = convex_blocks(np.concatenate([good, bad]))
    np.testing.assert_array_equal(out[:10], good)          # non-symmetric part kept too
    sym_bad = 0.5 * (bad + bad.transpose(0, 2, 1))
    w, V = np.linalg.eigh(sym_bad)
    for e in range(10):
        projected = V[e] @ np.diag(np.maximum(w[e], 0.0)) @ V[e].T
        np.testing.assert_allclose(out[10 + e], projected, atol=1e-9 * np.abs(w[e]).max())
        assert np.linalg.eigvalsh(out[10 + e]).min() > -1e-9 * np.abs(w[e]).max()
