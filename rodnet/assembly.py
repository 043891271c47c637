"""Scatter element vectors and matrices into global ones through a precomputed sparsity pattern.

Knows no physics: an element is a list of global DOF indices. Supported (fixed) DOFs are dropped
from the pattern once, so every assembled matrix is already the reduced one on the free DOFs.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import scipy.sparse as sp
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]
IndexArray = NDArray[np.int64]


class SparsityPattern:
    """The CSR structure of a global matrix built from groups of equally sized element blocks.

    Parameters
    ----------
    groups : sequence of (E_g, k_g) int arrays
        Global DOF indices of the blocks of each group (e.g. 12 DOF rod elements, 3 DOF nodes).
    n_dof : int
        Number of global DOFs.
    free : (n_dof,) bool, optional
        DOFs that stay in the matrix; the others (supports) are dropped.
    """

    def __init__(self, groups: Sequence[IndexArray], n_dof: int,
                 free: NDArray[np.bool_] | None = None) -> None:
        free = np.ones(n_dof, bool) if free is None else np.asarray(free, bool)
        self.n_dof, self.free = n_dof, free
        self.reduced_index = np.full(n_dof, -1, np.int64)
        self.reduced_index[free] = np.arange(int(free.sum()))
        self.n_free = int(free.sum())
        rows, cols, self._keep = [], [], []
        for dofs in groups:
            k = dofs.shape[1]
            r = self.reduced_index[np.repeat(dofs, k, axis=1)].ravel()
            c = self.reduced_index[np.tile(dofs, (1, k))].ravel()
            keep = (r >= 0) & (c >= 0)
            self._keep.append(keep)
            rows.append(r[keep]), cols.append(c[keep])
        row, col = np.concatenate(rows), np.concatenate(cols)
        key = row * self.n_free + col
        unique, self._slot = np.unique(key, return_inverse=True)
        self._keys = unique
        self._block_maps: dict[int, tuple[IndexArray, ...]] = {}
        self.nnz = len(unique)
        self._indices = (unique % self.n_free).astype(np.int32)
        counts = np.bincount(unique // self.n_free, minlength=self.n_free)
        self._indptr = np.concatenate([[0], np.cumsum(counts)]).astype(np.int32)

    def matrix(self, blocks: Sequence[FloatArray]) -> sp.csr_matrix:
        """Sum the blocks (one (E_g, k_g, k_g) array per group, same order) into a CSR matrix
        of shape (n_free, n_free)."""
        values = np.concatenate([b.reshape(-1)[keep] for b, keep in zip(blocks, self._keep)])
        data = np.bincount(self._slot, weights=values, minlength=self.nnz)
        return sp.csr_matrix((data, self._indices, self._indptr), shape=(self.n_free, self.n_free))


    def right_multiply_blocks(self, matrix: sp.csr_matrix, triples: IndexArray,
                              blocks: FloatArray) -> sp.csr_matrix:
        """``matrix @ T`` for T block diagonal: identity except the 3 x 3 ``blocks`` (B, 3, 3)
        on the reduced DOF ``triples`` (B, 3). ``matrix`` must have this pattern and every
        row that touches one DOF of a triple must touch all three (true for element blocks)."""
        rows_of, cols_of, others, block_of, local = self._block_map(triples)
        data = matrix.data.copy()
        gathered = matrix.data[others]                      # (m, 3): A[r, triple_b[k]]
        data[cols_of] = np.einsum("mk,mk->m", gathered, blocks[block_of, :, local])
        return sp.csr_matrix((data, matrix.indices, matrix.indptr), shape=matrix.shape)

    def _block_map(self, triples: IndexArray) -> tuple[IndexArray, ...]:
        cached = self._block_maps.get(id(triples))
        if cached is not None:
            return cached
        n = self.n_free
        row, col = self._keys // n, self._keys % n
        owner = np.full(n, -1)
        owner[triples.ravel()] = np.repeat(np.arange(len(triples)), 3)
        position = np.full(n, -1)
        position[triples.ravel()] = np.tile(np.arange(3), len(triples))
        entries = np.flatnonzero(owner[col] >= 0)
        block_of, local = owner[col[entries]], position[col[entries]]
        partner_keys = row[entries, None] * n + triples[block_of]
        others = np.searchsorted(self._keys, partner_keys)
        cached = (row[entries], entries, others, block_of, local)
        self._block_maps[id(triples)] = cached
        return cached


def assemble_vector(dofs: IndexArray, local: FloatArray, n_dof: int) -> FloatArray:
    """Sum element vectors ``local`` (E, k) at global DOFs ``dofs`` (E, k) into an (n_dof,) vector."""
    return np.bincount(dofs.ravel(), weights=local.ravel(), minlength=n_dof)
