"""Newton's method with an LU (band, dense or sparse), factorisation reuse and a backtracking
line search.

The unknown is a plain vector ``u`` on the free DOFs; the caller's ``evaluate(u)`` returns the
residual (and, on request, the iteration matrix). Reuse: the LU of an earlier iteration (or step)
is kept while residuals contract by at least ``reuse_contraction`` and the model's active set
(slack/taut threads, contacts) is unchanged; otherwise it is refreshed.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Callable

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla
from numpy.typing import NDArray
from scipy.linalg.lapack import dgbtrf as _gbtrf, dgbtrs as _gbtrs, dgetrf as _getrf, dgetrs as _getrs

from rodnet.assembly import DENSE_LIMIT, BandedMatrix, IterationMatrix
from rodnet.sparse_lu import Pattern, StaticPatternLU, same_pattern

FloatArray = NDArray[np.float64]


@dataclass(frozen=True, slots=True)
class NewtonOptions:
    """Tolerances and limits; the residual is converged when ``|r|_inf <= atol + rtol * scale``,
    or after a full Newton correction that moves no node by more than ``xtol`` times the model's
    length scale and turns none by more than ``xtol`` rad."""

    rtol: float = 1e-8
    atol: float = 1e-10
    max_iterations: int = 12
    reuse_factorization: bool = False
    reuse_contraction: float = 0.3
    max_rotation: float = np.pi / 4
    xtol: float = 1e-7
    stall_iterations: int | None = None
    """When set: give up after this many iterations if the residual has not fallen below
    ``stall_contraction`` times its starting value (an adaptive stepper then halves the step
    rather than spending the remaining iterations on a step too large for Newton)."""
    stall_contraction: float = 0.5


@dataclass
class NewtonResult:
    u: FloatArray
    converged: bool
    iterations: int
    factorizations: int
    residual_norm: float
    message: str = ""


class LinearSolver:
    """LU of the iteration matrix, kept between calls until refreshed.

    A CSR matrix is factorised by dense LAPACK below ``dense_limit`` unknowns and above by the
    fixed-pattern sparse LU of :mod:`rodnet.sparse_lu` once its pattern has come twice in a row
    (the analysis is then reused for every later matrix of that pattern), by SuperLU otherwise
    and whenever the fixed-pattern LU meets a (nearly) zero pivot. A model may instead hand over
    its matrix already in LAPACK's band storage (:class:`~rodnet.assembly.BandedMatrix`) or as a
    dense array, which are factorised as given.
    """

    dense_limit = DENSE_LIMIT

    def __init__(self) -> None:
        self.lu: Any = None
        self.factorizations = 0
        self._static: StaticPatternLU | None = None
        self._seen_pattern: Pattern | None = None
        self._unsymmetric: Pattern | None = None   # a pattern the fixed-pattern LU refused

    def factorize(self, matrix: IterationMatrix) -> None:
        """Factorise. A band matrix is factorised in place (its storage is overwritten), a dense
        one on a copy. For SuperLU the symmetric ordering with diagonal pivots suits the (nearly
        symmetric, pattern-symmetric) tangents, partial pivoting is its fall-back.

        Raises
        ------
        FloatingPointError
            When the matrix holds a NaN or an infinity.
        RuntimeError
            When the matrix is exactly singular.
        """
        self.factorizations += 1
        if isinstance(matrix, BandedMatrix):
            self.lu = _BandLU(matrix)
            return
        if isinstance(matrix, np.ndarray):
            self.lu = _DenseLU(matrix)
            return
        if not np.isfinite(matrix.data).all():  # SuperLU can loop forever on NaN
            raise FloatingPointError("non-finite iteration matrix")
        if matrix.shape[0] <= self.dense_limit:
            self.lu = _DenseLU(matrix.toarray())
            return
        static = self._static_lu(matrix)
        if static is not None and static.factorize(matrix):
            self.lu = static
            return
        csc = matrix.tocsc()
        try:
            self.lu = spla.splu(csc, permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0,
                                options={"SymmetricMode": True})
            probe = np.ones(csc.shape[0])
            if np.isfinite(self.lu.solve(probe)).all():
                return
        except RuntimeError:
            pass
        self.lu = spla.splu(csc)  # raises RuntimeError when exactly singular

    def solve(self, rhs: FloatArray) -> FloatArray:
        assert self.lu is not None
        return self.lu.solve(rhs)

    def _static_lu(self, matrix: sp.csr_matrix) -> StaticPatternLU | None:
        """The fixed-pattern LU for ``matrix``'s pattern, analysed when the same pattern comes a
        second time in a row (a pattern seen once may never come back); None for a pattern it
        cannot take (not structurally symmetric), which is then not analysed again."""
        if self._static is not None and self._static.matches(matrix):
            return self._static
        if same_pattern(self._unsymmetric, matrix):
            return None
        seen, self._seen_pattern = self._seen_pattern, (matrix.indptr, matrix.indices)
        if not same_pattern(seen, matrix):
            return None
        try:
            self._static = StaticPatternLU(matrix)
        except ValueError:  # not structurally symmetric
            self._static, self._unsymmetric = None, (matrix.indptr, matrix.indices)
        return self._static


class _DenseLU:
    """LAPACK's LU with partial pivoting of a dense (n, n) matrix, with SuperLU's ``solve``."""

    def __init__(self, matrix: FloatArray) -> None:
        if not np.isfinite(matrix).all():
            raise FloatingPointError("non-finite iteration matrix")
        lu, piv, info = _getrf(matrix)
        if info > 0 or not np.isfinite(lu).all():
            raise RuntimeError("Factor is exactly singular")
        self.lu, self.piv = lu, piv

    def solve(self, rhs: FloatArray) -> FloatArray:
        return _getrs(self.lu, self.piv, rhs)[0]


class _BandLU:
    """LAPACK's band LU with partial pivoting of a :class:`~rodnet.assembly.BandedMatrix`, with
    SuperLU's ``solve``; the band storage is factorised in place."""

    def __init__(self, matrix: BandedMatrix) -> None:
        if not np.isfinite(matrix.ab).all():
            raise FloatingPointError("non-finite iteration matrix")
        self.lower, self.upper, self.order = matrix.lower, matrix.upper, matrix.order
        self.lu, self.piv, info = _gbtrf(matrix.ab, self.lower, self.upper, overwrite_ab=1)
        if info > 0:
            raise RuntimeError("Factor is exactly singular")

    def solve(self, rhs: FloatArray) -> FloatArray:
        x = np.empty_like(rhs)
        x[self.order] = _gbtrs(self.lu, self.lower, self.upper, rhs[self.order], self.piv)[0]
        return x


def newton(evaluate: Callable[[FloatArray, bool], tuple[FloatArray, IterationMatrix | None]],
           u0: FloatArray, scale: float, solver: LinearSolver, options: NewtonOptions,
           step_limit: Callable[[FloatArray], float] | None = None,
           active_set: Callable[[FloatArray], int] | None = None,
           on_accept: Callable[[FloatArray], None] | None = None,
           increment_small: Callable[[FloatArray], bool] | None = None) -> NewtonResult:
    """Solve ``r(u) = 0``.

    Parameters
    ----------
    evaluate : callable
        ``evaluate(u, need_matrix) -> (r, S)``: residual (n,) and, when ``need_matrix``,
        the iteration matrix S (n, n).
    u0 : (n,) float
        Starting guess.
    scale : float
        Force scale of the problem for the relative tolerance.
    step_limit : callable, optional
        ``step_limit(du) -> s <= 1``: the largest fraction of the update ``du`` allowed
        (caps rotation increments).
    active_set : callable, optional
        Fingerprint of the non-smooth state at ``u``; a change refreshes a reused factorisation.
    on_accept : callable, optional
        Told every accepted iterate (lets the caller re-base a configuration).
    increment_small : callable, optional
        ``increment_small(du) -> bool``: a correction ``du`` moves the configuration by less than
        the caller's length and angle tolerances. The line search computes the next (simplified)
        Newton correction at the new iterate; when that is small, the iterate is within it of the
        solution and is accepted, even if the residual test, relative to a force scale, is
        stricter than the configuration needs; only when the residual fell in that iteration.
    """
    u = np.array(u0, dtype=float)
    start_factorizations = solver.factorizations
    tol = options.atol + options.rtol * scale
    fresh = not options.reuse_factorization or solver.lu is None
    r, S = evaluate(u, fresh)
    norm = first_norm = _max_abs(r)
    # the active set only decides whether a kept factorisation may be reused
    track = options.reuse_factorization and active_set is not None
    fingerprint = active_set(u) if track else 0
    for iteration in range(1, options.max_iterations + 1):
        if not math.isfinite(norm):
            return NewtonResult(u, False, iteration - 1, solver.factorizations - start_factorizations,
                                norm, "non-finite residual")
        if norm <= tol:
            return NewtonResult(u, True, iteration - 1, solver.factorizations - start_factorizations, norm)
        if (options.stall_iterations is not None and iteration > options.stall_iterations
                and norm > options.stall_contraction * first_norm):
            return NewtonResult(u, False, iteration - 1, solver.factorizations - start_factorizations,
                                norm, f"stalled: residual {norm:.3g} N after {iteration - 1} "
                                f"iterations, from {first_norm:.3g} N")
        if fresh:
            if S is None:
                _, S = evaluate(u, True)
            try:
                solver.factorize(S)
            except FloatingPointError as exc:
                return NewtonResult(u, False, iteration - 1,
                                    solver.factorizations - start_factorizations, norm, str(exc))
        du = -solver.solve(r)
        if step_limit is not None:
            du *= min(1.0, step_limit(du))
        u, r_new, norm_new, next_du = _line_search(evaluate, solver, u, du)
        if on_accept is not None:
            on_accept(u)
        if (increment_small is not None and next_du is not None and norm_new < norm
                and increment_small(next_du)):
            # the correction is already solved for: apply it (a simplified Newton step). Only
            # while the residual falls: when a thread turns taut within the step the old
            # matrix can make the correction look small although the residual has grown
            return NewtonResult(u + next_du, True, iteration,
                                solver.factorizations - start_factorizations, norm_new)
        contraction = norm_new / norm if norm > 0 else 0.0
        new_fingerprint = active_set(u) if track else 0
        fresh = (not options.reuse_factorization or contraction > options.reuse_contraction
                 or new_fingerprint != fingerprint)
        fingerprint, r, norm, S = new_fingerprint, r_new, norm_new, None
    converged = norm <= tol
    return NewtonResult(u, converged, options.max_iterations,
                        solver.factorizations - start_factorizations, norm,
                        "" if converged else f"no convergence in {options.max_iterations} iterations "
                        f"(residual {norm:.3g} N, tolerance {tol:.3g} N)")


def _line_search(evaluate, solver, u, du):  # type: ignore[no-untyped-def]
    """Deuflhard's natural monotonicity test: accept the damped step ``u + alpha du`` when the
    simplified Newton correction there, computed with the same factorisation, is smaller than
    ``(1 - alpha / 4) |du|``; halve ``alpha`` up to four times. Unlike a test on the residual
    norm it is invariant to the scaling of the equations, so a stiff axial residual after a
    large rotation does not stall the iteration."""
    size = _length(du)
    best = None
    alpha = 1.0
    for _ in range(5):
        trial = u + alpha * du
        r, _ = evaluate(trial, False)
        n = _max_abs(r)
        if math.isfinite(n):
            correction = solver.solve(r)
            size_next = _length(correction)
            if size_next <= (1.0 - 0.25 * alpha) * size or size == 0.0:
                return trial, r, n, -correction
            if best is None or size_next < best[3]:
                best = (trial, r, n, size_next)
        alpha *= 0.5
    if best is None:
        return u + du, np.full_like(u, np.nan), float("nan"), None
    return (*best[:3], None)


def _max_abs(r: FloatArray) -> float:
    """``max |r_i|`` (0 for an empty vector)."""
    return float(np.abs(r).max()) if r.size else 0.0


def _length(x: FloatArray) -> float:
    """Euclidean norm of a vector."""
    return math.sqrt(float(x @ x))
