"""Sparse LU of matrices whose sparsity pattern is symmetric and fixed, as Newton's iteration
matrices of nets are: the ordering and the symbolic factorisation are computed once per
pattern, every later factorisation is a compiled numeric pass.

Why: on nets SuperLU spends most of its time in set-up rather than arithmetic (a Cosserat net of
11,463 unknowns: 15 ms per factorisation for a factor of about 1e5 entries). No pivoting is done,
which suits Newton's iteration matrices ``M / (beta h^2) + ... + K``: their symmetric part is
dominated by the positive mass and stiffness terms. A pivot that is not clearly nonzero makes
:meth:`StaticPatternLU.factorize` return False and the caller falls back to a pivoting LU.

The numeric pass runs over 3 x 3 blocks, a node's translations or rotations: nine products per
index looked up instead of one (validation/benchmarks/results/static_lu.md).
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
    """LU without pivoting, in 3 x 3 blocks, for every matrix with one symmetric CSR pattern.

    The unknowns are grouped three by three in their order (a node's translations or rotations
    when the supports remove whole triples; any grouping gives the same factors, a misaligned
    one only more fill), the last group padded with unit diagonal entries.

    Parameters
    ----------
    matrix : csr_matrix (n, n)
        A matrix with the pattern (its values are not used). The pattern must be structurally
        symmetric.

    Raises
    ------
    ValueError
        When the pattern is not symmetric.
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
        N = -(-n // 3)
        self.n_blocks = N
        rows = np.repeat(np.arange(n, dtype=np.int64), np.diff(matrix.indptr))
        cols = matrix.indices.astype(np.int64)
        # the block pattern, with every diagonal block
        keys = np.unique(np.concatenate([(rows // 3) * N + cols // 3,
                                         np.arange(N, dtype=np.int64) * (N + 1)]))
        blocks = sp.csc_matrix((np.ones(len(keys)), (keys // N, keys % N)), shape=(N, N))
        # fill-reducing order: SuperLU's minimum degree on the block pattern, computed once
        ordering = spla.splu(blocks + (N + 1.0) * sp.identity(N, format="csc"),
                             permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0,
                             options={"SymmetricMode": True})
        order = np.argsort(ordering.perm_c)            # new block -> old block
        rank = np.empty(N, np.int64)
        rank[order] = np.arange(N)
        new_rows, new_cols = rank[keys // N], rank[keys % N]
        perm = np.lexsort((new_cols, new_rows))
        b_cols = new_cols[perm]
        b_rows = new_rows[perm]
        b_ptr = np.concatenate([[0], np.cumsum(np.bincount(b_rows, minlength=N))]).astype(np.int64)
        self.b_ptr, self.b_cols = b_ptr, b_cols
        key = b_rows * N + b_cols                      # ascending (row-major, sorted)
        self.transpose = np.searchsorted(key, b_cols * N + b_rows)
        self.diagonal = np.searchsorted(key, np.arange(N) * (N + 1))
        # the unknowns in elimination order (old numbering; n and above: padding)
        scalar = 3 * order[:, None] + np.arange(3)                     # (N, 3)
        self.scalar_rows = np.where(scalar < n, scalar, -1)
        real = np.flatnonzero(scalar.ravel() < n)
        self._real, self._real_order = real, scalar.ravel()[real]   # where each unknown sits
        self._scalar_ptr = np.asarray(matrix.indptr, np.int64)
        # where every scalar entry of every block is found in the CSR data
        canonical_keys = rows * n + cols
        sorter = np.argsort(canonical_keys)
        source = np.full((len(key), 3, 3), -1, np.int64)
        old_r, old_c = order[b_rows], order[b_cols]
        for a in range(3):
            for b in range(3):
                r, c = 3 * old_r + a, 3 * old_c + b
                inside = (r < n) & (c < n)
                want = np.where(inside, r * n + c, -1)
                at = np.minimum(np.searchsorted(canonical_keys, want, sorter=sorter),
                                len(sorter) - 1)
                found = inside & (canonical_keys[sorter[at]] == want)
                source[:, a, b] = np.where(found, sorter[at], -1)
                if a == b:   # the padding unknowns' unit diagonal
                    source[:, a, b] = np.where((b_rows == b_cols) & (r >= n), -2,
                                               source[:, a, b])
        self.source = source
        parent = elimination_tree(N, b_ptr, b_cols)
        self.reach_ptr, self.reach = row_reaches(N, b_ptr, b_cols, parent)
        reach_rows = np.repeat(np.arange(N), np.diff(self.reach_ptr))
        by_column = np.lexsort((reach_rows, self.reach))
        self.col_rows = reach_rows[by_column].astype(np.int64)
        self.col_ptr = np.concatenate([[0], np.cumsum(np.bincount(self.reach, minlength=N))]
                                      ).astype(np.int64)
        size = len(self.reach)
        self.lower, self.upper = np.empty((size, 3, 3)), np.empty((size, 3, 3))
        self.pivot_lu = np.empty((N, 3, 3))
        self._work_u, self._work_l = np.zeros((N, 3, 3)), np.zeros((N, 3, 3))
        self._fill = np.zeros(N, np.int64)
        self._big = np.zeros(n)
        self.factor_entries = 9 * (2 * size + N)
        """Entries of L and U together, blocks counted whole (the padding's included)."""

    def matches(self, matrix: sp.csr_matrix) -> bool:
        """Whether ``matrix`` has this object's pattern."""
        return same_pattern((self.indptr, self.indices), matrix)

    def factorize(self, matrix: sp.csr_matrix) -> bool:
        """Numeric factorisation of ``matrix`` (this pattern); False when a pivot is (nearly)
        zero or not finite, and the factors must not be used."""
        bad = factor_numeric(self.n_blocks, self.b_ptr, self.b_cols, self.transpose,
                             self.diagonal, self.source, np.ascontiguousarray(matrix.data),
                             self._scalar_ptr, self.scalar_rows,
                             self.reach_ptr, self.reach, self.col_ptr, self.col_rows, self.lower,
                             self.upper, self.pivot_lu, self._work_u, self._work_l, self._fill,
                             self._big)
        return bad < 0

    def solve(self, rhs: FloatArray) -> FloatArray:
        """``A^-1 rhs`` for the last factorised matrix; rhs (n,)."""
        x = np.zeros(3 * self.n_blocks)
        x[self._real] = rhs[self._real_order]
        solve_factored(self.col_ptr, self.col_rows, self.lower, self.upper, self.pivot_lu,
                       x.reshape(-1, 3))
        out = np.empty(self.n)
        out[self._real_order] = x[self._real]
        return out
