"""Newton's last resort where no step lowers the potential: the Levenberg-Marquardt correction
of ``|r|^2 / 2`` (:func:`rodnet.integrate.newton._residual_descent`).

A residual whose merit is not its potential: ``r(u) = u + u^3 / 2 - c`` (root ``u*`` with
``u* + u*^3 / 2 = c`` componentwise) judged by ``phi(u) = |u|^2 / 2``, whose minimum (0) is not
the root, as the step potential of a rod is not where gyroscopic moments and long turns put the
residual's root. From ``u = 0`` every step towards the root raises ``phi``.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from rodnet.assembly import BandedMatrix
from rodnet.integrate.newton import LinearSolver, NewtonOptions, NewtonProblem, newton

C = np.array([3.0, -2.0, 0.5])


def _problem(storage: str = "dense") -> NewtonProblem:
    def evaluate(u: np.ndarray, matrix: str | None):  # type: ignore[no-untyped-def]
        r = u + 0.5 * u**3 - C
        if matrix is None:
            return r, None
        S = np.diag(1.0 + 1.5 * u**2)
        return r, (sp.csr_matrix(S) if storage == "csr" else S)
    return NewtonProblem(evaluate, merit=lambda u: 0.5 * float(u @ u))


def _root() -> np.ndarray:
    # u + u^3 / 2 = c has one real root per component (the left side is increasing)
    return np.array([np.real(r[np.abs(np.imag(r)) < 1e-12][0])
                     for r in (np.roots([0.5, 0.0, 1.0, -c]) for c in C)])


def test_newton_reaches_the_root_that_its_merit_does_not_have() -> None:
    for storage in ("dense", "csr"):
        history: list[float] = []
        result = newton(_problem(storage), np.zeros(3), 1.0, LinearSolver(),
                        NewtonOptions(rtol=1e-12, atol=1e-13), history)
        assert result.converged, result.message
        np.testing.assert_allclose(result.u, _root(), rtol=1e-10)
        assert np.linalg.norm(result.u) > 1.0                 # far from the merit's minimum
        # the last iterations are Newton's own: quadratic contraction of the residual
        tail = [h for h in history if h > 1e-12][-3:]
        print(storage, "residuals:", " ".join(f"{h:.2e}" for h in history))
        assert tail[-1] <= 10.0 * tail[-2] ** 2


def test_band_storage_converts_to_the_same_matrix() -> None:
    rng = np.random.default_rng(3)
    n, lower, upper = 7, 2, 1
    order = rng.permutation(n)
    ab = np.asfortranarray(rng.normal(size=(2 * lower + upper + 1, n)))
    band = BandedMatrix(ab, lower, upper, order)
    np.testing.assert_array_equal(band.tocsr().toarray(), band.toarray())
    x = rng.normal(size=n)
    np.testing.assert_allclose(band.tocsr() @ x, band.dot(x), rtol=1e-14)
