"""Newton's restrained correction: a correction that turns a rotation node beyond the cap is
solved again with that node's rotations restrained by a diagonal shift
(:func:`rodnet.integrate.newton._restrained`), so that the rest of the correction answers the
shorter turn.

A six-unknown system: a position triple ``x`` and a rotation triple ``w`` (positions 3-5),
coupled, with little stiffness against turning (as the end of a slack thread element), so
that Newton's correction turns ``w`` by far more than the cap.
"""

from __future__ import annotations

import numpy as np

from rodnet.integrate.implicit import rotation_overshoot
from rodnet.integrate.newton import (LinearSolver, NewtonOptions, NewtonProblem, _restrained,
                                     newton)

TRIPLES = np.array([[3, 4, 5]])
CAP = 0.5


def _system() -> tuple[np.ndarray, np.ndarray]:
    """A symmetric positive definite (6, 6) matrix with a soft rotation triple, and a residual."""
    S = np.zeros((6, 6))
    S[:3, :3] = 100.0 * np.eye(3)
    S[3:, 3:] = 1.0 * np.eye(3)
    S[:3, 3:] = S[3:, :3] = 9.0 * np.eye(3)    # 100 * 1 - 81 > 0: definite, soft in w
    r = np.array([1.0, 0.0, 0.0, 2.0, 0.5, 0.0])
    return S, r


def test_overshoot_names_only_the_nodes_beyond_the_cap() -> None:
    du = np.array([9.0, 9.0, 9.0, 0.3, 0.4, 0.0, 0.1, 0.0, 0.0, 0.0])
    triples = np.array([[3, 4, 5], [6, 7, 8]])
    assert rotation_overshoot(du, triples, CAP) is None           # turns 0.5 and 0.1: none over
    du[3:6] = [3.0, 4.0, 0.0]                                     # turns by 5 = 10 caps
    factor = rotation_overshoot(du, triples, CAP)
    assert factor is not None
    np.testing.assert_allclose(factor[3:6], 9.0)
    assert not factor[[0, 1, 2, 6, 7, 8, 9]].any()                # positions, the other node


def test_restrained_correction_solves_the_shifted_system_and_turns_less() -> None:
    S, r = _system()
    du = -np.linalg.solve(S, r)
    turn = np.linalg.norm(du[3:])
    assert turn > CAP                                             # the case this is about
    problem = NewtonProblem(lambda u, m: (r, S), restraint=lambda d: rotation_overshoot(
        d, TRIPLES, CAP))
    restrained = _restrained(problem, LinearSolver(), S, r, du)
    shift = np.zeros(6)
    shift[3:] = (turn / CAP - 1.0) * np.abs(np.diag(S))[3:]
    # consistent: the positions answer the restrained turn, not the unrestrained one
    np.testing.assert_allclose((S + np.diag(shift)) @ restrained, -r, atol=1e-12)
    assert np.linalg.norm(restrained[3:]) < turn
    assert not np.allclose(restrained[:3], du[:3])
    assert r @ restrained < 0.0                                   # still downhill
    # a correction within the cap is left as it is
    small = du * (0.5 * CAP / turn)
    assert _restrained(problem, LinearSolver(), S, r, small) is small


def _quartic_problem(restrain: bool) -> tuple[NewtonProblem, NewtonOptions]:
    """``phi = u S u / 2 + |u|^4 / 16``: a smooth convex potential with its minimum at zero,
    whose Newton correction from the start below turns the rotation triple beyond the cap."""
    S0, _ = _system()

    def grad(u: np.ndarray) -> np.ndarray:
        return S0 @ u + 0.25 * u * (u @ u)

    def evaluate(u: np.ndarray, matrix: str | None):  # type: ignore[no-untyped-def]
        if matrix is None:
            return grad(u), None
        return grad(u), S0 + 0.25 * ((u @ u) * np.eye(6) + 2.0 * np.outer(u, u))

    def merit(u: np.ndarray) -> float:
        return 0.5 * u @ S0 @ u + (u @ u) ** 2 / 16.0

    def shorten(du: np.ndarray) -> np.ndarray:
        out = du.copy()
        turn = np.linalg.norm(du[3:])
        if turn > CAP:
            out[3:] *= CAP / turn
        return out

    problem = NewtonProblem(evaluate, shorten=shorten, merit=merit,
                            restraint=lambda d: rotation_overshoot(d, TRIPLES, CAP))
    return problem, NewtonOptions(restrain=restrain, rtol=1e-12, atol=1e-12)


def test_newton_with_restraint_reaches_the_same_root() -> None:
    u0 = np.array([0.5, -0.2, 0.1, 6.0, -4.0, 2.0])
    problem, _ = _quartic_problem(True)
    r0, S0 = problem.evaluate(u0, "exact")
    assert np.linalg.norm(np.linalg.solve(S0, r0)[3:]) > CAP    # the restraint acts
    for restrain in (True, False):
        problem, options = _quartic_problem(restrain)
        result = newton(problem, u0, 1.0, LinearSolver(), options)
        assert result.converged, result.message
        np.testing.assert_allclose(result.u, 0.0, atol=1e-9)
