"""Implicit integrators on a :class:`~rodnet.integrate.system.System`: one class per scheme
(Lie-group generalized-alpha, backward Euler, the momentum-conserving midpoint scheme) over one
Newton set-up, and the adaptive driver that marches from frame to frame.

A scheme says what the unknown of a step is and how the state at the end of the step, the
residual and Newton's iteration matrix follow from it (:meth:`Scheme.problem`); :meth:`Scheme.step`
solves that problem by Newton's method (:mod:`rodnet.integrate.newton`) with the rotation cap, the
convergence test on the configuration and the factorisation reuse common to all.

Generalized-alpha follows Arnold & Brüls (2007) in the Chung-Hulbert parametrisation
(``elements/cosserat/FORMULATION.md``, section 9, C39): with ``vd`` the true acceleration
dv/dt and ``a`` the algorithmic one,

    (1 - alpha_m) a1 + alpha_m a0 = (1 - alpha_f) vd1 + alpha_f vd0
    v1 = v0 + h (1 - gamma) a0 + h gamma a1
    q1 = q0 o exp(h [v0 + h (1/2 - beta) a0 + h beta a1])
    M vd1 + g(q1, v1, t1) = 0,

solved by Newton for vd1 with the iteration matrix M + h gamma c C + h^2 beta c K T(dq),
c = (1 - alpha_f) / (1 - alpha_m). The consistent start is a0 = vd0 = -M^-1 g(q0, v0, 0).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, Callable

import numpy as np
import scipy.sparse as sp
from numpy.typing import NDArray

from rodnet.errors import SimulationFailed
from rodnet.integrate.frames import ProgressSink, StepStats
from rodnet.integrate.newton import LinearSolver, NewtonOptions, NewtonResult, newton
from rodnet.integrate.system import FrameSink, System
from rodnet.kernels import so3
from rodnet.state import Configuration, State

FloatArray = NDArray[np.float64]


def chung_hulbert(rho_inf: float) -> tuple[float, float, float, float]:
    """``(alpha_m, alpha_f, gamma, beta)`` of generalized-alpha for spectral radius ``rho_inf``."""
    alpha_m = (2.0 * rho_inf - 1.0) / (rho_inf + 1.0)
    alpha_f = rho_inf / (rho_inf + 1.0)
    gamma = 0.5 + alpha_f - alpha_m
    return alpha_m, alpha_f, gamma, 0.25 * (gamma + 0.5) ** 2


@dataclass
class MotionState:
    """Configuration, velocity (n_dof,), true and algorithmic accelerations (n_dof,)."""

    q: Configuration
    v: FloatArray
    vd: FloatArray
    a: FloatArray
    vd_previous: FloatArray | None = None


@dataclass
class StepProblem:
    """One step as a nonlinear equation in its unknown ``u`` (on the free DOFs).

    Attributes
    ----------
    evaluate : callable
        ``evaluate(u, need_matrix) -> (r, S)``: residual and, when asked, iteration matrix.
    end_state : callable
        ``end_state(u) -> MotionState`` at the end of the step.
    starts : list of (n_free,) arrays
        Starting guesses, tried in turn until Newton converges.
    d_increment : float
        d(configuration increment)/du: converts a Newton correction into the motion it makes.
    """

    evaluate: Callable[[FloatArray, bool], tuple[FloatArray, Any]]
    end_state: Callable[[FloatArray], MotionState]
    starts: list[FloatArray]
    d_increment: float


@dataclass
class Scheme:
    """An implicit scheme on one system, with its Newton settings and linear solver."""

    system: System
    options: NewtonOptions = field(default_factory=NewtonOptions)
    solver: LinearSolver = field(default_factory=LinearSolver)
    name = "scheme"

    def initial(self, q0: Configuration, v0: FloatArray, t0: float) -> MotionState:
        """The start state with the consistent acceleration vd0 = -M^-1 g(q0, v0, t0)."""
        s = self.system
        v = np.where(s.free, v0, 0.0)
        g = s.generalized_force(q0, v, t0)
        vd = np.where(s.free, -g / np.where(s.dof_mass > 0, s.dof_mass, 1.0), 0.0)
        return MotionState(q0, v, vd, vd.copy())

    def problem(self, state: MotionState, t: float, h: float) -> StepProblem:
        """The nonlinear equation of the step from ``t`` to ``t + h``."""
        raise NotImplementedError

    def local_error(self, old: MotionState, new: MotionState, h: float) -> float:
        """Estimated local error [m] of the positions over the step; nan without an estimate."""
        return float("nan")

    def step(self, state: MotionState, t: float, h: float) -> tuple[MotionState, NewtonResult]:
        """Advance ``state`` from ``t`` to ``t + h``; the result says whether Newton converged."""
        return self._solve(state, self.problem(state, t, h))

    # --- the Newton set-up common to every scheme ----------------------------------------

    def _layout(self) -> tuple[NDArray[np.int64], NDArray[np.bool_]]:
        """Positions of the rotational unknowns among the free DOFs, and the translational mask."""
        cached = self.__dict__.get("_layout_cache")
        if cached is None:
            free_dofs = np.flatnonzero(self.system.free)
            is_rot = np.isin(free_dofs, self.system.rotation_dofs())
            cached = (np.flatnonzero(is_rot), ~is_rot)
            self.__dict__["_layout_cache"] = cached
        return cached

    def _solve(self, state: MotionState, p: StepProblem) -> tuple[MotionState, NewtonResult]:
        """Newton on the step's unknown from each of ``p.starts`` in turn until it converges:
        corrections that turn a rotation by more than ``max_rotation`` are shortened, and a
        correction that moves the configuration by less than ``xtol`` ends the solve."""
        s, free = self.system, self.system.free
        reduced_rot, free_trans = self._layout()
        reduced_trans = np.flatnonzero(free_trans)
        length = s.length_scale
        # at the converged previous step M vd = -g, so |M vd| measures the forces acting
        scale = max(float(np.abs(s.dof_mass[free] * state.vd[free]).max(initial=0.0)),
                    1e-2 * s.force_scale)
        d = p.d_increment

        def step_limit(du: FloatArray) -> float:
            return rotation_cap(d * du[reduced_rot], self.options.max_rotation)

        def active_set(u: FloatArray) -> int:
            end = p.end_state(u)
            return s.active_set(end.q, end.v)

        def increment_small(du: FloatArray) -> bool:
            return bool(d * np.abs(du[reduced_trans]).max(initial=0.0) <= self.options.xtol * length
                        and d * np.abs(du[reduced_rot]).max(initial=0.0) <= self.options.xtol)

        for u0 in p.starts:
            result = newton(p.evaluate, u0, scale, self.solver, self.options, step_limit,
                            active_set, increment_small=increment_small)
            if result.converged:
                break
        return p.end_state(result.u), result


@dataclass
class GeneralizedAlpha(Scheme):
    """Lie-group generalized-alpha (C39), unknown ``vd1``; spectral radius ``rho_inf``.

    When the first step fails it is taken as backward Euler instead: the consistent start
    acceleration of a rod with viscosity and a non-rigid initial velocity holds the response of
    the stiff shear/rotary modes (of order 1e13 rad/s^2 for a 1 mm thread), which the scheme's
    predictor turns into a huge first rotation. One first-order step keeps the global second
    order (its local error is O(h^2)).
    """

    rho_inf: float = 0.7
    started: bool = False
    name = "generalized-alpha"

    def step(self, state: MotionState, t: float, h: float) -> tuple[MotionState, NewtonResult]:
        new, result = super().step(state, t, h)
        if not self.started and not result.converged:
            new, result = BackwardEuler(self.system, self.options, self.solver).step(state, t, h)
        self.started = self.started or result.converged
        return new, result

    def problem(self, state: MotionState, t: float, h: float) -> StepProblem:
        s, free = self.system, self.system.free
        M = s.dof_mass[free]
        am, af, gamma, beta = chung_hulbert(self.rho_inf)
        c = (1.0 - af) / (1.0 - am)
        # a, v and dq are affine in the unknown vd: their parts known at the start of the step
        a_known = (af * state.vd - am * state.a) / (1.0 - am)
        v_known = state.v + h * (1.0 - gamma) * state.a
        dq_known = h * state.v + h * h * (0.5 - beta) * state.a

        def unpack(u: FloatArray) -> tuple[MotionState, FloatArray]:
            vd = np.zeros(s.n_dof)
            vd[free] = u
            a = a_known + ((1.0 - af) / (1.0 - am)) * vd
            v = v_known + (h * gamma) * a
            dq = dq_known + (h * h * beta) * a
            return MotionState(s.retract(state.q, dq), v, vd, a, state.vd), dq

        evaluate, state_of = _evaluator(s, unpack, M, t + h, M, h * gamma * c, h * h * beta * c)
        # predictor: the acceleration extrapolated linearly from the last two steps, which saves
        # iterations on smooth motion; the constant-acceleration predictor when that fails
        guesses = [state.vd] if state.vd_previous is None else \
            [2.0 * state.vd - state.vd_previous, state.vd]
        return StepProblem(evaluate, lambda u: state_of(u)[0], [g[free] for g in guesses],
                           h * h * beta * c)

    def local_error(self, old: MotionState, new: MotionState, h: float) -> float:
        """``|beta - 1/6| h^2 |a1 - a0|`` (Zienkiewicz and Xie 1991) over the free translations,
        with the algorithmic accelerations; rotations left out (their stiff, unresolved modes
        carry little of the motion)."""
        return _translation_error(self, abs(chung_hulbert(self.rho_inf)[3] - 1.0 / 6.0),
                                  new.a - old.a, h)


@dataclass
class BackwardEuler(Scheme):
    """Backward Euler, unknown ``v1``: ``q1 = q0 o exp(h v1)``,
    ``M (v1 - v0)/h + g(q1, v1, t1) = 0``. First order; no error estimate."""

    name = "backward-euler"

    def problem(self, state: MotionState, t: float, h: float) -> StepProblem:
        s, free = self.system, self.system.free
        M = s.dof_mass[free]

        def unpack(u: FloatArray) -> tuple[MotionState, FloatArray]:
            v = np.zeros(s.n_dof)
            v[free] = u
            vd = (v - state.v) / h
            dq = h * v
            return MotionState(s.retract(state.q, dq), v, vd, vd, state.vd), dq

        evaluate, state_of = _evaluator(s, unpack, M, t + h, M / h, 1.0, h)
        guesses = [state.vd] if state.vd_previous is None else \
            [2.0 * state.vd - state.vd_previous, state.vd]
        return StepProblem(evaluate, lambda u: state_of(u)[0],
                           [(state.v + h * g)[free] for g in guesses], h)


@dataclass
class Midpoint(Scheme):
    """The momentum-conserving midpoint scheme (FORMULATION.md, C39-C43).

    Unknown: the velocities v1 at the end of the step. With ``dq = h (v0 + v1) / 2`` the
    configuration moves to ``q1 = q0 o exp(dq)``, and the forces are evaluated once, at the
    midpoint ``q_mid = q0 o exp(dq / 2)`` with velocities ``(v0 + v1) / 2``:

        m (v1 - v0) / h + f(q_mid, v_mid, t + h/2) = 0                  (translations)
        [exp(th/2) J W1 - exp(-th/2) J W0] / h + m(q_mid, v_mid) = 0     (rotations)

    ``th`` the rotation increment of a node (the same vector in the start and end body
    frames), ``m`` its body-frame moments without the gyroscopic term. Multiplied by the
    midpoint rotation, the second line is the change of the spatial angular momentum
    ``R J W``; as the internal forces of an objective model at one configuration exert no
    net force or moment, total linear and angular momentum are conserved to Newton's
    tolerance (energy is not: the scheme is second-order and symmetric but not dissipative).
    """

    name = "midpoint"

    def problem(self, state: MotionState, t: float, h: float) -> StepProblem:
        s, free = self.system, self.system.free
        M = s.dof_mass[free]
        n = s.n_dof
        rot = s.rotation_dofs().reshape(-1, 3)
        J = s.dof_mass[rot]
        inertia_rows = M / h
        cache: dict[str, Any] = {}

        def unpack(u: FloatArray) -> tuple[MotionState, Configuration, FloatArray, FloatArray]:
            """End state, midpoint configuration, midpoint velocities and increment for ``u``."""
            if cache.get("u") is not None and np.array_equal(cache["u"], u):
                return cache["end"], cache["q_mid"], cache["v_mid"], cache["dq"]
            v1 = np.zeros(n)
            v1[free] = u
            v_mid = 0.5 * (state.v + v1)
            dq = h * v_mid
            vd = (v1 - state.v) / h
            end = MotionState(s.retract(state.q, dq), v1, vd, vd, state.vd)
            q_mid = s.retract(state.q, 0.5 * dq)
            cache.update(u=u.copy(), end=end, q_mid=q_mid, v_mid=v_mid, dq=dq)
            return end, q_mid, v_mid, dq

        def momentum_rate(end: MotionState, v_mid: FloatArray, dq: FloatArray) -> FloatArray:
            """The inertial term (n_dof,): m dv/h on translations, the midpoint-frame change of
            J W on rotations, minus the gyroscopic term the model adds to its forces."""
            rate = s.dof_mass * (end.v - state.v) / h
            if len(rot):
                half = so3.so3_exp(0.5 * dq[rot])
                W0, W1, Wm = state.v[rot], end.v[rot], v_mid[rot]
                rate[rot] = (np.einsum("rij,rj->ri", half, J * W1)
                             - np.einsum("rji,rj->ri", half, J * W0)) / h - np.cross(Wm, J * Wm)
            return rate

        def evaluate(u: FloatArray, need_matrix: bool) -> tuple[FloatArray, sp.csr_matrix | None]:
            end, q_mid, v_mid, dq = unpack(u)
            rate = momentum_rate(end, v_mid, dq)
            if not need_matrix:
                return (rate + s.generalized_force(q_mid, v_mid, t + 0.5 * h))[free], None
            g, K, C = s.tangents(q_mid, v_mid, t + 0.5 * h)
            # d(mid)/d(v1) = 1/2 for velocities, h/4 T(dq/2) for the configuration; the
            # gyroscopic derivative in C stands in for that of the rotated momenta (equal to O(h))
            S = combine(inertia_rows, 0.5, C, 0.25 * h, s.times_tangent_operator(K, 0.5 * dq))
            return (rate + g)[free], S

        guesses = [state.vd] if state.vd_previous is None else \
            [2.0 * state.vd - state.vd_previous, state.vd]
        guesses.append(np.zeros(n))
        return StepProblem(evaluate, lambda u: unpack(u)[0],
                           [(state.v + h * g)[free] for g in guesses], 0.5 * h)

    def local_error(self, old: MotionState, new: MotionState, h: float) -> float:
        """Trapezoidal positions: ``h^2 |vd1 - vd0| / 12`` over the free translations."""
        return _translation_error(self, 1.0 / 12.0, new.vd - old.vd, h)


SCHEMES: dict[str, type[Scheme]] = {"generalized-alpha": GeneralizedAlpha,
                                     "backward-euler": BackwardEuler, "midpoint": Midpoint}
"""``simulation.integrator`` -> the implicit scheme."""


def _evaluator(s: System, unpack: Callable[[FloatArray], tuple[MotionState, FloatArray]],
               M: FloatArray, t1: float, inertia: FloatArray, weight_C: float,
               weight_K: float) -> tuple[Callable[[FloatArray, bool], tuple[FloatArray, Any]],
                                         Callable[[FloatArray], tuple[MotionState, FloatArray]]]:
    """``evaluate(u, need_matrix)`` of a scheme whose equation is ``M vd1 + g(q1, v1, t1) = 0``
    at the end of the step, with the iteration matrix ``diag(inertia) + weight_C C +
    weight_K K T(dq)``, and ``state_of(u)``: the end state and increment, computed once per
    ``u``."""
    free = s.free
    cache: dict[str, Any] = {}

    def state_of(u: FloatArray) -> tuple[MotionState, FloatArray]:
        if cache.get("u") is not None and np.array_equal(cache["u"], u):
            return cache["state"], cache["dq"]
        new, dq = unpack(u)
        cache.update(u=u.copy(), state=new, dq=dq)
        return new, dq

    def evaluate(u: FloatArray, need_matrix: bool) -> tuple[FloatArray, Any]:
        new, dq = state_of(u)
        if not need_matrix:
            return M * new.vd[free] + s.generalized_force(new.q, new.v, t1)[free], None
        g, S = s.iteration_matrix(new.q, new.v, t1, dq, inertia, weight_C, weight_K)
        return M * new.vd[free] + g[free], S

    return evaluate, state_of


def _translation_error(scheme: Scheme, factor: float, change: FloatArray, h: float) -> float:
    _, free_trans = scheme._layout()
    free = scheme.system.free
    return factor * h * h * float(np.max(np.abs(change[free][free_trans]), initial=0.0))


def rotation_cap(rotation: FloatArray, max_rotation: float) -> float:
    """The fraction of an update whose rotation increments are ``rotation`` that keeps every
    component within ``max_rotation`` [rad] (1 when none exceeds it)."""
    largest = float(np.max(np.abs(rotation), initial=0.0))
    return 1.0 if largest <= max_rotation else max_rotation / largest


def combine(diagonal: FloatArray, a: float, C: sp.csr_matrix, b: float,
            KT: sp.csr_matrix) -> sp.csr_matrix:
    """``diag(diagonal) + a C + b KT``; when C and KT share one sparsity pattern that holds the
    diagonal (the assembled tangents do), the sum is formed on their data arrays."""
    same = (C.indptr is KT.indptr or np.array_equal(C.indptr, KT.indptr)) and \
        (C.indices is KT.indices or np.array_equal(C.indices, KT.indices))
    diag = _diagonal_positions(C) if same else None
    if diag is None:
        return (sp.diags(diagonal) + a * C + b * KT).tocsr()
    data = a * C.data + b * KT.data
    data[diag] += diagonal
    return sp.csr_matrix((data, C.indices, C.indptr), shape=C.shape)


_DIAGONALS: dict[int, tuple[Any, NDArray[np.int64] | None]] = {}


def _diagonal_positions(A: sp.csr_matrix) -> NDArray[np.int64] | None:
    """Positions of the diagonal entries in ``A.data`` (cached per index array), or None when a
    diagonal entry is not stored."""
    key = id(A.indices)
    cached = _DIAGONALS.get(key)
    if cached is not None and cached[0] is A.indices:
        return cached[1]
    n = A.shape[0]
    rows = np.repeat(np.arange(n), np.diff(A.indptr))
    hits = np.flatnonzero(rows == A.indices)
    positions = hits if len(hits) == n else None
    _DIAGONALS[key] = (A.indices, positions)
    return positions


def integrate_implicit(scheme: Scheme, state: State, times: NDArray[np.float64], dt: float,
                       adaptive: bool, on_frame: FrameSink,
                       on_progress: ProgressSink | None = None, dt_max: float | None = None,
                       min_dt: float = 1e-12, error_tolerance: float | None = None,
                       stats: StepStats | None = None) -> StepStats:
    """March ``state`` from ``times[0]`` to ``times[-1]`` landing on every frame time.

    Adaptive: a step whose Newton solve fails is retried with half the step, and the steps after
    it may grow by at most 1.2 per accepted step from there. With an
    ``error_tolerance`` [m] and a scheme that estimates its local error
    (:meth:`Scheme.local_error`), a step whose estimate exceeds the tolerance is rejected and
    every step is resized by ``0.9 (tolerance / error)^(1/3)`` (within 0.2 ... 2; no growth after
    a Newton solve of more than six iterations). Otherwise, after two steps in a row that each
    converged within four iterations the step grows by a quarter. Either way the step stays
    below ``dt_max`` (default: the interval between saved frames). A step that moves a point
    near a rigid body more than its travel limit is retried shorter; friction work of every
    accepted step is added to the state.

    Raises
    ------
    SimulationFailed
        When a step fails at a fixed step size, or the step falls below ``min_dt``.
    """
    stats = StepStats() if stats is None else stats  # filled in place: kept if the run fails
    system = scheme.system
    motion = scheme.initial(state.q, state.v, float(times[0]))
    state.v = motion.v
    on_frame(float(times[0]), state)
    t, h, easy = float(times[0]), dt, 0
    newton_limit = math.inf  # below a step Newton just failed on; relaxed by 1.2 per step
    controlled = adaptive and error_tolerance is not None
    frame_gap = float(np.diff(times).max(initial=dt))
    dt_max = max(dt, frame_gap) if dt_max is None else max(dt, dt_max)
    for t_frame in times[1:]:
        while t < t_frame - 1e-12 * max(1.0, abs(t_frame)):
            h_try = min(h, t_frame - t)
            new, result = scheme.step(motion, t, h_try)
            stats.newton_iterations += result.iterations
            stats.factorizations += result.factorizations
            if not result.converged:
                stats.rejected_steps += 1
                if not adaptive or h_try / 2 < min_dt:
                    raise SimulationFailed(
                        f"Newton's method failed at t = {t:.6g} s with dt = {h_try:.3g} s: "
                        f"{result.message}" + ("" if adaptive else "; reduce simulation.dt or set "
                                               "simulation.adaptive = true"))
                h, easy = h_try / 2, 0
                newton_limit = h
                continue
            travel = system.step_travel(motion.q, new.q)
            if travel > 1.0:  # a point near a body moved too far: it could pass through it
                stats.rejected_steps += 1
                h, easy = 0.9 * h_try / travel, 0
                if h < min_dt:
                    raise SimulationFailed(f"the step fell below {min_dt:.3g} s at t = {t:.6g} s "
                                           "to keep thread points near a body within their "
                                           "travel limit")
                continue
            error = scheme.local_error(motion, new, h_try) if controlled else float("nan")
            if controlled and np.isfinite(error):
                factor = _resize_factor(error, error_tolerance, result.iterations)  # type: ignore[arg-type]
                if error > error_tolerance:  # type: ignore[operator]
                    stats.rejected_steps += 1
                    if h_try * factor < min_dt:
                        raise SimulationFailed(
                            f"the step fell below {min_dt:.3g} s at t = {t:.6g} s: the local "
                            f"error estimate {error:.3g} m stays above simulation.error_tolerance")
                    h = h_try * factor
                    continue
                # a step cut short to land on a frame does not shrink the next one
                h = min(max(h_try * factor, h if h_try < h and factor >= 1.0 else 0.0), dt_max)
            motion, t = new, t + h_try
            stats.record_step(h_try)
            newton_limit *= 1.2
            h = min(h, newton_limit)
            state.friction_work += system.step_work(motion.q, motion.v, h_try)
            if adaptive and not (controlled and np.isfinite(error)):  # growth on easy Newton
                easy = easy + 1 if result.iterations <= 4 else 0
                if easy >= 2 and h_try == h:
                    h, easy = min(1.25 * h, dt_max), 0
            if on_progress is not None:
                on_progress(t, h_try, stats)
        state.q, state.v = motion.q, motion.v
        on_frame(float(t_frame), state)
    return stats


def _resize_factor(error: float, tolerance: float, iterations: int) -> float:
    """Step-size factor from the local error estimate of a second-order scheme: the error
    scales as h^3, so ``0.9 (tolerance / error)^(1/3)``, within 0.2 ... 2, and at most 1 when
    Newton needed more than six iterations."""
    factor = 2.0 if error <= 0.0 else 0.9 * (tolerance / error) ** (1.0 / 3.0)
    factor = min(2.0, max(0.2, factor))
    return min(factor, 1.0) if iterations > 6 else factor
