"""Scatter element vectors and matrices into global ones through a precomputed sparsity pattern.

Knows no physics: an element is a list of global DOF indices. Supported (fixed) DOFs are dropped
from the pattern once, so every assembled matrix is already the reduced one on the free DOFs.

Newton's iteration matrix ``diag(m) + a C + b K T`` is assembled in one pass straight into the
storage its LU will use (:meth:`SparsityPattern.iteration_matrix`): LAPACK band storage when the
rows and columns can be ordered into a narrow band (a thread, a chain), a dense array for other
small systems, CSR for the sparse LU otherwise (:mod:`rodnet.sparse_lu`, SuperLU as the fall-back).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from numpy.typing import NDArray
from scipy.sparse.csgraph import reverse_cuthill_mckee

from rodnet.kernels.assembly_compiled import add_transformed_blocks

FloatArray = NDArray[np.float64]
IndexArray = NDArray[np.int64]

DENSE_LIMIT = 100
"""Up to this many unknowns a dense LAPACK LU is used when no narrow band exists. (Above it, the
fixed-pattern sparse LU wins on nets: 351 unknowns of a 5 x 5 Cosserat net, a 0.3 s run took
7.1 s with dense LU and 1.2 s with :class:`~rodnet.sparse_lu.StaticPatternLU`.)"""

NARROW_BAND = 64
"""Above :data:`DENSE_LIMIT` unknowns, a band LU is used when ``lower + upper`` is at most this."""


@dataclass(frozen=True)
class BandedMatrix:
    """A square matrix that is banded once its rows and columns are taken in ``order``.

    Attributes
    ----------
    ab : (2 lower + upper + 1, n) float, Fortran order
        LAPACK general band storage of ``B = A[order][:, order]`` with the ``lower`` extra rows
        the LU's pivoting fills: ``ab[lower + upper + i - j, j] = B[i, j]``.
    lower, upper : int
        Bandwidths of ``B`` below and above its diagonal.
    order : (n,) int
    """

    ab: FloatArray
    lower: int
    upper: int
    order: IndexArray

    @property
    def shape(self) -> tuple[int, int]:
        n = self.ab.shape[1]
        return n, n

    def dot(self, x: FloatArray) -> FloatArray:
        """``A x`` for a vector ``x`` (n,)."""
        n, top = self.shape[0], self.lower + self.upper
        xb, yb = x[self.order], np.zeros(n)
        for k in range(-self.lower, self.upper + 1):   # the diagonal j - i = k
            if k >= 0:
                yb[:n - k] += self.ab[top - k, k:] * xb[k:]
            else:
                yb[-k:] += self.ab[top - k, :n + k] * xb[:n + k]
        y = np.empty(n)
        y[self.order] = yb
        return y

    def toarray(self) -> FloatArray:
        """The matrix ``A`` as a dense (n, n) array."""
        rows, cols, values = self._entries()
        A = np.zeros(self.shape)
        A[rows, cols] = values
        return A

    def tocsr(self) -> sp.csr_matrix:
        """The matrix ``A`` in CSR storage (every entry of the band, zeros included)."""
        rows, cols, values = self._entries()
        return sp.csr_matrix((values, (rows, cols)), shape=self.shape)

    def _entries(self) -> tuple[IndexArray, IndexArray, FloatArray]:
        """Rows, columns and values of ``A`` over the band of ``B``."""
        n = self.shape[0]
        offsets = np.arange(-self.lower, self.upper + 1)          # j - i along the band
        i = np.repeat(np.arange(n), len(offsets))
        j = i + np.tile(offsets, n)
        inside = (j >= 0) & (j < n)
        i, j = i[inside], j[inside]
        return self.order[i], self.order[j], self.ab[self.lower + self.upper + i - j, j]


IterationMatrix = BandedMatrix | FloatArray | sp.csr_matrix
"""Newton's iteration matrix in the storage :meth:`SparsityPattern.iteration_matrix` chose."""


@dataclass(frozen=True)
class _Storage:
    """Where each entry of an iteration matrix lives in a flat array.

    ``kind`` is ``"band"``, ``"dense"`` or ``"csr"``; ``positions`` holds one (E_g, k_g, k_g)
    array per group (-1: a dropped entry), ``triples`` one (E_g, k_g / 3) array per group (the DOF
    triple of each three block columns), ``diagonal`` (n_free,) the positions of the diagonal.
    """

    kind: str
    size: int
    positions: tuple[IndexArray, ...]
    triples: tuple[IndexArray, ...]
    diagonal: IndexArray
    lower: int = 0
    upper: int = 0
    order: IndexArray | None = None


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
        self._groups = [np.asarray(dofs, np.int64) for dofs in groups]
        self.reduced_index = np.full(n_dof, -1, np.int64)
        self.reduced_index[free] = np.arange(int(free.sum()))
        self.n_free = int(free.sum())
        rows, cols, self._keep = [], [], []
        for dofs in self._groups:
            r, c = self._entries(dofs)
            keep = (r >= 0) & (c >= 0)
            self._keep.append(keep)
            rows.append(r[keep]), cols.append(c[keep])
        row, col = np.concatenate(rows), np.concatenate(cols)
        key = row * self.n_free + col
        unique, self._slot = np.unique(key, return_inverse=True)
        self._keys = unique
        self._block_maps: dict[int, tuple[IndexArray, ...]] = {}
        self._storage: _Storage | None = None
        self.nnz = len(unique)
        self._indices = (unique % self.n_free).astype(np.int32)
        counts = np.bincount(unique // self.n_free, minlength=self.n_free)
        self._indptr = np.concatenate([[0], np.cumsum(counts)]).astype(np.int32)

    def _entries(self, dofs: IndexArray) -> tuple[IndexArray, IndexArray]:
        """Reduced row and column (E * k * k,) of every entry of the blocks on ``dofs`` (E, k),
        -1 for a supported DOF."""
        k = dofs.shape[1]
        return (self.reduced_index[np.repeat(dofs, k, axis=1)].ravel(),
                self.reduced_index[np.tile(dofs, (1, k))].ravel())

    def matrix(self, blocks: Sequence[FloatArray]) -> sp.csr_matrix:
        """Sum the blocks (one (E_g, k_g, k_g) array per group, same order) into a CSR matrix
        of shape (n_free, n_free)."""
        values = np.concatenate([b.reshape(-1)[keep] for b, keep in zip(blocks, self._keep)])
        data = np.bincount(self._slot, weights=values, minlength=self.nnz)
        return sp.csr_matrix((data, self._indices, self._indptr), shape=(self.n_free, self.n_free))

    def iteration_matrix(self, diagonal: FloatArray, a: float, C_blocks: Sequence[FloatArray],
                         b: float, K_blocks: Sequence[FloatArray],
                         transforms: FloatArray) -> IterationMatrix:
        """``diag(diagonal) + a C + b K T`` on the free DOFs, assembled in one pass.

        ``C`` and ``K`` are the sums of their blocks (as :meth:`matrix`); ``T`` is block diagonal
        over the DOF triples ``(3 p, 3 p + 1, 3 p + 2)`` with the 3 x 3 blocks ``transforms``
        (n_dof / 3, 3, 3) restricted to the free DOFs: ``T`` multiplies each element block from
        the right before it is scattered. Every group's DOFs must come in such triples.

        Parameters
        ----------
        diagonal : (n_free,) float
        a, b : float
        C_blocks, K_blocks : sequences of (E_g, k_g, k_g) float, one array per group
        transforms : (n_dof / 3, 3, 3) float

        Returns
        -------
        BandedMatrix, (n_free, n_free) ndarray or csr_matrix
            In the storage :attr:`storage_kind` names.
        """
        storage = self._iteration_storage()
        out = np.zeros(storage.size)
        for C, K, positions, triples in zip(C_blocks, K_blocks, storage.positions,
                                            storage.triples):
            add_transformed_blocks(out, positions, float(a), np.ascontiguousarray(C), float(b),
                                   np.ascontiguousarray(K), triples, transforms)
        out[storage.diagonal] += diagonal
        n = self.n_free
        if storage.kind == "band":
            ab = out.reshape(n, -1).T  # Fortran-ordered (2 lower + upper + 1, n) view
            return BandedMatrix(ab, storage.lower, storage.upper, storage.order)
        if storage.kind == "dense":
            return out.reshape(n, n)
        return sp.csr_matrix((out, self._indices, self._indptr), shape=(n, n))

    @property
    def storage_kind(self) -> str:
        """``"band"``, ``"dense"`` or ``"csr"``: how :meth:`iteration_matrix` stores its result."""
        return self._iteration_storage().kind

    def _iteration_storage(self) -> _Storage:
        if self._storage is None:
            self._storage = self._choose_storage()
        return self._storage

    def _choose_storage(self) -> _Storage:
        """The storage of :meth:`iteration_matrix`.

        The rows and columns are ordered by reverse Cuthill-McKee, which gives a chain of
        elements (a thread) a band as narrow as its element blocks. Up to :data:`DENSE_LIMIT`
        unknowns: band storage when a band LU (about ``n lower (lower + upper)`` multiply-adds)
        takes less than a quarter of a dense one (``n^3 / 3``), else dense. Above: band storage
        when ``lower + upper`` is at most :data:`NARROW_BAND`, else CSR for the sparse LU.
        """
        n = self.n_free
        triples = []
        for dofs in self._groups:
            first = dofs[:, ::3]
            aligned = np.repeat(first, 3, axis=1) + np.tile(np.arange(3), first.shape[1])
            if dofs.shape[1] % 3 or np.any(first % 3) or np.any(dofs != aligned):
                raise ValueError("iteration_matrix needs every block's DOFs in aligned triples")
            triples.append(np.ascontiguousarray(first // 3))
        structure = sp.csr_matrix((np.ones(self.nnz), self._indices, self._indptr), shape=(n, n))
        order = (reverse_cuthill_mckee(structure, symmetric_mode=True).astype(np.int64) if n
                 else np.zeros(0, np.int64))
        rank = np.empty(n, np.int64)
        rank[order] = np.arange(n)
        row, col = rank[self._keys // max(n, 1)], rank[self._keys % max(n, 1)]
        lower = int(np.max(row - col, initial=0))
        upper = int(np.max(col - row, initial=0))
        if n <= DENSE_LIMIT:
            kind = "band" if 4 * n * lower * (lower + upper) < n ** 3 / 3 else "dense"
        else:
            kind = "band" if lower + upper <= NARROW_BAND else "csr"
        height = 2 * lower + upper + 1

        def where(r: IndexArray, c: IndexArray) -> IndexArray:
            if kind == "band":  # column-major (height, n) band storage
                i, j = rank[r], rank[c]
                return (lower + upper + i - j) + height * j
            if kind == "dense":
                return r * n + c
            return np.searchsorted(self._keys, r * n + c)

        positions = []
        for dofs in self._groups:
            r, c = self._entries(dofs)
            keep = (r >= 0) & (c >= 0)
            p = np.full(len(r), -1, np.int64)
            p[keep] = where(r[keep], c[keep])
            positions.append(p.reshape(len(dofs), dofs.shape[1], dofs.shape[1]))
        diagonal = where(np.arange(n), np.arange(n))
        size = {"band": height * n, "dense": n * n, "csr": self.nnz}[kind]
        return _Storage(kind, size, tuple(positions), tuple(triples), diagonal, lower, upper,
                        order if kind == "band" else None)

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


def add_diagonal(matrix: IterationMatrix, shift: FloatArray) -> IterationMatrix:
    """A new matrix ``matrix + diag(shift)`` in the same storage (CSR, band or dense);
    ``matrix`` is left as it is."""
    if isinstance(matrix, BandedMatrix):
        ab = np.array(matrix.ab, order="F")
        ab[matrix.lower + matrix.upper, np.argsort(matrix.order)] += shift
        return BandedMatrix(ab, matrix.lower, matrix.upper, matrix.order)
    if isinstance(matrix, np.ndarray):
        out = matrix.copy()
        out[np.diag_indices_from(out)] += shift
        return out
    rows = np.repeat(np.arange(matrix.shape[0]), np.diff(matrix.indptr))
    on_diagonal = matrix.indices == rows
    if np.count_nonzero(on_diagonal) == matrix.shape[0]:
        # every diagonal entry is in the pattern: the same pattern (a fixed-pattern LU of it
        # is reused)
        data = matrix.data.copy()
        data[on_diagonal] += shift[rows[on_diagonal]]
        return sp.csr_matrix((data, matrix.indices, matrix.indptr), shape=matrix.shape)
    return (matrix + sp.diags(shift)).tocsr()


def add_blocks(matrix: IterationMatrix, rows: IndexArray, blocks: FloatArray) -> IterationMatrix:
    """``matrix`` (CSR, band or dense) with the square ``blocks`` (B, k, k) added at the rows and
    columns ``rows`` (B, k), in place; every entry of the blocks must lie in the matrix's
    pattern (CSR) or band."""
    if isinstance(matrix, np.ndarray):
        for r, block in zip(rows, blocks):
            matrix[np.ix_(r, r)] += block
        return matrix
    if isinstance(matrix, BandedMatrix):
        where = np.argsort(matrix.order)   # position of every row in the band's order
        for r, block in zip(rows, blocks):
            i, j = np.meshgrid(where[r], where[r], indexing="ij")
            matrix.ab[matrix.lower + matrix.upper + i - j, j] += block
        return matrix
    for r, block in zip(rows, blocks):
        for a, row in enumerate(r):
            start, stop = matrix.indptr[row], matrix.indptr[row + 1]
            at = start + np.searchsorted(matrix.indices[start:stop], r)
            if not np.array_equal(matrix.indices[at], r):
                raise ValueError("a block entry lies outside the matrix's pattern")
            matrix.data[at] += block[a]
    return matrix


def diagonal(matrix: IterationMatrix) -> FloatArray:
    """The diagonal of ``matrix`` (n,)."""
    if isinstance(matrix, BandedMatrix):
        d = np.empty(matrix.shape[0])
        d[matrix.order] = matrix.ab[matrix.lower + matrix.upper]
        return d
    if isinstance(matrix, np.ndarray):
        return np.diag(matrix).copy()
    return matrix.diagonal()

