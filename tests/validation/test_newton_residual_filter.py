"""Newton's full step where it halves the smallest residual (:func:`rodnet.integrate.newton.
_halves_residual`), though the potential rises along it.

A residual that is the potential's gradient up to a small constant, as a rod's residual is its
step potential's gradient up to the rotated momenta and the damping at the step's strain
rates: ``r(u) = u + u^3 / 2 - c``, ``phi(u) = sum(u^2 / 2 + u^4 / 8) - (c + d) . u`` with
``grad phi = r - d``. The potential's minimum is where ``r = d``, off the root; near the root
every full Newton step raises ``phi``.
"""

from __future__ import annotations

import numpy as np
import pytest

import rodnet.integrate.newton as newton_module
from rodnet.integrate.newton import LinearSolver, NewtonOptions, NewtonProblem, newton

C = np.array([3.0, -2.0, 0.5, 1.0])
D = np.array([1e-2, -2e-2, 5e-3, 1e-2])


def _problem() -> NewtonProblem:
    def evaluate(u: np.ndarray, matrix: str | None):  # type: ignore[no-untyped-def]
        r = u + 0.5 * u**3 - C
        return r, (None if matrix is None else np.diag(1.0 + 1.5 * u**2))
    return NewtonProblem(evaluate, merit=lambda u: float(np.sum(0.5 * u**2 + u**4 / 8) - (C + D) @ u))


def _solve() -> tuple[object, list[float]]:
    history: list[float] = []
    result = newton(_problem(), np.zeros(4), 1.0, LinearSolver(),
                    NewtonOptions(rtol=1e-12, atol=1e-13), history)
    print("residuals:", " ".join(f"{h:.2e}" for h in history))
    return result, history


def test_full_steps_that_halve_the_residual_converge_quadratically_past_the_merit_minimum() -> None:
    result, history = _solve()
    assert result.converged, result.message  # type: ignore[attr-defined]
    r, _ = _problem().evaluate(result.u, None)  # type: ignore[attr-defined]
    assert np.abs(r).max() <= 1e-12
    assert result.iterations <= 8  # type: ignore[attr-defined]
    tail = [h for h in history if h > 1e-13][-3:]
    assert tail[-1] <= 10.0 * tail[-2] ** 2 and tail[-2] <= 10.0 * tail[-3] ** 2


def test_judged_by_the_potential_alone_the_solve_stalls_at_the_merit_minimum(
        monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(newton_module, "RESIDUAL_FILTER", 0.0)
    result, history = _solve()
    assert not result.converged  # type: ignore[attr-defined]
    # the full step from 2e-4 reaches 5e-9 but raises phi: the watchdog goes back to 2e-4,
    # and no later step lowers phi enough to leave it
    assert min(history) < 1e-6 and history[-1] > 1e-4
