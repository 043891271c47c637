"""Static equilibria with load stepping, on a :class:`~rodnet.integrate.system.System`."""

from __future__ import annotations

from typing import Any

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla
from numpy.typing import NDArray

from rodnet.errors import SimulationFailed
from rodnet.integrate.frames import StepStats
from rodnet.integrate.implicit import cap_rotations
from rodnet.integrate.mixed import MixedStrains
from rodnet.integrate.newton import (LinearSolver, NewtonOptions, NewtonProblem, NewtonResult,
                                     newton)
from rodnet.integrate.system import FrameSink, System
from rodnet.state import Configuration, State

FloatArray = NDArray[np.float64]

STATIC_TIME = float("inf")
"""The time at which a static run evaluates loads: every ``ramp`` is complete, so only the load
factor raises them."""


def solve_static(system: System, state: State, load_steps: int, options: NewtonOptions,
                 on_frame: FrameSink, max_halvings: int = 6,
                 stats: StepStats | None = None, history: list[float] | None = None) -> StepStats:
    """Equilibrium ``g(q, 0, load) = 0`` under loads raised in ``load_steps`` equal increments,
    from the configuration of ``state`` (moved to the equilibrium, in place).

    Each increment is solved by Newton from the previous equilibrium; a failed increment is
    split in two (up to ``max_halvings`` times). ``on_frame(load, state)`` receives the
    equilibrium at the end of every requested increment (and the unloaded start, load 0).
    """
    stats = StepStats() if stats is None else stats  # filled in place: kept if the run fails
    solver = LinearSolver()
    zero = np.zeros(system.n_dof)
    q0 = state.q
    q = q0
    loads = system.generalized_force(q0, zero, STATIC_TIME, 1.0) - system.generalized_force(q0, zero, STATIC_TIME, 0.0)
    # Newton's tolerance is relative to the loads (a light load on a stiff thread is solved to
    # the same relative accuracy as a heavy one); without loads, to the structure's forces
    largest = float(np.max(np.abs(loads), initial=0.0))
    scale = largest if largest > 0.0 else 1e-2 * system.force_scale
    state.v = zero
    on_frame(0.0, state)
    done, target_steps = 0.0, [k / load_steps for k in range(1, load_steps + 1)]
    for target in target_steps:
        lam, halvings = done, 0
        while lam < target - 1e-12:
            trial = min(target, lam + (target - done) / 2 ** halvings)
            q_new, result = _static_increment(system, q, trial, options, solver, scale, history)
            stats.newton_iterations += result.iterations
            stats.factorizations += result.factorizations
            if not result.converged:
                halvings += 1
                stats.rejected_steps += 1
                if halvings > max_halvings:
                    raise SimulationFailed(f"no static equilibrium found at load factor {trial:.4g}: "
                                           f"{result.message}")
                continue
            q, lam = q_new, trial
            stats.record_step(trial)
        done = target
        state.q = q
        on_frame(target, state)
    if unstable(system, q, done):
        stats.extra["unstable"] = 1.0
    return stats


def unstable(system: System, q: Configuration, load: float) -> bool:
    """Whether the equilibrium ``q`` at ``load`` is unstable: a saddle of the potential, such as
    a chain folded on itself with links in compression, which Newton's method converges to as
    readily as to a minimum (:func:`negative_curvature`). False where the forces have no
    potential (dead moments, contact): stability is then not a property of the tangent's
    symmetric part."""
    if not system.potential_exact or system.potential(q, STATIC_TIME, load) is None:
        return False
    return negative_curvature(system, q, load) is not None


def negative_curvature(system: System, q: Configuration, load: float) -> FloatArray | None:
    """A direction (free DOFs) along which the static potential at ``q`` curves down, or None
    where the tangent stiffness ``K`` is positive semidefinite (no eigenvalue of its symmetric
    part below ``-SEMIDEFINITE`` times its largest diagonal entry).

    The symmetric part, shifted by that tolerance, is factorised ``P (S + d I) P^T = L D L^T``
    (SuperLU in symmetric mode without pivoting off the diagonal): ``D`` has as many negative
    entries as ``S + d I`` has negative eigenvalues (Sylvester's law of inertia), and for the
    most negative ``D_jj`` the direction ``y = P^T L^-T e_j`` has ``y^T (S + d I) y = D_jj < 0``
    (Gill and Murray's direction of negative curvature, Nocedal and Wright 2006, section
    3.4)."""
    _, K, _ = system.tangents(q, np.zeros(system.n_dof), STATIC_TIME, load)
    K = sp.csc_matrix(K)
    S = 0.5 * (K + K.T)
    largest = float(np.abs(S.diagonal()).max(initial=0.0))
    if largest == 0.0 or not np.isfinite(S.data).all():
        return None
    shifted = (S + SEMIDEFINITE * largest * sp.identity(S.shape[0], format="csc")).tocsc()
    try:
        lu = spla.splu(shifted, permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0,
                       options={"SymmetricMode": True})
    except RuntimeError:   # an exactly singular pivot: not a factorisation to judge by
        return None
    if not np.array_equal(lu.perm_r, lu.perm_c):   # pivoted off the diagonal: no inertia
        return None
    pivots = lu.U.diagonal()
    j = int(np.argmin(pivots))
    if not pivots[j] < 0.0:
        return None
    unit = np.zeros(S.shape[0])
    unit[j] = 1.0
    # S + d I = Pr^T L D L^T Pr with Pr[perm_r[k], k] = 1 (scipy's splu): x = z[perm_r]
    return spla.spsolve_triangular(lu.L.T.tocsr(), unit, lower=False)[lu.perm_r]


SEMIDEFINITE = 1e-9
"""Eigenvalues of the tangent stiffness above ``-SEMIDEFINITE`` times its largest diagonal entry
count as non-negative (zero modes such as the free twist of a pinned rod are stable enough)."""


def _static_increment(system: System, q_start: Configuration, load: float, options: NewtonOptions,
                      solver: LinearSolver, scale: float,
                      history: list[float] | None = None) -> tuple[Configuration, NewtonResult]:
    """Newton on the configuration: every accepted iterate becomes the base the next
    increments are measured from, so rotations can grow without limit and Newton's matrix is
    always taken at the base (``T(0) = I``)."""
    free, zero = system.free, np.zeros(system.n_dof)
    base: dict[str, Any] = {"q": q_start, "u": np.zeros(int(free.sum()))}
    mixed = MixedStrains(system, q_start, options.mixed)

    def increment(u: FloatArray) -> FloatArray:
        dq = np.zeros(system.n_dof)
        dq[free] = u - base["u"]
        return dq

    def moved(u: FloatArray) -> Configuration:
        return system.retract(base["q"], increment(u))

    def evaluate(u: FloatArray, matrix: str | None) -> tuple[FloatArray, sp.csr_matrix | None]:
        q = moved(u)
        if matrix is None:
            return system.generalized_force(q, zero, STATIC_TIME, load)[free], None
        g, K, _ = system.tangents(q, zero, STATIC_TIME, load,
                                  linearization=mixed.linearization(increment(u), q,
                                                                    matrix == "convex"))
        return g[free], K.tocsr()

    def rebase(u: FloatArray) -> None:
        q = moved(u)
        mixed.accept(increment(u), q)
        mixed.rebase(q)
        base["q"], base["u"] = q, u.copy()

    n_free = int(free.sum())
    rot = np.flatnonzero(np.isin(np.flatnonzero(free), system.rotation_dofs()))
    trans = np.setdiff1d(np.arange(n_free), rot)
    weights = np.ones(n_free)
    weights[trans] = 1.0 / system.length_scale
    position = np.full(system.n_dof, -1)
    position[np.flatnonzero(free)] = np.arange(n_free)
    nodes = position[system.rotation_dofs()].reshape(-1, 3)
    triples = nodes[(nodes >= 0).all(axis=1)]

    def shorten(du: FloatArray) -> FloatArray:
        return cap_rotations(du, rot, triples, options.max_rotation)

    def small(du: FloatArray) -> bool:
        return bool(np.abs(du[trans]).max(initial=0.0) <= options.xtol * system.length_scale
                    and np.abs(du[rot]).max(initial=0.0) <= options.xtol)

    merit = None
    if system.potential_exact and system.potential(q_start, STATIC_TIME, load) is not None:
        def merit(u: FloatArray) -> float:
            return system.potential(moved(u), STATIC_TIME, load)  # type: ignore[return-value]

    problem = NewtonProblem(evaluate, shorten, small, merit, weights, rebase,
                            metric=system.dof_mass[free], length=system.length_scale)
    result = newton(problem, np.zeros(n_free), scale, solver, options, history)
    if result.singular:
        raise SimulationFailed(
            "the static tangent stiffness is singular: the structure is not supported against "
            "rigid motion (add [[supports]]) or a DOF has no stiffness")
    return moved(result.u), result
