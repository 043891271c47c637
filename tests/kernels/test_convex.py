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


def test_a_share_of_the_masses_keeps_the_blocks_it_outweighs_and_the_sum_definite() -> None:
    """With a share ``d`` of the masses' diagonal per block: a block whose negative curvature
    ``d`` outweighs keeps its exact entries (and is projected without it); one that it does not
    becomes ``P - diag(d)`` with ``P`` the projection of ``sym + diag(d)``, so the blocks plus
    their shares are positive semidefinite, and assembled over shared DOFs with twice the
    shares (the rest of the diagonal) the matrix is positive definite."""
    rng = np.random.default_rng(5)
    k = 12
    mild = _blocks(rng, 6, k, True)      # negative eigenvalue down to -1e3
    share = np.full((6, k), 2e3)         # outweighs it
    np.testing.assert_array_equal(convex_blocks(mild, share), mild)
    assert not np.array_equal(convex_blocks(mild), mild)
    small = np.full((6, k), 1e-6)        # does not outweigh it
    out = convex_blocks(mild, small)
    sym = 0.5 * (mild + mild.transpose(0, 2, 1)) + np.einsum("ek,kj->ekj", small, np.eye(k))
    w, V = np.linalg.eigh(sym)
    for e in range(6):
        expected = V[e] @ np.diag(np.maximum(w[e], 0.0)) @ V[e].T - np.diag(small[e])
        np.testing.assert_allclose(out[e], expected, atol=1e-9 * np.abs(w[e]).max())
    # a chain of the blocks sharing 6 DOFs at each joint, with each DOF's diagonal twice the
    # sum of its blocks' shares: symmetric part positive definite
    n = 6 * (len(out) + 1)
    A = np.zeros((n, n))
    diagonal = np.zeros(n)
    for e in range(len(out)):
        dofs = np.arange(6 * e, 6 * e + k)
        A[np.ix_(dofs, dofs)] += out[e]
        diagonal[dofs] += 2.0 * small[e]
    A += np.diag(diagonal)
    assert np.linalg.eigvalsh(0.5 * (A + A.T)).min() > 0.0
