"""Compiled kernels of :class:`rodnet.sparse_lu.StaticPatternLU`: the symbolic analysis and the
numeric LU without pivoting of a matrix with a symmetric sparsity pattern.

The matrix ``B`` (already in elimination order) is given in CSR form. Its pattern is symmetric,
so ``L`` (unit lower) and ``U^T`` have the same pattern, that of the Cholesky factor of the
pattern: column ``j`` of ``L`` holds the rows ``k > j`` whose row-reach in the elimination tree
contains ``j`` (Davis, *Direct Methods for Sparse Linear Systems*, 2006, sections 4.1-4.3).
The numeric factorisation is "up-looking": row ``k`` of ``L`` and column ``k`` of ``U`` come from
two sparse triangular solves over that reach (the LU analogue of Davis' ``cs_chol``).
"""

from __future__ import annotations

import numba
import numpy as np


@numba.njit(cache=True)
def elimination_tree(n, indptr, indices):  # pragma: no cover - compiled
    """Parent (n,) of every column in the elimination tree of a symmetric pattern (-1 for a
    root), from the entries ``j < k`` of each row ``k`` (Davis, ``cs_etree``, path compression)."""
    parent = np.full(n, -1, np.int64)
    ancestor = np.full(n, -1, np.int64)
    for k in range(n):
        for p in range(indptr[k], indptr[k + 1]):
            i = indices[p]
            while i != -1 and i < k:
                nxt = ancestor[i]
                ancestor[i] = k
                if nxt == -1:
                    parent[i] = k
                i = nxt
    return parent


@numba.njit(cache=True)
def row_reaches(n, indptr, indices, parent):  # pragma: no cover - compiled
    """The reach of every row: the columns ``j < k`` with ``L[k, j] != 0``, sorted ascending.

    Returns
    -------
    reach_ptr : (n + 1,) int
    reach : (nnz(L) - n,) int
        Row ``k``'s columns are ``reach[reach_ptr[k]:reach_ptr[k + 1]]``.
    """
    mark = np.full(n, -1, np.int64)
    counts = np.zeros(n + 1, np.int64)
    # first pass: sizes
    for k in range(n):
        mark[k] = k
        c = 0
        for p in range(indptr[k], indptr[k + 1]):
            i = indices[p]
            while i != -1 and i < k and mark[i] != k:
                mark[i] = k
                c += 1
                i = parent[i]
        counts[k + 1] = c
    reach_ptr = np.cumsum(counts)
    reach = np.empty(reach_ptr[n], np.int64)
    mark[:] = -1
    for k in range(n):
        mark[k] = k
        top = reach_ptr[k]
        for p in range(indptr[k], indptr[k + 1]):
            i = indices[p]
            while i != -1 and i < k and mark[i] != k:
                mark[i] = k
                reach[top] = i
                top += 1
                i = parent[i]
        reach[reach_ptr[k]:reach_ptr[k + 1]].sort()
    return reach_ptr, reach


@numba.njit(cache=True)
def factor_numeric(n, indptr, indices, data, transpose, diagonal, reach_ptr, reach,
                   col_ptr, col_rows, lower, upper, pivots, work_u, work_l,
                   fill):  # pragma: no cover - compiled
    """Numeric LU ``B = L U`` without pivoting; returns the first row whose pivot is not a
    finite number larger in magnitude than ``1e-14`` times the row's largest entry (-1 if none).

    Parameters
    ----------
    n : int
    indptr, indices, data : CSR of ``B`` (n, n) with a symmetric pattern
    transpose : (nnz,) int
        Position in ``data`` of the transposed entry of every entry.
    diagonal : (n,) int
        Position in ``data`` of every diagonal entry.
    reach_ptr, reach : from :func:`row_reaches`
    col_ptr : (n + 1,) int
        Start of every column of ``L`` (and row of ``U``) in ``col_rows``/``lower``/``upper``.
    col_rows : (nnz(L) - n,) int
        Row indices of ``L`` by columns, ascending (the column indices of ``U`` by rows).
    lower, upper : (nnz(L) - n,) float
        Output: strictly lower ``L`` by columns, strictly upper ``U`` by rows.
    pivots : (n,) float
        Output: the diagonal of ``U``.
    work_u, work_l : (n,) float
        Zeroed work arrays (left zeroed).
    fill : (n,) int
        Work array.
    """
    fill[:] = 0
    for k in range(n):
        big = 0.0
        for p in range(indptr[k], indptr[k + 1]):
            j = indices[p]
            if j < k:
                work_u[j] = data[transpose[p]]   # B[j, k]
                work_l[j] = data[p]              # B[k, j]
            a = abs(data[p])
            if a > big:
                big = a
        d = data[diagonal[k]]
        for q in range(reach_ptr[k], reach_ptr[k + 1]):
            j = reach[q]
            u = work_u[j]
            l_kj = work_l[j] / pivots[j]
            start = col_ptr[j]
            for p in range(start, start + fill[j]):
                m = col_rows[p]
                work_u[m] -= lower[p] * u
                work_l[m] -= upper[p] * l_kj
            d -= l_kj * u
            slot = start + fill[j]
            lower[slot] = l_kj
            upper[slot] = u
            fill[j] += 1
            work_u[j] = 0.0
            work_l[j] = 0.0
        pivots[k] = d
        if not (abs(d) > 1e-14 * big) or not np.isfinite(d):
            return k
    return -1


@numba.njit(cache=True)
def solve_factored(col_ptr, col_rows, lower, upper, pivots, x):  # pragma: no cover - compiled
    """Overwrite ``x`` (n,) with ``U^-1 L^-1 x``."""
    n = pivots.shape[0]
    for j in range(n):
        xj = x[j]
        if xj != 0.0:
            for p in range(col_ptr[j], col_ptr[j + 1]):
                x[col_rows[p]] -= lower[p] * xj
    for i in range(n - 1, -1, -1):
        s = x[i]
        for p in range(col_ptr[i], col_ptr[i + 1]):
            s -= upper[p] * x[col_rows[p]]
        x[i] = s / pivots[i]
