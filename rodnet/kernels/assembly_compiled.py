"""Compiled scatter of element blocks into the storage of a global matrix.

Used by :meth:`rodnet.assembly.SparsityPattern.iteration_matrix`: one pass over the element blocks
forms Newton's iteration matrix ``a C + b K T`` entry by entry and adds it where the pattern says,
so no intermediate global matrices are built.
"""

from __future__ import annotations

import numba


@numba.njit(cache=True)
def add_transformed_blocks(out, positions, a, C, b, K, triples,
                           transforms):  # pragma: no cover - compiled
    """``out[positions[e, i, j]] += a C[e, i, j] + b (K[e] T_e)[i, j]`` wherever the position is
    not negative, with ``T_e = blockdiag(transforms[triples[e, 0]], transforms[triples[e, 1]], ...)``.

    Parameters
    ----------
    out : (S,) float
        Flat matrix storage, added to in place.
    positions : (E, k, k) int
        Where each block entry goes in ``out``; -1 drops it (a supported DOF).
    a, b : float
        Weights of the ``C`` and ``K T`` blocks.
    C, K : (E, k, k) float
        Element blocks, ``k`` a multiple of 3.
    triples : (E, k // 3) int
        For each group of three block columns, the transform acting on it.
    transforms : (P, 3, 3) float
        3 x 3 right factors (identity for most).
    """
    for e in range(K.shape[0]):
        for m in range(triples.shape[1]):
            T = transforms[triples[e, m]]
            c = 3 * m
            for i in range(K.shape[1]):
                k0, k1, k2 = K[e, i, c], K[e, i, c + 1], K[e, i, c + 2]
                for j in range(3):
                    p = positions[e, i, c + j]
                    if p >= 0:
                        out[p] += a * C[e, i, c + j] + b * (k0 * T[0, j] + k1 * T[1, j]
                                                             + k2 * T[2, j])
