"""Compiled kernels of :class:`rodnet.sparse_lu.StaticPatternLU`: the symbolic analysis and the
numeric LU without pivoting, in 3 x 3 blocks, of a matrix with a symmetric block pattern.

The unknowns are taken three at a time (a node's translations or rotations), so the matrix is
one of ``N`` x ``N`` blocks. The block matrix ``B`` (already in elimination order) is given by
its CSR pattern. Its pattern is symmetric, so ``L`` (unit lower) and ``U^T`` have the same
pattern, that of the Cholesky factor of the pattern: block column ``j`` of ``L`` holds the
block rows ``k > j`` whose row-reach in the elimination tree contains ``j`` (Davis, *Direct
Methods for Sparse Linear Systems*, 2006, sections 4.1-4.3). The numeric factorisation is
"up-looking": block row ``k`` of ``L`` and block column ``k`` of ``U`` come from two sparse
triangular solves over that reach (the LU analogue of Davis' ``cs_chol``), each step a pair of
3 x 3 products. The pivot blocks are factorised as ``D = L_D U_D`` without pivoting and the
factors kept are the scalar LU's (diagonal blocks ``L_D`` of ``L`` and ``U_D`` of ``U``), the
same numbers as a scalar LU in that elimination order: the blocks only let the compiled loops do
nine products per index looked up instead of one. (The block LU with ``D^-1`` in ``L`` is less
accurate where pivot blocks are ill-conditioned: ten times the residual on the nets.)
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


@numba.njit(inline="always")
def _entry(data, slot):  # pragma: no cover - compiled
    """A scalar entry of the matrix: ``data[slot]``, 0 for a slot outside the pattern (-1) and
    1 for the diagonal of a padding unknown (-2)."""
    if slot >= 0:
        return data[slot]
    return 1.0 if slot == -2 else 0.0


@numba.njit(cache=True)
def factor_numeric(n_blocks, indptr, indices, transpose, diagonal, source, data, scalar_ptr,
                   scalar_rows, reach_ptr, reach, col_ptr, col_rows, lower, upper, pivot_lu,
                   work_u, work_l, fill, big):  # pragma: no cover - compiled
    """Numeric block LU ``B = L U`` without pivoting; returns the first scalar row (of the
    elimination order, ``3 k + a``) whose pivot is not a finite number larger in magnitude
    than ``1e-14`` times the row's largest entry (-1 if none).

    Parameters
    ----------
    n_blocks : int
    indptr, indices : CSR pattern of the block matrix ``B`` (N, N), symmetric
    transpose : (nnz_B,) int
        Position of the transposed block of every block.
    diagonal : (N,) int
        Position of every diagonal block.
    source : (nnz_B, 3, 3) int
        Position in ``data`` of every scalar entry of every block: -1 outside the scalar
        pattern, -2 on the diagonal of a padding unknown.
    data : (nnz,) float
        The scalar matrix's values (CSR).
    scalar_ptr : (n + 1,) int
        The scalar matrix's row pointer (for the rows' largest entries).
    scalar_rows : (N, 3) int
        Scalar row of every unknown of every block row (-1 for padding).
    reach_ptr, reach : from :func:`row_reaches` of ``B``
    col_ptr : (N + 1,) int
        Start of every block column of ``L`` (and block row of ``U``) in ``col_rows``,
        ``lower``, ``upper``.
    col_rows : (nnz_L,) int
        Block row indices of ``L`` by columns, ascending.
    lower, upper : (nnz_L, 3, 3) float
        Output: strictly lower blocks of ``L`` by columns, strictly upper blocks of ``U`` by
        rows.
    pivot_lu : (N, 3, 3) float
        Output: every pivot block's ``L_D`` (strictly lower part) and ``U_D`` (upper part with
        the diagonal) in one array.
    work_u, work_l : (N, 3, 3) float
        Zeroed work arrays (left zeroed when the factorisation succeeds).
    fill : (N,) int
        Work array.
    big : (n,) float
        Work array: the largest magnitude in every scalar row.
    """
    for r in range(scalar_ptr.shape[0] - 1):
        m = 0.0
        for p in range(scalar_ptr[r], scalar_ptr[r + 1]):
            m = max(m, abs(data[p]))
        big[r] = m
    fill[:] = 0
    D = np.empty((3, 3))
    el = np.empty((3, 3))
    u = np.empty((3, 3))
    for k in range(n_blocks):
        for p in range(indptr[k], indptr[k + 1]):
            j = indices[p]
            if j < k:
                t = transpose[p]
                for a in range(3):
                    for b in range(3):
                        work_u[j, a, b] = _entry(data, source[t, a, b])   # B[j, k]
                        work_l[j, a, b] = _entry(data, source[p, a, b])   # B[k, j]
        for a in range(3):
            for b in range(3):
                D[a, b] = _entry(data, source[diagonal[k], a, b])
        for q in range(reach_ptr[k], reach_ptr[k + 1]):
            j = reach[q]
            f = pivot_lu[j]
            for a in range(3):
                # L[k, j] = work_l[j] U_D^-1 (row a), U[j, k] = L_D^-1 work_u[j] (column a)
                el[a, 0] = work_l[j, a, 0] / f[0, 0]
                el[a, 1] = (work_l[j, a, 1] - el[a, 0] * f[0, 1]) / f[1, 1]
                el[a, 2] = (work_l[j, a, 2] - el[a, 0] * f[0, 2] - el[a, 1] * f[1, 2]) / f[2, 2]
                u[0, a] = work_u[j, 0, a]
                u[1, a] = work_u[j, 1, a] - f[1, 0] * u[0, a]
                u[2, a] = work_u[j, 2, a] - f[2, 0] * u[0, a] - f[2, 1] * u[1, a]
            start = col_ptr[j]
            for p in range(start, start + fill[j]):
                m = col_rows[p]
                for a in range(3):
                    for b in range(3):
                        work_u[m, a, b] -= (lower[p, a, 0] * u[0, b] + lower[p, a, 1] * u[1, b]
                                            + lower[p, a, 2] * u[2, b])
                        work_l[m, a, b] -= (el[a, 0] * upper[p, 0, b] + el[a, 1] * upper[p, 1, b]
                                            + el[a, 2] * upper[p, 2, b])
            slot = start + fill[j]
            for a in range(3):
                for b in range(3):
                    D[a, b] -= el[a, 0] * u[0, b] + el[a, 1] * u[1, b] + el[a, 2] * u[2, b]
                    lower[slot, a, b] = el[a, b]
                    upper[slot, a, b] = u[a, b]
                    work_u[j, a, b] = 0.0
                    work_l[j, a, b] = 0.0
            fill[j] += 1
        # the pivot block D = L_D U_D, scalar LU without pivoting
        f = pivot_lu[k]
        for a in range(3):
            for b in range(3):
                f[a, b] = D[a, b]
        for a in range(3):
            for i in range(a):                       # row a of L_D and U_D
                f[a, i] = (f[a, i] - _dot_prefix(f, a, i, i)) / f[i, i]
            for b in range(a, 3):
                f[a, b] = f[a, b] - _dot_prefix(f, a, b, a)
            row = scalar_rows[k, a]
            scale = big[row] if row >= 0 else 1.0
            if not (abs(f[a, a]) > 1e-14 * scale) or not np.isfinite(f[a, a]):
                work_u[:, :, :] = 0.0
                work_l[:, :, :] = 0.0
                return 3 * k + a
    return -1


@numba.njit(inline="always")
def _dot_prefix(f, a, b, count):  # pragma: no cover - compiled
    """``sum_i<count f[a, i] f[i, b]``: the products of row ``a`` of ``L_D`` and column ``b``
    of ``U_D`` already formed."""
    s = 0.0
    for i in range(count):
        s += f[a, i] * f[i, b]
    return s


@numba.njit(cache=True)
def solve_factored(col_ptr, col_rows, lower, upper, pivot_lu, x):  # pragma: no cover - compiled
    """Overwrite ``x`` (N, 3) with ``U^-1 L^-1 x``."""
    n_blocks = pivot_lu.shape[0]
    for j in range(n_blocks):
        f = pivot_lu[j]                              # L_D^-1 x_j
        x0 = x[j, 0]
        x1 = x[j, 1] - f[1, 0] * x0
        x2 = x[j, 2] - f[2, 0] * x0 - f[2, 1] * x1
        x[j, 1], x[j, 2] = x1, x2
        for p in range(col_ptr[j], col_ptr[j + 1]):
            m = col_rows[p]
            for a in range(3):
                x[m, a] -= lower[p, a, 0] * x0 + lower[p, a, 1] * x1 + lower[p, a, 2] * x2
    for i in range(n_blocks - 1, -1, -1):
        s0, s1, s2 = x[i, 0], x[i, 1], x[i, 2]
        for p in range(col_ptr[i], col_ptr[i + 1]):
            m = col_rows[p]
            s0 -= upper[p, 0, 0] * x[m, 0] + upper[p, 0, 1] * x[m, 1] + upper[p, 0, 2] * x[m, 2]
            s1 -= upper[p, 1, 0] * x[m, 0] + upper[p, 1, 1] * x[m, 1] + upper[p, 1, 2] * x[m, 2]
            s2 -= upper[p, 2, 0] * x[m, 0] + upper[p, 2, 1] * x[m, 1] + upper[p, 2, 2] * x[m, 2]
        f = pivot_lu[i]                              # U_D^-1 s
        x2 = s2 / f[2, 2]
        x1 = (s1 - f[1, 2] * x2) / f[1, 1]
        x[i, 0] = (s0 - f[0, 1] * x1 - f[0, 2] * x2) / f[0, 0]
        x[i, 1] = x1
        x[i, 2] = x2
