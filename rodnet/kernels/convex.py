"""Element blocks made convex for Newton's method (projected Newton).

Where a step's potential is not convex (a rod element whose section stands more than 45 degrees
off its chord, a compressed element under shear), Newton's exact matrix can be indefinite and
its correction climb the potential instead of descending it. Replacing every indefinite element
block by the projection of its symmetric part on the positive semidefinite matrices gives a
matrix whose symmetric part is positive definite once the mass term is added, so its
correction descends (Teran, Sifakis, Irving and Fedkiw 2005, "Robust quasistatic finite
elements and flesh simulation"; the projected Newton of incremental-potential integrators).
Blocks whose symmetric part is positive semidefinite are left as they are (also their
non-symmetric part), so near a convex solution the matrix is the exact one.
"""

from __future__ import annotations

import math

import numba
import numpy as np
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]

RELATIVE_TOLERANCE = 1e-12
"""A block counts as indefinite when its symmetric part plus ``RELATIVE_TOLERANCE`` times its
Frobenius norm has no Cholesky factor (an eigenvalue below about ``-RELATIVE_TOLERANCE`` times
the largest)."""


def convex_blocks(K: FloatArray) -> FloatArray:
    """``K`` (E, k, k) with every block whose symmetric part is indefinite replaced by
    ``V max(Lambda, 0) V^T`` of that part (a new array where any block changes). Blocks are
    told apart by a compiled Cholesky test; only the indefinite ones are decomposed."""
    if len(K) == 0:
        return K
    sym = 0.5 * (K + K.transpose(0, 2, 1))
    bad = np.flatnonzero(indefinite(np.ascontiguousarray(sym), RELATIVE_TOLERANCE))
    if not len(bad):
        return K
    w_bad, V = np.linalg.eigh(sym[bad])
    out = K.copy()
    out[bad] = np.einsum("eij,ej,ekj->eik", V, np.maximum(w_bad, 0.0), V)
    return out


@numba.njit(cache=True)
def indefinite(sym, relative):  # pragma: no cover - compiled
    """(E,) bool: whether ``sym[e] + relative |sym[e]|_F I`` (E, k, k symmetric) has no
    Cholesky factor."""
    E, k = sym.shape[0], sym.shape[1]
    out = np.zeros(E, np.bool_)
    L = np.empty((k, k))
    for e in range(E):
        norm = 0.0
        for i in range(k):
            for j in range(k):
                norm += sym[e, i, j] * sym[e, i, j]
        shift = relative * math.sqrt(norm)
        for j in range(k):
            d = sym[e, j, j] + shift
            for m in range(j):
                d -= L[j, m] * L[j, m]
            if not d > 0.0:        # also NaN
                out[e] = True
                break
            d = math.sqrt(d)
            L[j, j] = d
            for i in range(j + 1, k):
                a = sym[e, i, j]
                for m in range(j):
                    a -= L[i, m] * L[j, m]
                L[i, j] = a / d
    return out
