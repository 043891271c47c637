"""Static equilibria with load stepping, on a :class:`~rodnet.integrate.system.System`."""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Any

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla
from scipy.spatial.transform import Rotation
from numpy.typing import NDArray

from rodnet.errors import SimulationFailed
from rodnet.assembly import add_diagonal
from rodnet.integrate.frames import StepStats
from rodnet.integrate.implicit import cap_rotations
from rodnet.integrate.mixed import MixedStrains
from rodnet.integrate.newton import (LinearSolver, NewtonOptions, NewtonProblem, NewtonResult,
                                     newton, tolerance)
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
    split in two (up to ``max_halvings`` times), and where that fails too the load step's
    equilibrium is relaxed to (:func:`_relaxed`); an unstable equilibrium is left for a stable
    one where one is found (:func:`_stable`). ``on_frame(load, state)`` receives the
    equilibrium at the end of every requested increment (and the unloaded start, load 0).
    """
    stats = StepStats() if stats is None else stats  # filled in place: kept if the run fails
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
    solve = _Solve(system, options, LinearSolver(), scale, stats, history)
    done, target_steps = 0.0, [k / load_steps for k in range(1, load_steps + 1)]
    # the largest node motion per load factor of the last load step [m]; before the first, the
    # linear response's, against which a jump is taken at FIRST_JUMP_FACTOR
    rate = _linear_rate(system, q0, loads)
    for target in target_steps:
        q_step = q
        lam, halvings = done, 0
        while lam < target - 1e-12:
            trial = min(target, lam + (target - done) / 2 ** halvings)
            q_new, result = solve.increment(q, trial)
            if not result.converged:
                halvings += 1
                stats.rejected_steps += 1
                if halvings <= max_halvings:
                    continue
                # Newton cannot reach the equilibrium of the increment (a mechanism that must
                # turn far): relax to it from the last one
                q_new, found = _relaxed(solve, q, target, far=True)
                if not found:
                    raise SimulationFailed(f"no static equilibrium found at load factor "
                                           f"{trial:.4g}: {result.message}; relaxing from the "
                                           f"last equilibrium did not reach it either")
                trial = target
            q, lam = q_new, trial
            stats.record_step(trial)
        q = _stable(solve, q, target)
        rate = _watch_jump(system, q_step, q, done, target, rate, stats)
        done = target
        state.q = q
        on_frame(target, state)
    return stats


UNSTABLE_KICK = 1e-2
"""An unstable equilibrium is left along its direction of negative curvature by this fraction of
the structure's size (its largest translation; rotations at most ``max_rotation``)."""

RELAX_REACH = 0.1
"""The first pseudo-time step of :func:`_relaxed` would move the most accelerated DOF by about
this fraction of the structure's size if nothing but its mass resisted."""

RELAX_STEPS = 100
"""Pseudo-time steps :func:`_relaxed` takes before it gives up."""

RELAX_EASY, RELAX_EASY_ITERATIONS = 0.25, 4
"""A pseudo-time step solved within this many Newton iterations lowers ``c`` by this factor
besides the residual's ratio (the next step four times as free, twice as long in time)."""

RELAX_INEXACT = 0.1
"""A pseudo-time step of :func:`_relaxed` with ``far`` is solved to this fraction of the
residual it starts from (or Newton's tolerance, where that is larger)."""

RELAX_STANDING, RELAX_GROW = 0.9, 0.5
"""In :func:`_relaxed` with ``far``: a step after which the residual stands above this fraction
of the last one's lowers ``c`` by this factor instead of the residual's ratio."""


@dataclass
class _Solve:
    """What the increments of one static run share: the system, Newton's options, the linear
    solver, the residual scale [N], the counters and the residual history."""

    system: System
    options: NewtonOptions
    solver: LinearSolver
    scale: float
    stats: StepStats
    history: list[float] | None

    def increment(self, q: Configuration, load: float, inertia: FloatArray | None = None,
                  tolerance: float | None = None) -> tuple[Configuration, NewtonResult]:
        """:func:`_static_increment` from ``q`` at ``load``, counted in :attr:`stats`; with
        ``tolerance`` [N] solved to that residual instead of Newton's own."""
        options = self.options if tolerance is None else \
            replace(self.options, rtol=tolerance / self.scale, atol=0.0)
        moved, result = _static_increment(self.system, q, load, options, self.solver,
                                          self.scale, self.history, inertia)
        self.stats.newton_iterations += result.iterations
        self.stats.factorizations += result.factorizations
        return moved, result


def _stable(solve: _Solve, q: Configuration, load: float) -> Configuration:
    """``q``, an equilibrium at ``load``, or where it is unstable (:func:`unstable`) the
    equilibrium relaxed to from ``q`` moved along its direction of negative curvature by
    :data:`UNSTABLE_KICK` of the size: the move lowers the potential below the saddle's (to
    second order: the force is zero there and the curvature negative along the move) and the
    relaxation lowers it at every step, so it cannot return there (short exact steps first,
    then, where they fail or end unstable, those of a far equilibrium: :func:`_relaxed`).
    Where that fails or ends unstable too, ``q`` is kept and ``stats.extra["unstable"]`` set (the run warns; each
    load step's check replaces the last one's)."""
    system, stats = solve.system, solve.stats
    stats.extra.pop("unstable", None)
    direction = negative_curvature(system, q, load) if _judged(system, q, load) else None
    if direction is None:
        return q
    free = system.free
    rot = _rotation_mask(system)
    move = float(np.abs(direction[~rot]).max(initial=0.0))
    turn = float(np.abs(direction[rot]).max(initial=0.0))
    size = min(UNSTABLE_KICK * system.length_scale / move if move else np.inf,
               solve.options.max_rotation / turn if turn else np.inf)
    dq = np.zeros(system.n_dof)
    dq[free] = size * direction
    for far in (False, True):
        relaxed, found = _relaxed(solve, system.retract(q, dq), load, far)
        if found and negative_curvature(system, relaxed, load) is None:
            return relaxed
    stats.extra["unstable"] = 1.0
    return q


JUMP_FACTOR = 3.0
"""A load step whose largest node motion per load factor is this many times the last step's,
moving a node by more than :data:`JUMP_SIZE` of the structure's size, is taken for a jump of the
equilibrium path (the run warns). Measured on Williams' toggle frame (20 elements):
a smooth approach to the limit point at 99.5 % of its load gives ratios up to 2.04 (6 load
steps), 1.63 (20); a jump past it 4.6 - 8.8 (the square-root path of a limit point reached in
equal steps: at most about 2.4)."""

JUMP_SIZE = 1e-3


FIRST_JUMP_FACTOR = 10.0
"""The first load step is taken for a jump where it moves a node this many times farther than
the linear response at the unloaded state says (a column loaded far past its buckling load
in one step flips over: 1e4 times). Softening before a limit point reached smoothly stays well
below it (Williams' toggle at 99.5 % of its limit load: about 2.5)."""


def _linear_rate(system: System, q0: Configuration, loads: FloatArray) -> float:
    """The linear response's largest node motion per load factor at ``q0`` [m] (the forces
    ``loads`` (n_dof,) that the full load adds, and the tangent at the unloaded configuration
    under it), divided by :data:`FIRST_JUMP_FACTOR` over :data:`JUMP_FACTOR`, so that
    :func:`_watch_jump` compares the first load step with it; 0 where the tangent is singular
    (a slack cable, a mechanism held by its load)."""
    free = system.free
    _, K, _ = system.tangents(q0, np.zeros(system.n_dof), STATIC_TIME, 1.0)
    try:
        with np.errstate(all="ignore"):
            du = spla.splu(K.tocsc()).solve(-loads[free])   # K on the free DOFs
    except RuntimeError:   # exactly singular
        return 0.0
    dq = np.zeros(system.n_dof)
    dq[free] = du
    move = system.retract(q0, dq).x - q0.x
    largest = float(np.max(np.linalg.norm(move, axis=1), initial=0.0))
    if not np.isfinite(largest) or largest > 1e6 * system.length_scale:
        return 0.0
    return largest * FIRST_JUMP_FACTOR / JUMP_FACTOR


def _watch_jump(system: System, q: Configuration, q_new: Configuration, lam: float,
                trial: float, rate: float, stats: StepStats) -> float:
    """The motion per load factor [m] of the load step from ``q`` at ``lam`` to ``q_new`` at
    ``trial`` (an unstable equilibrium left included); where it jumps (:data:`JUMP_FACTOR`),
    the first jump's load factors go to ``stats.extra`` (``jump_from``, ``jump_to``,
    ``jump_move`` [m]), the later ones' count and last load factors to ``jumps_later``,
    ``last_jump_from``, ``last_jump_to``. Load control follows the path of equilibria only up to a limit point
    (a snap-through) or a bifurcation (buckling): past it Newton lands on another branch.
    A structure without supports (held by its contacts alone) is measured after the rigid
    motion that best takes one state to the other: a frictionless net on a sphere turns freely
    about the vertical, a neutral motion that moved its nodes 5 cm in one of 20 load steps and
    was told as a jump."""
    motion = q_new.x - q.x
    if system.free.all() and len(q.x) > 2:
        motion = _shape_change(q.x, q_new.x)
    move = float(np.max(np.linalg.norm(motion, axis=1), initial=0.0))
    now = move / max(trial - lam, 1e-300)
    if rate > 0.0 and now > JUMP_FACTOR * rate and move > JUMP_SIZE * system.length_scale:
        if "jump_from" not in stats.extra:
            stats.extra.update(jump_from=lam, jump_to=trial, jump_move=move)
        else:
            stats.extra.update(jumps_later=stats.extra.get("jumps_later", 0.0) + 1.0,
                               last_jump_from=lam, last_jump_to=trial)
    return now


def _shape_change(x0: FloatArray, x1: FloatArray) -> FloatArray:
    """The node motions (N, 3) [m] from ``x0`` to ``x1`` (N, 3) left after the rigid motion
    (translation of the mean, rotation by Kabsch's least squares) that best takes one to the
    other."""
    a, b = x0 - x0.mean(axis=0), x1 - x1.mean(axis=0)
    turn, _ = Rotation.align_vectors(b, a)
    return b - turn.apply(a)


def _relaxed(solve: _Solve, q: Configuration, load: float, far: bool = False
             ) -> tuple[Configuration, bool]:
    """The equilibrium at ``load`` reached from ``q`` by pseudo-transient continuation (Kelley
    and Keyes 1998, "Convergence analysis of pseudo-transient continuation", SIAM J. Numer.
    Anal. 35): Newton solves of ``g(q) + c M u = 0``, ``u`` the move of the step and ``M`` the
    masses, each the minimum of the potential plus ``c |u|_M^2 / 2`` (a backward-Euler step
    of damped motion that starts at rest, ``c = 1 / h^2``), with ``c`` lowered as the residual
    falls (``c_{k+1} = c_k |r_{k+1}| / |r_k|``, switched evolution relaxation, and by
    :data:`RELAX_EASY` more after an easy step) and raised fourfold where a step's solve
    fails, until the residual of ``g(q) = 0`` is within Newton's tolerance, or a step moves the
    structure by less than Newton's ``xtol`` and Newton's method from there converges. With
    ``far`` (an equilibrium that may lie far away: a load step Newton could not reach) a step
    after which the residual stands (:data:`RELAX_STANDING`) lowers ``c`` by
    :data:`RELAX_GROW`, and each step is solved only to :data:`RELAX_INEXACT` of the residual
    it starts from: a mechanism swinging far under its load (a cable on one pin turning a
    quarter turn) keeps nearly the same residual all the way, and the residual's ratio alone
    left its steps at a few millimetres; and the steps of a cable turning over with a heavy end
    mass stalled in Newton's method at a residual far below the one they started from
    (the tension-only kink), when the pseudo-time path needs no exact step (Kelley and Keyes
    take one Newton iteration per step). Without ``far`` (leaving an unstable equilibrium,
    :func:`_stable`, first) the steps stay short and exact, so that the flow follows the
    negative curvature away from the saddle instead of jumping to a nearby one. Returns the
    configuration reached and whether it is the equilibrium."""
    system, options = solve.system, solve.options
    free, zero = system.free, np.zeros(system.n_dof)
    mass = np.maximum(system.dof_mass[free], 1e-300)
    tol = tolerance(options, solve.scale)
    is_rotation = _rotation_mask(system)

    def residual(at: Configuration) -> FloatArray:
        return system.generalized_force(at, zero, STATIC_TIME, load)[free]

    r = residual(q)
    if not np.isfinite(r).all():
        return q, False
    c = float(np.max(np.abs(r) / mass, initial=0.0)) / (RELAX_REACH * system.length_scale)
    for _ in range(RELAX_STEPS):
        if float(np.abs(r).max(initial=0.0)) <= tol or c == 0.0:
            return q, True
        loose = max(tol, RELAX_INEXACT * float(np.abs(r).max(initial=0.0))) if far else None
        moved, result = solve.increment(q, load, inertia=c * mass, tolerance=loose)
        if not result.converged:
            c *= 4.0
            continue
        r_next = residual(moved)
        if _within_xtol(result.u, is_rotation, options, system.length_scale):
            # at rest within Newton's tolerances, though g = -c M u need not be small where
            # c is large: Newton's method from here decides
            final, plain = solve.increment(moved, load)
            if plain.converged:
                return final, True
        ratio = float(np.linalg.norm(r_next)) / max(float(np.linalg.norm(r)), 1e-300)
        # an easy step lengthens the next pseudo-time step too
        if result.iterations <= RELAX_EASY_ITERATIONS:
            c *= min(ratio, 4.0) * RELAX_EASY
        elif far and ratio > RELAX_STANDING:
            c *= RELAX_GROW
        else:
            c *= min(ratio, 4.0)
        q, r = moved, r_next
    return q, bool(float(np.abs(r).max(initial=0.0)) <= tol)


def _has_potential(system: System, q: Configuration, load: float) -> bool:
    """Whether the static forces have a potential (:meth:`System.static_potential`: with
    contact against fixed bodies too, whose penalty springs have one)."""
    return system.static_potential(q, STATIC_TIME, load) is not None


def _judged(system: System, q: Configuration, load: float) -> bool:
    """Whether an equilibrium's stability is judged by its tangent: where the forces have a
    potential and no contact (a thread resting on a body has directions it can slide along
    without stiffness, which the check would kick it along again and again)."""
    return getattr(system, "contact", None) is None and _has_potential(system, q, load)


def unstable(system: System, q: Configuration, load: float) -> bool:
    """Whether the equilibrium ``q`` at ``load`` is unstable: a saddle of the potential, such as
    a chain folded on itself with links in compression, which Newton's method converges to as
    readily as to a minimum (:func:`negative_curvature`). False where the forces have no
    potential (dead moments, contact): stability is then not a property of the tangent's
    symmetric part."""
    return _judged(system, q, load) and negative_curvature(system, q, load) is not None


def negative_curvature(system: System, q: Configuration, load: float) -> FloatArray | None:
    """A direction (free DOFs) along which the static potential at ``q`` curves down, or None
    where the tangent stiffness ``K`` is positive semidefinite (no eigenvalue of its symmetric
    part below ``-SEMIDEFINITE`` times its largest diagonal entry, or none whose direction's
    curvature ``y^T S y`` stands out of the round-off of its products, :data:`ROUNDOFF`).

    The symmetric part, shifted by that tolerance, is factorised ``P (S + d I) P^T = L D L^T``
    (SuperLU in symmetric mode without pivoting off the diagonal): ``D`` has as many negative
    entries as ``S + d I`` has negative eigenvalues (Sylvester's law of inertia), and for the
    most negative ``D_jj`` the direction ``y = P^T L^-T e_j`` has ``y^T (S + d I) y = D_jj < 0``
    (Gill and Murray's direction of negative curvature, Nocedal and Wright 2006, section
    3.4). Where the pivots show none, an eigenvalue within the shift can still be negative:
    :func:`_lowest_mode` looks for it with the same factors."""
    _, K, _ = system.tangents(q, np.zeros(system.n_dof), STATIC_TIME, load)
    K = sp.csc_matrix(K)
    S = 0.5 * (K + K.T)
    largest = float(np.abs(S.diagonal()).max(initial=0.0))
    if largest == 0.0 or not np.isfinite(S.data).all():
        return None
    shift = SEMIDEFINITE * largest
    shifted = (S + shift * sp.identity(S.shape[0], format="csc")).tocsc()
    try:
        lu = spla.splu(shifted, permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0,
                       options={"SymmetricMode": True})
    except RuntimeError:   # an exactly singular pivot: not a factorisation to judge by
        return None
    if not np.array_equal(lu.perm_r, lu.perm_c):   # pivoted off the diagonal: no inertia
        return _lowest_mode(S, lu, shift, largest)
    pivots = lu.U.diagonal()
    j = int(np.argmin(pivots))
    if not pivots[j] < 0.0:
        return _lowest_mode(S, lu, shift, largest)
    unit = np.zeros(S.shape[0])
    unit[j] = 1.0
    # S + d I = Pr^T L D L^T Pr with Pr[perm_r[k], k] = 1 (scipy's splu): x = z[perm_r]
    y = spla.spsolve_triangular(lu.L.T.tocsr(), unit, lower=False)[lu.perm_r]
    # y^T S y = D_jj - d |y|^2 < 0 in exact arithmetic; the pivot is trusted only where the
    # product, taken directly, is negative beyond its own round-off
    curvature = float(y @ (S @ y))
    bound = float(np.abs(y) @ (abs(S) @ np.abs(y)))
    return y if curvature < -ROUNDOFF * bound else None


def _lowest_mode(S: sp.csc_matrix, lu: Any, shift: float, largest: float) -> FloatArray | None:
    """The eigenvector of the lowest eigenvalue of ``S`` where that eigenvalue lies below
    ``-NEGATIVE`` times ``largest`` (a negative eigenvalue within the factorised ``shift``, which
    the pivots cannot show), else None: :data:`LOWEST_MODES` eigenpairs nearest ``-shift`` by
    shift-invert Lanczos on the factors ``lu`` of ``S + shift I``."""
    n = S.shape[0]
    if n <= LOWEST_MODES + 1:
        w, V = np.linalg.eigh(S.toarray())
    else:
        solve = spla.LinearOperator(S.shape, matvec=lu.solve, dtype=float)
        try:
            w, V = spla.eigsh(S, k=LOWEST_MODES, sigma=-shift, OPinv=solve, which="LM",
                              maxiter=LOWEST_MODE_RESTARTS)
        except spla.ArpackNoConvergence as stopped:   # the pairs it has, if any
            w, V = stopped.eigenvalues, stopped.eigenvectors
        except spla.ArpackError:
            return None
        if not len(w):   # none converged: no verdict beyond the pivots'
            return None
    j = int(np.argmin(w))
    return V[:, j] if w[j] < -NEGATIVE * largest else None


LOWEST_MODES = 6
"""Eigenpairs of the tangent's symmetric part that :func:`_lowest_mode` computes: its zero
modes (free twists) and its softest ones (a column's two buckling planes)."""

LOWEST_MODE_RESTARTS = 30
"""Restarts of the Lanczos iteration of :func:`_lowest_mode` before it stops with the pairs it
has: its searches take two or three (31 - 45 solves) on rods and nets, but hundreds of free
modes at one eigenvalue (the nodes that only slack threads hold in a tilted net of cable threads)
took it 69,000 restarts, 7 s for each check of an 11 x 11 net."""

NEGATIVE = 1e-15
"""An eigenvalue of the tangent's symmetric part below ``-NEGATIVE`` times its largest diagonal
entry is negative (:func:`_lowest_mode`): about ten times the round-off of the tangent's entries,
fifty times a pinned rod's computed free twist (2e-17 of it). A slender column's soft mode sinks
with the mesh: at EA L^2 / EI = 1e7 and 2 % past its buckling load, -8.6e-14 at 160 elements,
within :data:`SEMIDEFINITE` of zero, which the pivots' signs let pass as stable."""

SEMIDEFINITE = 1e-13
"""Eigenvalues of the tangent stiffness above ``-SEMIDEFINITE`` times its largest diagonal entry
count as non-negative (zero modes such as the free twist of a pinned rod are stable enough).
Small, because a slender rod's soft modes sit far below its stiff ones: a column of EA L^2 / EI
= 1e7 in 20 elements at 1.5 times its buckling load has the eigenvalue -0.049 against a largest
diagonal entry of 4e8 (-1.2e-10 of it), which 1e-9 let pass as stable; a pinned rod's free twist
computes to about 1e-8 (2e-17 of it)."""

ROUNDOFF = 1e-14
"""A direction ``y`` of negative curvature counts where ``y^T S y < -ROUNDOFF |y|^T |S| |y|``:
about 50 times the unit round-off, above the error of the products that sum to ``y^T S y``."""


def _rotation_mask(system: System) -> NDArray[np.bool_]:
    """(free DOFs,) whether each free DOF is a rotation."""
    return np.isin(np.flatnonzero(system.free), system.rotation_dofs())


def _within_xtol(du: FloatArray, is_rotation: NDArray[np.bool_], options: NewtonOptions,
                 length: float) -> bool:
    """Whether the move ``du`` (free DOFs) is within Newton's tolerances: every translation
    within ``xtol`` times ``length`` [m], every rotation within ``xtol`` rad."""
    return bool(np.abs(du[~is_rotation]).max(initial=0.0) <= options.xtol * length
                and np.abs(du[is_rotation]).max(initial=0.0) <= options.xtol)


def _static_increment(system: System, q_start: Configuration, load: float, options: NewtonOptions,
                      solver: LinearSolver, scale: float,
                      history: list[float] | None = None,
                      inertia: FloatArray | None = None) -> tuple[Configuration, NewtonResult]:
    """Newton on the configuration: every accepted iterate becomes the base the next
    increments are measured from, so rotations can grow without limit and Newton's matrix is
    always taken at the base (``T(0) = I``). With ``inertia`` (free DOFs), the equation is
    ``g + inertia u = 0``, ``u`` the move from ``q_start``: the minimum of the potential plus
    ``inertia |u|^2 / 2`` (:func:`_relaxed`)."""
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
        held = 0.0 if inertia is None else inertia * u
        if matrix is None:
            return system.generalized_force(q, zero, STATIC_TIME, load)[free] + held, None
        g, K, _ = system.tangents(q, zero, STATIC_TIME, load,
                                  linearization=mixed.linearization(increment(u), q,
                                                                    matrix == "convex"))
        K = K.tocsr()
        return g[free] + held, K if inertia is None else add_diagonal(K, inertia)

    def rebase(u: FloatArray) -> None:
        q = moved(u)
        mixed.accept(increment(u), q)
        mixed.rebase(q)
        base["q"], base["u"] = q, u.copy()

    n_free = int(free.sum())
    is_rotation = _rotation_mask(system)
    rot, trans = np.flatnonzero(is_rotation), np.flatnonzero(~is_rotation)
    weights = np.ones(n_free)
    weights[trans] = 1.0 / system.length_scale
    position = np.full(system.n_dof, -1)
    position[np.flatnonzero(free)] = np.arange(n_free)
    nodes = position[system.rotation_dofs()].reshape(-1, 3)
    triples = nodes[(nodes >= 0).all(axis=1)]

    def shorten(du: FloatArray) -> FloatArray:
        return cap_rotations(du, rot, triples, options.max_rotation)

    def small(du: FloatArray) -> bool:
        return _within_xtol(du, is_rotation, options, system.length_scale)

    merit = None
    if _has_potential(system, q_start, load):
        def merit(u: FloatArray) -> float:
            held = 0.0 if inertia is None else 0.5 * float(np.dot(inertia * u, u))
            return system.static_potential(moved(u), STATIC_TIME, load) + held  # type: ignore[operator]

    problem = NewtonProblem(evaluate, shorten, small, merit, weights, rebase,
                            metric=system.dof_mass[free], length=system.length_scale,
                            rebases=True, to_residual=True)
    result = newton(problem, np.zeros(n_free), scale, solver, options, history)
    if result.singular:
        bodies = ("; contact holds threads only along a body's normal, without friction in a "
                  "static run, so a thread lying on a body can still slide along it (support "
                  "it there, or run the scene dynamically with damping)"
                  if getattr(system, "contact", None) is not None else "")
        raise SimulationFailed(
            "the static tangent stiffness is singular: the structure is not supported against "
            "rigid motion (add [[supports]]), or a load acts along a motion nothing resists "
            "(a moment about a straight rod's axis when no support holds its twist r1; a "
            "slack thread pulled sideways), or a DOF has no stiffness" + bodies)
    return moved(result.u), result
