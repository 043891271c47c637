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

import numpy as np
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]

RELATIVE_TOLERANCE = 1e-12
"""An eigenvalue below ``-RELATIVE_TOLERANCE`` times the block's largest counts as negative."""


def convex_blocks(K: FloatArray) -> FloatArray:
    """``K`` (E, k, k) with every block whose symmetric part has a negative eigenvalue replaced
    by ``V max(Lambda, 0) V^T`` of that part (a new array where any block changes)."""
    if len(K) == 0:
        return K
    sym = 0.5 * (K + K.transpose(0, 2, 1))
    w = np.linalg.eigvalsh(sym)
    bad = np.flatnonzero(w[:, 0] < -RELATIVE_TOLERANCE * np.abs(w).max(axis=1))
    if not len(bad):
        return K
    w_bad, V = np.linalg.eigh(sym[bad])
    out = K.copy()
    out[bad] = np.einsum("eij,ej,ekj->eik", V, np.maximum(w_bad, 0.0), V)
    return out
