"""Sparse LU of matrices whose sparsity pattern is symmetric and fixed, as Newton's iteration
matrices of nets are: the ordering and the symbolic factorisation are computed once per
pattern, every later factorisation is a compiled numeric pass.

Why: on nets SuperLU spends most of its time in set-up rather than arithmetic (a Cosserat net of
11,463 unknowns: 15 ms per factorisation for a factor of about 1e5 entries). No pivoting is done,
which suits Newton's iteration matrices ``M / (beta h^2) + ... + K``: their symmetric part is
dominated by the positive mass and stiffness terms. A pivot that is not clearly nonzero makes
:meth:`StaticPatternLU.factorize` return False and the caller falls back to a pivoting LU.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla
from numpy.typing import NDArray

from rodnet.kernels.sparse_lu_compiled import (elimination_tree, factor_numeric, row_reaches,
                                               solve_factored)

FloatArray = NDArray[np.float64]


Pattern = tuple[NDArray[np.int32], NDArray[np.int32]]
"""A CSR sparsity pattern: ``(indptr, indices)``."""


def same_pattern(pattern: Pattern | None, matrix: sp.csr_matrix) -> bool:
    """Whether the CSR ``matrix`` has ``pattern`` (the same index arrays, or equal ones)."""
    if pattern is None:
        return False
    indptr, indices = pattern
    if matrix.indptr is indptr and matrix.indices is indices:
        return True
    return np.array_equal(matrix.indptr, indptr) and np.array_equal(matrix.indices, indices)


class StaticPatternLU:
    """LU without pivoting for every matrix with one symmetric CSR pattern.

    Parameters
    ----------
    matrix : csr_matrix (n, n)
        A matrix with the pattern (its values choose nothing but are used for the ordering
        call). The pattern must be structurally symmetric.

    Raises
    ------
    ValueError
        When the pattern is not symmetric or lacks a diagonal entry.
    """

    def __init__(self, matrix: sp.csr_matrix) -> None:
        n = matrix.shape[0]
        self.n = n
        self.indptr, self.indices = matrix.indptr, matrix.indices
        structure = sp.csr_matrix((np.arange(1, matrix.nnz + 1, dtype=float), matrix.indices,
                                   matrix.indptr), shape=matrix.shape)
        transposed = structure.T.tocsr()
        transposed.sort_indices()
        canonical = structure.copy()
        canonical.sort_indices()
        if (not np.array_equal(canonical.indptr, transposed.indptr)
                or not np.array_equal(canonical.indices, transposed.indices)):
            raise ValueError("StaticPatternLU needs a structurally symmetric pattern")
        # fill-reducing order: SuperLU's minimum degree on A + A^T, computed once
        pattern = sp.csc_matrix((np.ones(matrix.nnz), matrix.indices, matrix.indptr),
                                shape=matrix.shape)        # A^T's pattern: the same
        ordering = spla.splu(pattern + (n + 1.0) * sp.identity(n, format="csc"),
                             permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0,
                             options={"SymmetricMode": True})
        order = np.argsort(ordering.perm_c)            # new index -> old index
        rank = np.empty(n, np.int64)
        rank[order] = np.arange(n)
        self.order = order
        # B = A[order][:, order] in CSR with sorted columns; where each of A's entries goes
        rows = np.repeat(np.arange(n), np.diff(matrix.indptr))
        new_rows, new_cols = rank[rows], rank[matrix.indices]
        perm = np.lexsort((new_cols, new_rows))      # B entry q takes A entry perm[q]
        self.source = perm
        b_cols = new_cols[perm].astype(np.int64)
        b_ptr = np.concatenate([[0], np.cumsum(np.bincount(new_rows, minlength=n))]).astype(np.int64)
        self.b_ptr, self.b_cols = b_ptr, b_cols
        b_rows = np.repeat(np.arange(n), np.diff(b_ptr))
        key = b_rows * n + b_cols                    # ascending (row-major, sorted)
        self.transpose = np.searchsorted(key, b_cols * n + b_rows)
        diagonal = np.searchsorted(key, np.arange(n) * (n + 1))
        if np.any(diagonal >= len(key)) or np.any(key[np.minimum(diagonal, len(key) - 1)]
                                                  != np.arange(n) * (n + 1)):
            raise ValueError("StaticPatternLU needs every diagonal entry in the pattern")
        self.diagonal = diagonal
        parent = elimination_tree(n, b_ptr, b_cols)
        self.reach_ptr, self.reach = row_reaches(n, b_ptr, b_cols, parent)
        reach_rows = np.repeat(np.arange(n), np.diff(self.reach_ptr))
        by_column = np.lexsort((reach_rows, self.reach))
        self.col_rows = reach_rows[by_column].astype(np.int64)
        self.col_ptr = np.concatenate([[0], np.cumsum(np.bincount(self.reach, minlength=n))]
                                      ).astype(np.int64)
        size = len(self.reach)
        self.lower, self.upper = np.empty(size), np.empty(size)
        self.pivots = np.empty(n)
        self._work_u, self._work_l = np.zeros(n), np.zeros(n)
        self._fill = np.zeros(n, np.int64)
        self.factor_entries = 2 * size + n
        """Entries of L and U together (the diagonal of L not counted)."""

    def matches(self, matrix: sp.csr_matrix) -> bool:
        """Whether ``matrix`` has this object's pattern."""
        return same_pattern((self.indptr, self.indices), matrix)

    def factorize(self, matrix: sp.csr_matrix) -> bool:
        """Numeric factorisation of ``matrix`` (this pattern); False when a pivot is (nearly)
        zero or not finite, and the factors must not be used."""
        data = np.ascontiguousarray(matrix.data[self.source])
        bad = factor_numeric(self.n, self.b_ptr, self.b_cols, data, self.transpose, self.diagonal,
                             self.reach_ptr, self.reach, self.col_ptr, self.col_rows, self.lower,
                             self.upper, self.pivots, self._work_u, self._work_l, self._fill)
        if bad >= 0:
            self._work_u[:] = 0.0
            self._work_l[:] = 0.0
            return False
        return True

    def solve(self, rhs: FloatArray) -> FloatArray:
        """``A^-1 rhs`` for the last factorised matrix; rhs (n,)."""
        x = np.array(rhs[self.order], dtype=float)
        solve_factored(self.col_ptr, self.col_rows, self.lower, self.upper, self.pivots, x)
        out = np.empty_like(x)
        out[self.order] = x
        return out
