"""The fixed-pattern sparse LU against SciPy's SuperLU, and its refusals."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from rodnet.integrate.newton import LinearSolver
from rodnet.sparse_lu import StaticPatternLU


def net_like(n_side: int, seed: int, asymmetry: float = 1e-3) -> sp.csr_matrix:
    """A pattern-symmetric, slightly unsymmetric matrix on a square grid of 3 x 3 node blocks
    (the structure of a net's iteration matrix): mass-like diagonal plus stiffness blocks."""
    rng = np.random.default_rng(seed)
    nodes = n_side * n_side
    edges = [(i * n_side + j, i * n_side + j + 1) for i in range(n_side) for j in range(n_side - 1)]
    edges += [(i * n_side + j, (i + 1) * n_side + j) for i in range(n_side - 1) for j in range(n_side)]
    n = 3 * nodes
    A = sp.lil_matrix((n, n))
    for a, b in edges:
        k = rng.normal(size=(3, 3))
        k = k @ k.T + np.eye(3)
        dofs = np.r_[3 * a:3 * a + 3, 3 * b:3 * b + 3]
        block = np.block([[k, -k], [-k, k]])
        block += asymmetry * rng.normal(size=(6, 6))
        A[np.ix_(dofs, dofs)] = A[np.ix_(dofs, dofs)].toarray() + block
    A.setdiag(A.diagonal() + 1.0)
    return A.tocsr()


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_solution_equals_superlu(seed: int) -> None:
    A = net_like(9, seed)
    lu = StaticPatternLU(A)
    assert lu.factorize(A)
    rhs = np.random.default_rng(seed).normal(size=A.shape[0])
    expected = spla.spsolve(A.tocsc(), rhs)
    x = lu.solve(rhs)
    assert np.max(np.abs(x - expected)) <= 1e-10 * np.max(np.abs(expected))
    # new values on the same pattern: the analysis is reused
    B = A.copy()
    B.data *= 1.0 + 0.1 * np.random.default_rng(seed + 10).random(B.nnz)
    assert lu.matches(B)
    assert lu.factorize(B)
    expected = spla.spsolve(B.tocsc(), rhs)
    assert np.max(np.abs(lu.solve(rhs) - expected)) <= 1e-10 * np.max(np.abs(expected))


def test_unknowns_not_in_node_triples() -> None:
    """Supports that remove single DOFs leave unknowns that are not a node's triple, and a
    count that is not a multiple of three: the blocks then mix nodes and the last is padded,
    and the solution is still SuperLU's."""
    A = net_like(9, 6)
    keep = np.setdiff1d(np.arange(A.shape[0]), [0, 4, 100, 101])   # 243 - 4 = 3 * 79 + 2
    A = A[keep][:, keep].tocsr()
    A.sort_indices()
    lu = StaticPatternLU(A)
    assert A.shape[0] % 3 == 2
    assert lu.factorize(A)
    rhs = np.random.default_rng(6).normal(size=A.shape[0])
    expected = spla.spsolve(A.tocsc(), rhs)
    assert np.max(np.abs(lu.solve(rhs) - expected)) <= 1e-10 * np.max(np.abs(expected))


def test_zero_pivot_inside_a_block_is_reported() -> None:
    """A node block whose second pivot vanishes ([[1, 1], [1, 1]] in its leading corner)."""
    A = net_like(5, 7).tolil()
    A[3, 3], A[3, 4], A[4, 3], A[4, 4] = 1.0, 1.0, 1.0, 1.0
    A[3, 5] = A[4, 5] = A[5, 3] = A[5, 4] = 0.0
    for j in range(6, A.shape[0]):        # node 1 decoupled from later nodes, and earlier ones
        A[3, j] = A[4, j] = A[j, 3] = A[j, 4] = 0.0
    for j in range(3):
        A[3, j] = A[4, j] = A[j, 3] = A[j, 4] = 0.0
    A = A.tocsr()
    lu = StaticPatternLU(A)
    assert not lu.factorize(A)


def test_fill_is_reduced() -> None:
    """The ordering keeps the factor far below a dense one (a 12 x 12 grid: 432 unknowns)."""
    A = net_like(12, 3)
    lu = StaticPatternLU(A)
    assert lu.factor_entries < 0.1 * A.shape[0] ** 2


def swap_block() -> sp.csr_matrix:
    """[[0, 1], [1, 0]] with its zero diagonal stored: no LU without pivoting exists."""
    return sp.csr_matrix((np.array([0.0, 1.0, 1.0, 0.0]), np.array([0, 1, 0, 1]),
                          np.array([0, 2, 4])), shape=(2, 2))


def test_zero_pivot_is_reported() -> None:
    """A matrix whose leading block is singular cannot be factorised without pivoting."""
    A = swap_block()
    lu = StaticPatternLU(A)
    assert not lu.factorize(A)


def test_unsymmetric_pattern_is_refused() -> None:
    A = sp.csr_matrix(np.array([[1.0, 2.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]))
    with pytest.raises(ValueError, match="symmetric pattern"):
        StaticPatternLU(A)


def test_linear_solver_falls_back_to_pivoting() -> None:
    """The Newton solver uses the fixed-pattern LU once a pattern repeats, and a pivoting LU
    when a zero pivot makes it fail, so the solution is right either way."""
    A = net_like(13, 4)                                  # 507 unknowns: above the dense limit
    swap = swap_block()
    rhs = np.ones(A.shape[0] + 2)
    solver = LinearSolver()
    for M, static in ((sp.block_diag([A, sp.identity(2)], format="csr"), True),
                      (sp.block_diag([A, swap], format="csr"), False)):
        M.sort_indices()
        assert M.nnz == A.nnz + (2 if static else 4)
        for _ in range(2):
            solver.factorize(M)
            assert np.allclose(M @ solver.solve(rhs), rhs, rtol=0, atol=1e-9)
        assert isinstance(solver.lu, StaticPatternLU) == static


def test_linear_solver_takes_unsymmetric_patterns_with_superlu() -> None:
    """A pattern the fixed-pattern LU refuses (one entry without its transposed partner) is
    solved by SuperLU every time it comes."""
    A = net_like(13, 5).tolil()
    A[0, A.shape[0] - 1] = 1e-3                     # no entry at (n - 1, 0)
    A = A.tocsr()
    A.sort_indices()
    rhs = np.ones(A.shape[0])
    solver = LinearSolver()
    for _ in range(3):
        solver.factorize(A)
        assert not isinstance(solver.lu, StaticPatternLU)
        assert np.allclose(A @ solver.solve(rhs), rhs, rtol=0, atol=1e-9)
