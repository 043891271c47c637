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
from dataclasses import dataclass, field, replace
from typing import Any, Callable

import numpy as np
from numpy.typing import NDArray

from rodnet.errors import SimulationFailed
from rodnet.integrate.frames import ProgressSink, StepStats, whole_steps
from rodnet.integrate.mixed import MixedStrains
from rodnet.integrate.newton import (Evaluate, LinearSolver, NewtonOptions, NewtonProblem,
                                     NewtonResult, newton)
from rodnet.integrate.system import FrameSink, System
from rodnet.assembly import add_blocks
from rodnet.kernels import so3, so3_compiled
from rodnet.state import Configuration, State, StepRate

FloatArray = NDArray[np.float64]


def chung_hulbert(rho_inf: float) -> tuple[float, float, float, float]:
    """``(alpha_m, alpha_f, gamma, beta)`` of generalized-alpha for spectral radius ``rho_inf``."""
    alpha_m = (2.0 * rho_inf - 1.0) / (rho_inf + 1.0)
    alpha_f = rho_inf / (rho_inf + 1.0)
    gamma = 0.5 + alpha_f - alpha_m
    return alpha_m, alpha_f, gamma, 0.25 * (gamma + 0.5) ** 2


@dataclass
class MotionState:
    """Configuration, velocity (n_dof,), true and algorithmic accelerations (n_dof,), and what
    multistep schemes and step rates take from the step that ended here.

    Attributes
    ----------
    strain : object or None
        The model's strains at ``q`` (reference of a :class:`~rodnet.state.StepRate`), once
        computed.
    increment : (n_dof,) float or None
        ``dq`` of the step that ended here (``q = q_before o exp(dq)``); ``step`` its size [s].
    v_previous, strain_previous :
        Velocity and strains at the start of that step.
    first_order : bool
        That step was a second-order scheme's backward-Euler step: its start, or a step taken
        again by the energy guard.
    retaken : bool
        That step was taken again by the energy guard (:meth:`Scheme._guarded`).
    energy : (float, float, float) or None
        ``(t, E, W)``: the mechanical energy ``E`` [J] at this state with the loads of time
        ``t`` [s], and ``W`` [J] the loads' change over the step that ended here times its
        motion (:meth:`Scheme._gains_energy`).
    recent : tuple of float
        Within the first ``ENERGY_WINDOW`` steps of a scheme's start, the energies [J] at the
        starts of the steps before the one that ended here (:meth:`Scheme._gains_energy`).
    """

    q: Configuration
    v: FloatArray
    vd: FloatArray
    a: FloatArray
    vd_previous: FloatArray | None = None
    strain: Any = None
    increment: FloatArray | None = None
    step: float = 0.0
    v_previous: FloatArray | None = None
    strain_previous: Any = None
    first_order: bool = False
    retaken: bool = False
    energy: tuple[float, float, float] | None = None
    recent: tuple[float, ...] = ()


@dataclass
class StepProblem:
    """One step as a nonlinear equation in its unknown ``u`` (on the free DOFs).

    Attributes
    ----------
    evaluate : Evaluate
        ``evaluate(u, matrix) -> (r, S)``: residual and, when asked, iteration matrix.
    end_state : callable
        ``end_state(u) -> MotionState`` at the end of the step.
    unpacked : callable
        ``unpacked(u) -> (end state, q_e, v_e, dq_e)``: the forces act at ``q_e = q0 o
        exp(dq_e)`` with the velocities ``v_e``.
    starts : list of (n_free,) arrays
        Starting guesses, tried in turn until Newton converges.
    d_increment : float
        ``d(dq_e)/du``: converts a Newton correction into the motion it makes.
    mixed : MixedStrains
        The strain shift of the mixed Newton step.
    merit : callable, optional
        ``merit(u)``, the step's incremental potential, whose gradient is the residual up to
        small velocity terms, for the line search; None where there is none.
    """

    evaluate: Evaluate
    end_state: Callable[[FloatArray], MotionState]
    unpacked: Callable[[FloatArray], tuple[Any, ...]]
    starts: list[FloatArray]
    d_increment: float
    mixed: MixedStrains
    merit: Callable[[FloatArray], float] | None = None


@dataclass(frozen=True)
class BodyMomentum:
    """A scheme's momentum rate (``rate(u, unpacked)``, free DOFs) whose free-body rotation rows
    are in spatial angular momentum, and those rows' blocks to add to Newton's matrix
    (``tangent(u, unpacked) -> (rows (F, 3), blocks (F, 3, 3))``) (B10)."""

    rate: Callable[[FloatArray, tuple[Any, ...]], FloatArray]
    tangent: Callable[[FloatArray, tuple[Any, ...]], tuple[NDArray[np.int64], FloatArray]]


@dataclass
class Scheme:
    """An implicit scheme on one system, with its Newton settings and linear solver."""

    system: System
    options: NewtonOptions = field(default_factory=NewtonOptions)
    solver: LinearSolver = field(default_factory=LinearSolver)
    history: list[float] | None = None
    """When a list: the residual of every Newton iterate of every step is appended."""
    name = "scheme"
    order = 2
    """Order of accuracy: the local error estimate scales as h^(order + 1)."""

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
        return self._solve(state, self.problem(state, t, h), h)

    def strain(self, state: MotionState) -> Any:
        """The model's strains at ``state`` (computed once)."""
        if state.strain is None:
            state.strain = self.system.strains(state.q, state.v)[0]
        return state.strain

    def _gains_energy(self, old: MotionState, new: MotionState, t: float, h: float) -> bool:
        """Whether the step from ``t`` to ``t + h`` raised the mechanical energy by more than
        :data:`ENERGY_SLACK` of the larger energy in motion and in the threads' strain
        (kinetic plus elastic: at the turning point of a vibration it is all elastic, and the
        kinetic energy alone made smooth vibrations retake steps, a cantilever's first mode
        damped 300 times the scheme's own, outside check). Neither generalized-alpha nor
        variable-step BDF2 is energy-stable on nonlinear problems: where a stiff, non-smooth
        force (a thread snapping taut, a penalty contact) acts over less than a step, their
        extrapolation from the last step can pump energy (measured on the reference net:
        generalized-alpha at 1 ms up to 10 % of the kinetic energy in a step, a smooth
        pendulum's steps below 2e-4; BDF2 with 3 mm threads +10 % by 0.11 s).

        Loads that vary in time do work the energy balance knows only to the scheme's order:
        the rise is the mean of the energy changes with the potentials of ``t`` and of
        ``t + h`` (the loads' work by the trapezoid rule), and may exceed the slack by half
        the difference of the two (the change of the loads times the motion), or of an
        earlier step's times :data:`LOAD_MEMORY` per step since: BDF2's steps after a load
        falls still take up its impulse (the velocity's change a third of the last one's),
        and generalized-alpha's accelerations lag the load. With the end's loads alone, the
        falling side of a load pulse, and the steps after it, were taken for gains, and the
        steps retaken as backward Euler lost 14 - 16 % of a triangular pulse's impulse
        (BDF2, generalized-alpha at a fixed 10 ms; outside check).

        On the :data:`ENERGY_WINDOW` - 1 steps after a scheme's first one, where they are smooth
        (no load changes, no thread turns slack or taut and no contact starts or ends: the same
        :meth:`~rodnet.integrate.system.System.active_set`), the rise is counted from the
        largest energy of the run's states so far: generalized-alpha's start transient raises
        the energy of a vibration by up to 4e-3 of itself at its second step (rho_inf 0.7 at 10
        steps per period, from a velocity start) and gives it back, and counted from the step's
        start alone that step was taken again by backward Euler, which cost an undamped spring
        9 % of its energy at 20 steps per period and 28 % at 10 (outside check). Later steps
        are counted from their start: the same window on every smooth step let a 5 x 5 net of
        rigid knots thrown open (generalized-alpha, ``dt_max`` 1e-4 s) pump energy in, 78,062
        Newton iterations over 0.34 s against 33,527 and elements turned inside out; so
        generalized-alpha at rho_inf 0.5 and 10 steps per period still has steps of a smooth
        vibration taken again (its steady swing 1.4e-3)."""
        s = self.system
        before = s.mechanical_energy(old.q, old.v, t + h)
        if before is None:
            return False
        after = s.mechanical_energy(new.q, new.v, t + h)
        rise = after - before  # type: ignore[operator]
        start = old.energy[1] if old.energy is not None and old.energy[0] == t else \
            s.mechanical_energy(old.q, old.v, t)
        changing = 0.0   # the loads' change over the step times its motion [J]
        if start != before:
            rise_start = s.mechanical_energy(new.q, new.v, t) - start  # type: ignore[operator]
            changing = abs(rise - rise_start)
            rise = 0.5 * (rise + rise_start)
        if old.energy is not None:   # the work of earlier changes, fading step by step
            changing = max(changing, LOAD_MEMORY * old.energy[2])
        new.energy = (t + h, after, changing)  # type: ignore[assignment]
        if changing == 0.0 and 0 < len(old.recent) < ENERGY_WINDOW - 1:   # just started
            new.recent = (*old.recent, before)  # type: ignore[assignment]
        allowed = 0.5 * changing
        kinetic = [0.5 * float(np.einsum("i,i,i", s.dof_mass, v, v)) for v in (old.v, new.v)]
        if not rise > ENERGY_SLACK * max(kinetic) + allowed:
            return False
        moving = max(k + s.model.energy(m.q, m.v[:s.model.n_dof], t + h)["elastic"]
                     for k, m in zip(kinetic, (old, new)))   # only where the kinetic test fails
        if not rise > ENERGY_SLACK * moving + allowed:
            return False
        if changing == 0.0 and old.recent and \
                s.active_set(old.q, old.v) == s.active_set(new.q, new.v):   # a smooth step
            rise = after - max((before, *old.recent))  # type: ignore[operator]
        return rise > ENERGY_SLACK * moving + allowed

    def _unguarded(self, state: MotionState, t: float, h: float,
                   new: MotionState) -> MotionState:
        """``new``, the end of a scheme's first step (taken without the guard), with its
        start's energy as the first of the states the next step is compared with."""
        energy = self.system.mechanical_energy(state.q, state.v, t + h)
        if energy is not None:
            new.recent = (energy,)
        return new

    def _guarded(self, state: MotionState, t: float, h: float, new: MotionState,
                 result: NewtonResult) -> tuple[MotionState, NewtonResult]:
        """``new``, or the step taken again by backward Euler (dissipative for a convex
        potential) when ``new`` gained energy (:meth:`_gains_energy`)."""
        if not (result.converged and self._gains_energy(state, new, t, h)):
            return new, result
        euler, euler_result = BackwardEuler(self.system, self.options, self.solver,
                                            self.history).step(state, t, h)
        euler_result.add_counts(result)
        if not euler_result.converged:
            return new, result
        euler.first_order = euler.retaken = True
        return euler, euler_result

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

    def _equation(self, state: MotionState, unpack: Callable[[FloatArray], tuple[Any, ...]],
                  inertia: FloatArray, u_c: FloatArray, d: float, weight_C: float,
                  t_eval: float, rate: StepRate | None, starts: list[FloatArray],
                  merit_exact: bool,
                  inertial: Callable[[FloatArray, tuple[Any, ...]], FloatArray] | BodyMomentum
                  | None = None,
                  ) -> StepProblem:
        """The step problem (from the guesses ``starts``) whose equation is

            r(u) = inertia (u - u_c) + g(q_e(u), v_e(u), t_eval)       on the free DOFs,

        ``unpack(u) -> (end state, q_e, v_e, dq_e)``: the forces act at ``q_e = q0 o exp(dq_e)``
        with velocities ``v_e``, ``d = d(dq_e)/du``, ``weight_C = d(v_e)/du``, damping at the
        strain rates of ``rate``; Newton's matrix is ``diag(inertia) + weight_C C + d K T(dq_e)``
        with ``K`` and ``C`` as the mixed strains' linearization says. ``inertial(u,
        unpacked)`` replaces the first term where a scheme's momentum rate is not of that form
        (midpoint rotations). The merit ``inertia |u - u_c|^2 / 2 + U(q_e(u)) / d`` (``U`` the
        system's potential) has the residual as its gradient.
        """
        s, free = self.system, self.system.free
        cache: dict[str, Any] = {}
        mixed = MixedStrains(s, state.q, self.options.mixed and rate is not None)
        correction = None
        if isinstance(inertial, BodyMomentum):
            inertial, correction = inertial.rate, inertial.tangent

        def state_of(u: FloatArray) -> tuple[Any, ...]:
            if cache.get("u") is not None and np.array_equal(cache["u"], u):
                return cache["unpacked"]
            unpacked = unpack(u)
            cache.update(u=u.copy(), unpacked=unpacked)
            return unpacked

        def momentum(u: FloatArray, unpacked: tuple[Any, ...]) -> FloatArray:
            return inertia * (u - u_c) if inertial is None else inertial(u, unpacked)

        def evaluate(u: FloatArray, matrix: str | None) -> tuple[FloatArray, Any]:
            unpacked = state_of(u)
            _, q_e, v_e, dq_e = unpacked
            if matrix is None:
                g = s.generalized_force(q_e, v_e, t_eval, rate=rate)
                return momentum(u, unpacked) + g[free], None
            g, S = s.iteration_matrix(q_e, v_e, t_eval, dq_e, inertia, weight_C, d, rate=rate,
                                      linearization=mixed.linearization(dq_e, q_e,
                                                                        matrix == "convex"))
            if correction is not None:
                S = add_blocks(S, *correction(u, unpacked))
            return momentum(u, unpacked) + g[free], S

        def merit(u: FloatArray) -> float:
            _, q_e, _, _ = state_of(u)
            w = u - u_c
            return 0.5 * float(np.einsum("i,i,i", inertia, w, w)) + \
                s.potential(q_e, t_eval, rate=rate) / d  # type: ignore[operator]

        usable = merit_exact and rate is not None   # potential_exact: the system has one
        return StepProblem(evaluate, lambda u: state_of(u)[0], state_of, starts, d, mixed,
                           merit if usable else None)

    def _solve(self, state: MotionState, p: StepProblem, h: float
               ) -> tuple[MotionState, NewtonResult]:
        """Newton on the step's unknown from each of ``p.starts`` in turn until it converges:
        rotation increments longer than ``max_rotation`` are cut to it node by node, and a
        correction that moves the configuration by less than ``xtol`` ends the solve."""
        s, free = self.system, self.system.free
        reduced_rot, free_trans = self._layout()
        reduced_trans = np.flatnonzero(free_trans)
        length = s.length_scale
        # at the converged previous step M vd = -g, so |M vd| measures the forces acting
        scale = max(float(np.abs(s.dof_mass[free] * state.vd[free]).max(initial=0.0)),
                    1e-2 * s.force_scale)
        d = p.d_increment
        triples = self._rotation_triples()

        def shorten(du: FloatArray) -> FloatArray:
            return cap_rotations(du, reduced_rot, triples, self.options.max_rotation / d)

        def small(du: FloatArray) -> bool:
            return bool(d * np.abs(du[reduced_trans]).max(initial=0.0) <= self.options.xtol * length
                        and d * np.abs(du[reduced_rot]).max(initial=0.0) <= self.options.xtol)

        def active_set(u: FloatArray) -> int:
            end = p.end_state(u)
            return s.active_set(end.q, end.v)

        def accept(u: FloatArray) -> None:
            _, q_e, _, dq_e = p.unpacked(u)
            p.mixed.accept(dq_e, q_e)

        def start(u: FloatArray) -> None:
            _, q_e, _, dq_e = p.unpacked(u)
            p.mixed.start(dq_e, q_e)

        def restraint(du: FloatArray) -> FloatArray | None:
            return rotation_overshoot(du, triples, self.options.max_rotation / d)

        weights = np.full(len(free_trans), d / length)
        weights[reduced_rot] = d
        problem = NewtonProblem(p.evaluate, shorten, small, p.merit, weights, accept, active_set,
                                s.dof_mass[free], length, restraint, on_start=start,
                                residual_weights=self._body_weights(state, scale, h))
        rot = s.rotation_dofs()
        # a start that turns a node by more than the rotation cap lies beyond where the
        # exponential map is one-to-one near the solution: left out, unless every start does
        # (then the one that turns least); the starts are looked at in turn, as far as needed
        turns: list[float] = []
        first: FloatArray | None = None   # the first start tried
        result: NewtonResult | None = None
        discarded = [0, 0]   # iterations and factorisations of the starts that failed
        for u0 in p.starts:
            turns.append(float(np.abs(p.end_state(u0).increment[rot]).max(initial=0.0)))  # type: ignore[index]
            if turns[-1] > self.options.max_rotation:
                continue
            if result is not None:
                discarded = [discarded[0] + result.iterations,
                             discarded[1] + result.factorizations]
            first = u0 if first is None else first
            result = newton(problem, u0, scale, self.solver, self.options, self.history)
            if result.converged:
                break
        if first is None or result is None:
            first = p.starts[int(np.argmin(turns))]
            result = newton(problem, first, scale, self.solver, self.options, self.history)
        result.discarded_iterations, result.discarded_factorizations = discarded
        if not result.converged and self.options.restrain:
            # the restrained corrections follow another path, which can end in a valley the
            # plain cut avoids (backward Euler at a fixed 2 ms on the pinned reference net)
            plain = newton(problem, first, scale, self.solver,
                           replace(self.options, restrain=False), self.history)
            plain.add_counts(result)
            result = plain
        return p.end_state(result.u), result

    def _body_weights(self, state: MotionState, scale: float, h: float) -> FloatArray | None:
        """Weights of the residual in Newton's convergence test (free DOFs): 1 on the threads,
        ``scale / body_scale`` (at least 1) on each free body's translations and on its
        rotations, ``body_scale`` being their own force or moment ``|M vd|`` or, at least,
        :data:`BODY_MOMENTUM_FLOOR` of their momentum per step ``|M v| / h``. Without them a
        body's equations would be solved to the threads' tolerance: beside a clamped steel
        post, a tumbling 1 kg box took moment residuals of 1.6e-3 N m each step (1 % of its
        gyroscopic moment) and flipped 1.2 s late. None without free bodies."""
        s = self.system
        groups, rows = self._body_groups()
        if not len(groups):
            return None
        weights = np.ones(int(s.free.sum()))
        for group, row in zip(groups, rows):           # (3,) DOFs: a body's V or its W
            mass = s.dof_mass[group]
            own = max(float(np.abs(mass * state.vd[group]).max()),
                      BODY_MOMENTUM_FLOOR * float(np.abs(mass * state.v[group]).max()) / h)
            if own > 0.0:
                weights[row] = max(1.0, scale / own)
        return weights

    def _body_groups(self) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
        """The free bodies' DOF groups (G, 3) (:meth:`System.body_dof_groups`) and their
        positions among the free DOFs (G, 3), computed once."""
        cached = self.__dict__.get("_body_groups_cache")
        if cached is None:
            s = self.system
            groups = s.body_dof_groups()
            position = np.full(s.n_dof, -1)
            position[np.flatnonzero(s.free)] = np.arange(int(s.free.sum()))
            cached = (groups, position[groups])
            self.__dict__["_body_groups_cache"] = cached
        return cached

    def _rotation_triples(self) -> NDArray[np.int64]:
        """(F, 3) positions among the free DOFs of the rotation nodes whose three rotations are
        free (a node with a supported rotation is capped by its free components alone)."""
        cached = self.__dict__.get("_triples_cache")
        if cached is None:
            position = np.full(self.system.n_dof, -1)
            position[np.flatnonzero(self.system.free)] = np.arange(int(self.system.free.sum()))
            nodes = position[self.system.rotation_dofs()].reshape(-1, 3)
            cached = nodes[(nodes >= 0).all(axis=1)]
            self.__dict__["_triples_cache"] = cached
        return cached

    def _finish(self, state: MotionState, end: MotionState, dq: FloatArray,
                h: float) -> MotionState:
        """``end`` with what the next step takes from this one."""
        end.increment, end.step = dq, h
        end.v_previous, end.strain_previous = state.v, state.strain
        return end

    def _body_momentum(self, momenta: list[tuple[float, Configuration, FloatArray]], h_bar: float
                       ) -> BodyMomentum | None:
        """The momentum rate of a multistep scheme (``inertial`` of :meth:`_equation`) whose
        velocity rate is ``(v1 - sum_k a_k v_k) / h_bar`` (``momenta``: the ``(a_k, q_k, v_k)``),
        with free bodies' rotations in spatial angular momentum (B10): their rows
        ``(J W1 - R1^T pi_ref) / h_bar - W1 x J W1``, ``pi_ref = sum_k a_k R_k J W_k`` (``R``
        the principal axes, ``J`` the principal moments; the last term cancels the gyroscopic
        moment in the forces), and those rows' exact derivative. A torque-free body then keeps
        ``pi = R J W`` to Newton's tolerance whatever the step (``sum_k a_k = 1``), where the
        same rate of the body-axis ``W`` damps its nutation, which turns ``pi``: a 1 m needle
        spun at 10 rev/s lost half of ``|pi|`` to BDF2 and turned it by 96 degrees in 20 s at
        the default steps (outside check). None without free bodies."""
        s = self.system
        groups = s.body_dof_groups()
        if not len(groups):
            return None
        rot = groups[len(groups) // 2:]                       # (F, 3): the bodies' rotations
        J = s.dof_mass[rot]
        rows = (np.cumsum(s.free) - 1)[rot]                  # their free-DOF indices
        reference = sum(a * np.einsum("fij,fj->fi", so3.quat_to_matrix(q.body_quat), J * v[rot])
                        for a, q, v in momenta)
        M = s.dof_mass[s.free]
        v_ref = sum(a * v for a, _, v in momenta)[s.free]

        def rate(u: FloatArray, unpacked: tuple[Any, ...]) -> FloatArray:
            end = unpacked[0]
            out = M * (u - v_ref) / h_bar
            W = end.v[rot]
            R = so3.quat_to_matrix(end.q.body_quat)
            out[rows] = (J * W - np.einsum("fji,fj->fi", R, reference)) / h_bar \
                - np.cross(W, J * W)
            return out

        def tangent(u: FloatArray, unpacked: tuple[Any, ...]) -> tuple[NDArray[np.int64], FloatArray]:
            """Added to the rows' blocks of ``diag(J) / h_bar + (hat(W) J - hat(J W)) +
            h_bar K T``: ``-hat(R1^T pi_ref) T(dq) - (hat(W) J - hat(J W))``."""
            end, _, _, dq = unpacked
            W = end.v[rot]
            body = np.einsum("fji,fj->fi", so3.quat_to_matrix(end.q.body_quat), reference)
            turn = so3_compiled.dexp(np.ascontiguousarray(dq[rot]))
            gyroscopic = so3.hat(W) * J[:, None, :] - so3.hat(J * W)
            return rows, -np.einsum("fij,fjk->fik", so3.hat(body), turn) - gyroscopic

        return BodyMomentum(rate, tangent)

    def _guesses(self, state: MotionState) -> list[FloatArray]:
        """Accelerations to start Newton from: extrapolated linearly from the last two steps
        (saves iterations on smooth motion), the last one, and none."""
        zero = np.zeros_like(state.vd)
        if state.vd_previous is None:
            return [state.vd, zero]
        return [2.0 * state.vd - state.vd_previous, state.vd, zero]


ENERGY_SLACK = 1e-3
"""A generalized-alpha or BDF2 step may raise the mechanical energy by this fraction of the
kinetic plus elastic energy (the scheme's own fluctuation on smooth motion) before it is taken
again as backward Euler."""

ENERGY_WINDOW = 4
"""The steps of a scheme's start whose energy is compared with every state's since the start
(:meth:`Scheme._gains_energy`): over its first four steps generalized-alpha's energy on a
linear vibration never rises by more than :data:`ENERGY_SLACK` above the largest so far
(``rho_inf`` 0.5, 0.7 and 0.9 at 1.5 to 80 steps per period, from displaced and moving starts,
computed from its amplification matrix), while above its last state's by up to 4e-3."""

LOAD_MEMORY = 0.5
"""The fraction of a step's load-work change (:meth:`Scheme._gains_energy`) that the next step's
energy balance may still owe to it: above BDF2's 1/3 and generalized-alpha's 0.31 (rho_inf 0.7)
decay of the response to a load change."""


@dataclass
class GeneralizedAlpha(Scheme):
    """Lie-group generalized-alpha (C39), unknown ``vd1``; spectral radius ``rho_inf``.

    The first step is taken as backward Euler when its predictor turns a rotation by more than
    ``max_rotation``, or when it fails: the consistent start acceleration of a rod with
    viscosity and a non-rigid initial velocity holds the response of the stiff shear/rotary
    modes (of order 1e13 rad/s^2 for a 1 mm thread), which the predictor turns into a huge
    first rotation. One first-order step keeps the global second order (its local error is
    O(h^2)).

    Damping acts at the step's strain rates (:class:`~rodnet.state.StepRate`): from the state
    ``q*``, ``v*`` the step reaches with ``vd1 = 0``, the end configuration moves as
    ``q* o exp(h_bar (v1 - v*))``, ``h_bar = h beta / gamma``.
    """

    rho_inf: float = 0.7
    name = "generalized-alpha"

    def step(self, state: MotionState, t: float, h: float) -> tuple[MotionState, NewtonResult]:
        if state.increment is None:
            rot = self.system.rotation_dofs()
            _, _, dq_known = self._known(state, h)
            if np.abs(dq_known[rot]).max(initial=0.0) <= self.options.max_rotation:
                new, result = super().step(state, t, h)
                if result.converged:
                    return self._unguarded(state, t, h, new), result
            new, result = BackwardEuler(self.system, self.options, self.solver,
                                        self.history).step(state, t, h)
            new.first_order = True
            return self._unguarded(state, t, h, new), result
        return self._guarded(state, t, h, *super().step(state, t, h))

    def _known(self, state: MotionState, h: float) -> tuple[FloatArray, FloatArray, FloatArray]:
        """``a``, ``v`` and ``dq`` at ``vd1 = 0``: they are affine in the unknown."""
        am, af, gamma, beta = chung_hulbert(self.rho_inf)
        a_known = (af * state.vd - am * state.a) / (1.0 - am)
        v_known = state.v + h * (1.0 - gamma) * state.a + h * gamma * a_known
        dq_known = h * state.v + h * h * (0.5 - beta) * state.a + h * h * beta * a_known
        return a_known, v_known, dq_known

    def local_error(self, old: MotionState, new: MotionState, h: float) -> float:
        """``|beta - 1/6| h^2 |a1 - a0|`` (Zienkiewicz and Xie 1991) over the free translations,
        with the algorithmic accelerations; rotations left out (their stiff, unresolved modes
        carry little of the motion). A backward-Euler start: ``h |v1 - v0| / 2``."""
        if new.first_order:
            return _translation_error(self, 0.5, (new.v - old.v) / h, h)
        return _translation_error(self, abs(chung_hulbert(self.rho_inf)[3] - 1.0 / 6.0),
                                  new.a - old.a, h)

    def problem(self, state: MotionState, t: float, h: float) -> StepProblem:
        s, free = self.system, self.system.free
        M = s.dof_mass[free]
        am, af, gamma, beta = chung_hulbert(self.rho_inf)
        c = (1.0 - af) / (1.0 - am)
        a_known, v_known, dq_known = self._known(state, h)

        def unpack(u: FloatArray) -> tuple[MotionState, Configuration, FloatArray, FloatArray]:
            vd = np.zeros(s.n_dof)
            vd[free] = u
            a = a_known + c * vd
            v = v_known + (h * gamma * c) * vd
            dq = dq_known + (h * h * beta * c) * vd
            end = self._finish(state, MotionState(s.retract(state.q, dq), v, vd, a, state.vd),
                               dq, h)
            return end, end.q, v, dq

        rate = s.step_rate(s.retract(state.q, dq_known), v_known, h * beta / gamma)
        d = h * h * beta * c
        return self._equation(state, unpack, M, np.zeros_like(M), d, h * gamma * c,
                              step_end(t, h), rate, [g[free] for g in self._guesses(state)],
                              s.potential_exact)


@dataclass
class BackwardEuler(Scheme):
    """Backward Euler, unknown ``v1``: ``q1 = q0 o exp(h v1)``,
    ``M (v1 - v0)/h + g(q1, v1, t1) = 0``, damping at the strain rates ``(e1 - e0) / h``:
    the gradient of ``|v1 - v0|_M^2 / (2 h) + U(q1) / h``. First order; local error estimate
    ``h |v1 - v0| / 2``."""

    name = "backward-euler"
    order = 1

    def problem(self, state: MotionState, t: float, h: float) -> StepProblem:
        s, free = self.system, self.system.free
        M = s.dof_mass[free]

        def unpack(u: FloatArray) -> tuple[MotionState, Configuration, FloatArray, FloatArray]:
            v = np.zeros(s.n_dof)
            v[free] = u
            vd = (v - state.v) / h
            dq = h * v
            end = self._finish(state, MotionState(s.retract(state.q, dq), v, vd, vd, state.vd),
                               dq, h)
            return end, end.q, v, dq

        rate = _step_rate(self.strain(state), 1.0 / h)
        return self._equation(state, unpack, M / h, state.v[free], h, 1.0, step_end(t, h), rate,
                              [(state.v + h * g)[free] for g in self._guesses(state)],
                              s.potential_exact,
                              inertial=self._body_momentum([(1.0, state.q, state.v)], h))

    def local_error(self, old: MotionState, new: MotionState, h: float) -> float:
        """``h |v1 - v0| / 2`` over the free translations: the first-order term of the step."""
        return _translation_error(self, 0.5, (new.v - old.v) / h, h)


@dataclass
class BDF2(Scheme):
    """Variable-step BDF2 on the Lie group in incremental-potential form; unknown ``v1``.

    In the chart of the start configuration (``q = q0 o exp(x)``; the previous configuration
    is at ``x = -xi``, ``xi`` the last step's increment and ``h_p`` its size), with
    ``omega = h / h_p``, ``alpha = (1 + 2 omega) / (1 + omega)``, ``c = omega^2 / (1 + omega)``
    (FORMULATION.md C53):

        dq = (h v1 + c xi) / alpha,       v_ref = ((1 + omega) v0 - c v_p) / alpha,
        M alpha (v1 - v_ref) / h + g(q0 o exp(dq), v1, t1) = 0,

    with damping at the BDF2 strain rates ``alpha (e1 - e_ref) / h``,
    ``e_ref = ((1 + omega) e0 - c e_p) / alpha``. The equation is the gradient of
    ``alpha |v1 - v_ref|_M^2 / (2 h) + alpha U(q1) / h``: a minimisation where ``U`` is
    convex. A-stable and L-stable, so unresolved stiff modes die out within a step. The first
    step is backward Euler, and so is a step taken again because it gained energy (variable
    steps and non-smooth forces cost BDF2 its linear energy stability; :meth:`_guarded`).
    """

    name = "bdf2"

    def step(self, state: MotionState, t: float, h: float) -> tuple[MotionState, NewtonResult]:
        if state.increment is None:
            start, result = BackwardEuler(self.system, self.options, self.solver,
                                          self.history).step(state, t, h)
            start.first_order = True
            return self._unguarded(state, t, h, start), result
        return self._guarded(state, t, h, *super().step(state, t, h))

    @staticmethod
    def coefficients(h: float, h_previous: float) -> tuple[float, float, float]:
        """``omega, alpha, c`` of a step ``h`` after a step ``h_previous``."""
        omega = h / h_previous
        return omega, (1.0 + 2.0 * omega) / (1.0 + omega), omega * omega / (1.0 + omega)

    def _predictor(self, state: MotionState, h: float) -> list[FloatArray]:
        """Accelerations ``g`` to start Newton from (``v1 = v + h g``): the velocity extrapolated
        along the parabola through the last step's start and end velocities with the slope
        ``vd`` at its end (the step's own interpolant: BDF2's ``vd`` is the derivative of the
        parabola through the last three velocities), then the last acceleration, then none.
        Against the linear extrapolation of the accelerations (:meth:`Scheme._guesses`) it
        saved 8 to 15 % of the Newton iterations of the clamped thread and of the reference
        deployment's first second (docs/rod_model.md, Predictor). After a backward-Euler step,
        whose ``vd`` is the step's mean acceleration, the guesses of :meth:`Scheme._guesses`."""
        if state.first_order:
            return self._guesses(state)
        assert state.v_previous is not None
        hp = state.step
        curvature = (state.v_previous - state.v + hp * state.vd) / (hp * hp)
        return [state.vd + h * curvature, state.vd, np.zeros_like(state.vd)]

    def problem(self, state: MotionState, t: float, h: float) -> StepProblem:
        s, free = self.system, self.system.free
        M = s.dof_mass[free]
        assert state.increment is not None and state.v_previous is not None
        omega, alpha, c = self.coefficients(h, state.step)
        shift = (c / alpha) * state.increment
        v_ref = ((1.0 + omega) * state.v - c * state.v_previous) / alpha

        def unpack(u: FloatArray) -> tuple[MotionState, Configuration, FloatArray, FloatArray]:
            v = np.zeros(s.n_dof)
            v[free] = u
            vd = (alpha / h) * (v - v_ref)
            dq = (h / alpha) * v + shift
            end = self._finish(state, MotionState(s.retract(state.q, dq), v, vd, vd, state.vd),
                               dq, h)
            return end, end.q, v, dq

        previous, current = state.strain_previous, self.strain(state)
        if previous is None and current is not None:
            previous = s.strains(s.retract(state.q, -state.increment), state.v_previous)[0]
        rate = None if current is None else \
            StepRate(((1.0 + omega) * current - c * previous) / alpha, alpha / h)
        momenta = [((1.0 + omega) / alpha, state.q, state.v),
                   (-c / alpha, s.retract(state.q, -state.increment), state.v_previous)]
        return self._equation(state, unpack, (alpha / h) * M, v_ref[free], h / alpha, 1.0,
                              step_end(t, h), rate,
                              [(state.v + h * g)[free] for g in self._predictor(state, h)],
                              s.potential_exact, inertial=self._body_momentum(momenta, h / alpha))

    def local_error(self, old: MotionState, new: MotionState, h: float) -> float:
        """The scheme's local error ``(1 + omega)^2 / (6 omega (1 + 2 omega)) h^3`` times the
        third derivative of the positions, taken as ``|vd1 - vd0| / h``, over the free
        translations (C54); a backward-Euler step (the start, or one taken again by the energy
        guard): ``h |v1 - v0| / 2``."""
        if old.increment is None or new.first_order:
            return _translation_error(self, 0.5, (new.v - old.v) / h, h)
        omega = h / old.step
        factor = (1.0 + omega) ** 2 / (6.0 * omega * (1.0 + 2.0 * omega))
        return _translation_error(self, factor, new.vd - old.vd, h)


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
    Damping acts at the strain rates ``(e_mid - e0) / (h / 2)``.
    """

    name = "midpoint"

    def problem(self, state: MotionState, t: float, h: float) -> StepProblem:
        s, free = self.system, self.system.free
        M = s.dof_mass[free]
        n = s.n_dof
        rot = s.rotation_dofs().reshape(-1, 3)
        J = s.dof_mass[rot]

        def unpack(u: FloatArray) -> tuple[MotionState, Configuration, FloatArray, FloatArray]:
            """End state, midpoint configuration, midpoint velocities and half increment."""
            v1 = np.zeros(n)
            v1[free] = u
            v_mid = 0.5 * (state.v + v1)
            dq = h * v_mid
            vd = (v1 - state.v) / h
            end = self._finish(state, MotionState(s.retract(state.q, dq), v1, vd, vd, state.vd),
                               dq, h)
            return end, s.retract(state.q, 0.5 * dq), v_mid, 0.5 * dq

        def momentum_rate(u: FloatArray, unpacked: tuple[Any, ...]) -> FloatArray:
            """m dv/h on translations, the midpoint-frame change of J W on rotations minus the
            gyroscopic term the model adds to its forces."""
            end, _, v_mid, half_dq = unpacked
            rate = s.dof_mass * (end.v - state.v) / h
            if len(rot):
                half = so3.so3_exp(half_dq[rot])
                W0, W1, Wm = state.v[rot], end.v[rot], v_mid[rot]
                rate[rot] = (np.einsum("rij,rj->ri", half, J * W1)
                             - np.einsum("rji,rj->ri", half, J * W0)) / h - np.cross(Wm, J * Wm)
            return rate[free]

        # d(mid)/d(v1) = 1/2 for velocities, h/4 T(dq/2) for the configuration; the gyroscopic
        # derivative in C stands in for that of the rotated momenta (equal to O(h))
        rate = _step_rate(self.strain(state), 2.0 / h)
        if rate is not None and s.secant_forces:   # energy-conserving forces over the step
            rate = replace(rate, start=state.q)
        return self._equation(state, unpack, M / h, state.v[free], 0.25 * h, 0.5, t + 0.5 * h,
                              rate, [(state.v + h * g)[free] for g in self._guesses(state)],
                              s.potential_exact and not len(rot) and not s.secant_forces,
                              inertial=momentum_rate)

    def local_error(self, old: MotionState, new: MotionState, h: float) -> float:
        """Trapezoidal positions: ``h^2 |vd1 - vd0| / 12`` over the free translations."""
        return _translation_error(self, 1.0 / 12.0, new.vd - old.vd, h)


SCHEMES: dict[str, type[Scheme]] = {"bdf2": BDF2, "generalized-alpha": GeneralizedAlpha,
                                     "backward-euler": BackwardEuler, "midpoint": Midpoint}
"""``simulation.integrator`` -> the implicit scheme."""


def step_end(t: float, h: float) -> float:
    """The end of the step ``(t, t + h]`` seen from inside it, where the schemes evaluate the
    loads: a load that switches at ``t + h`` (the steppers land on such times) acts on this
    step with its value before the switch, so a pulse gives its impulse exactly. The shift,
    1e-9 of the step, changes a smooth load by 1e-9 of its change over the step."""
    end = t + h
    return end - max(1e-9 * h, 4.0 * math.ulp(end))


def _step_rate(reference: Any, inv_h: float) -> StepRate | None:
    """The step rate with these reference strains; None for a model without strains."""
    return None if reference is None else StepRate(reference, inv_h)


def _translation_error(scheme: Scheme, factor: float, change: FloatArray, h: float) -> float:
    """``factor h^2 |change|``, the norm the system measures a change of its velocities by
    (:meth:`~rodnet.integrate.system.System.error_norm`)."""
    return factor * h * h * scheme.system.error_norm(change)


def cap_rotations(du: FloatArray, rotations: NDArray[np.int64], triples: NDArray[np.int64],
                  max_rotation: float) -> FloatArray:
    """``du`` with every rotation longer than ``max_rotation`` [rad] cut to that length, node
    by node: the rotation vectors at the positions ``triples`` (F, 3) by their length, the
    other ``rotations`` (nodes with a supported rotation) component by component. Newton's
    correction can turn a node of little stiffness (a thread's section about its own axis)
    by many radians where the rest of the correction is sound; cutting the whole correction
    to the largest turn would stall the rest.
    """
    if not len(rotations):
        return du
    out = du.copy()
    out[rotations] = np.clip(du[rotations], -max_rotation, max_rotation)
    if len(triples):
        vectors = du[triples]
        length = np.sqrt(np.einsum("ij,ij->i", vectors, vectors))
        factor = np.minimum(1.0, max_rotation / np.maximum(length, max_rotation))
        out[triples] = vectors * factor[:, None]
    return out


def rotation_overshoot(du: FloatArray, triples: NDArray[np.int64],
                       max_rotation: float) -> FloatArray | None:
    """For every DOF of a rotation node (its positions ``triples`` (F, 3) in ``du``) that
    ``du`` turns by ``turn > max_rotation``, ``turn / max_rotation - 1``, zero elsewhere (n,);
    None when no node turns that far (Newton's restrained correction,
    :func:`rodnet.integrate.newton._restrained`)."""
    if not len(triples):
        return None
    vectors = du[triples]
    turn = np.sqrt(np.einsum("ij,ij->i", vectors, vectors))
    over = turn > max_rotation
    if not over.any():
        return None
    out = np.zeros_like(du)
    out[triples[over]] = (turn[over] / max_rotation - 1.0)[:, None]
    return out


def integrate_implicit(scheme: Scheme, state: State, times: NDArray[np.float64], dt: float,
                       adaptive: bool, on_frame: FrameSink,
                       on_progress: ProgressSink | None = None, dt_max: float | None = None,
                       min_dt: float = 1e-12, error_tolerance: float | None = None,
                       stats: StepStats | None = None,
                       restarts: frozenset[float] = frozenset(),
                       newton_shrinks: bool = True) -> StepStats:
    """March ``state`` from ``times[0]`` to ``times[-1]`` landing on every frame time.

    Adaptive: a step whose Newton solve fails is retried with half the step, and the steps after
    it may grow by at most 1.2 per accepted step from there. With an
    ``error_tolerance`` [m] and a scheme that estimates its local error
    (:meth:`Scheme.local_error`), a step whose estimate exceeds the tolerance is rejected and
    every step is resized by ``0.9 (tolerance / error)^(1/3)`` (within 0.2 ... 2) and by at most
    ``(6 / iterations)^(1/2)`` for the Newton iterations it took, or with ``newton_shrinks``
    false not grown after more than 6 (:func:`_resize_factor`).
    Otherwise, after two steps in a row that each converged within four iterations the step
    grows by a quarter. Either way the step stays below ``dt_max`` (default: the interval
    between saved frames), the first one too. A step that moves a point near a rigid body
    more than its travel limit is retried shorter; friction work of every
    accepted step is added to the state. At the times in ``restarts`` (where a load jumps) the
    scheme starts afresh (:meth:`Scheme.initial`: consistent accelerations, a multistep
    scheme's first step), so that no step's formula reaches across the jump.
    ``on_progress(t, h, stats)`` is told every accepted step and every failed solve.

    Raises
    ------
    SimulationFailed
        When a step fails at a fixed step size, the step falls below ``min_dt``, or more than
        :data:`CRAWL_STEPS` steps towards one frame end on one below :data:`CRAWL_FRACTION` of
        the frame interval.
    """
    stats = StepStats() if stats is None else stats  # filled in place: kept if the run fails
    system = scheme.system
    motion = scheme.initial(state.q, state.v, float(times[0]))
    state.v = motion.v
    on_frame(float(times[0]), state)
    if adaptive and dt_max is not None:
        dt = min(dt, dt_max)   # the first step too
    if adaptive:
        dt = min(dt, system.step_limit(motion.v))
    t, h, easy = float(times[0]), dt, 0
    fixed = dt   # the fixed step, before it is shrunk to fill each frame interval
    newton_limit = math.inf  # below a step Newton just failed on; relaxed by 1.2 per step
    controlled = adaptive and error_tolerance is not None
    frame_gap = float(np.diff(times).max(initial=dt))
    dt_max = max(dt, frame_gap) if dt_max is None else max(dt, dt_max)
    for t_frame in times[1:]:
        steps = 0   # accepted steps towards this frame
        if not adaptive:
            h = _equal_steps(fixed, t_frame - t)
        while t < t_frame - 1e-12 * max(1.0, abs(t_frame)):
            h_try = min(h, t_frame - t)
            new, result = scheme.step(motion, t, h_try)
            stats.newton_iterations += result.iterations + result.discarded_iterations
            stats.factorizations += result.factorizations + result.discarded_factorizations
            if not result.converged:
                stats.rejected_steps += 1
                if on_progress is not None:   # a run may be stopped between the retries too
                    on_progress(t, h_try, stats)
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
                fixed = min(fixed, h)
                if h < min_dt:
                    raise SimulationFailed(f"the step fell below {min_dt:.3g} s at t = {t:.6g} s "
                                           "to keep thread points near a body within their "
                                           "travel limit")
                continue
            error = scheme.local_error(motion, new, h_try) if controlled else float("nan")
            if controlled and np.isfinite(error):
                factor = _resize_factor(error, error_tolerance,  # type: ignore[arg-type]
                                        result.iterations, scheme.order, newton_shrinks)
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
            end = t_frame if h_try == t_frame - t else t + h_try   # a frame's time exactly
            record = system.accepted_step(motion.q, motion.v, new.q, new.v, t, end)
            motion, t = new, end
            stats.record_step(h_try)
            steps += 1
            if steps > CRAWL_STEPS and h_try < CRAWL_FRACTION * frame_gap:
                raise SimulationFailed(
                    f"{steps:,} steps since the last frame, the last {h_try:.3g} s long, at t = "
                    f"{t:.6g} s: the step control finds no usable step for the motion there (a "
                    "section spun by a moment that nothing resists); "
                    + ("another integrator (bdf2 and backward-euler damp), "
                       if scheme.name not in ("bdf2", "backward-euler") else "")
                    + "supports or stiffness against that motion")
            stats.retaken_steps += new.retaken
            newton_limit = 1.2 * newton_limit if newton_limit < dt_max else math.inf
            h = min(h, newton_limit)
            if adaptive:
                h = min(h, system.step_limit(motion.v))
            state.friction_work += record.friction_work
            state.load_factor_energy += record.load_factor_energy
            stats.record_accepted(record)
            if adaptive and not (controlled and np.isfinite(error)):  # growth on easy Newton
                easy = easy + 1 if result.iterations <= 4 else 0
                if easy >= 2 and h_try == h:
                    h, easy = min(1.25 * h, dt_max), 0
            if on_progress is not None:
                on_progress(t, h_try, stats)
        state.q, state.v = motion.q, motion.v
        on_frame(float(t_frame), state)
        if float(t_frame) in restarts:
            motion = scheme.initial(motion.q, motion.v, float(t_frame))
    return stats


def _equal_steps(h: float, interval: float) -> float:
    """The fixed step ``h`` [s] shrunk so that a whole number of equal steps fills
    ``interval`` [s] (:func:`~rodnet.integrate.frames.whole_steps`; ``h`` itself where it
    does, to 1e-9 of it, so that such runs step as before): a short last step before each
    frame, where generalized-alpha's accelerations belong to the step size, cost it its second
    order (an outside check: order 1.1 on a tumbling box, frames every 3.5 steps)."""
    n, equal = whole_steps(0.0, interval, h)
    return h if abs(n * h - interval) <= 1e-9 * h else equal


CRAWL_STEPS, CRAWL_FRACTION = 20_000, 1e-5
"""An implicit run stops where it has taken more than this many steps since its last frame and
its last step is shorter than this fraction of the frame interval: its step control has found
no usable step (the midpoint rule on a free tension-only element pushed through itself crawled
at 1e-8 s steps, 11,000 steps in 30 s for 4e-4 s of its 0.02 s, before its stresses took the
step's mean strains, C56), as CVODE's ``mxstep`` stops a solve that takes too many steps
between outputs."""


BODY_MOMENTUM_FLOOR = 1e-4
"""The smallest force scale of a free body's equations, as a fraction of its momentum per step
``|M v| / h``: a body moving uniformly (no force) is solved to ``rtol`` of that, a velocity
error of ``1e-4 rtol`` of its velocity per step, well above round-off."""


NEWTON_TARGET = 6
"""Newton iterations per step that the step control aims at."""


def _resize_factor(error: float, tolerance: float, iterations: int, order: int,
                   newton_shrinks: bool = True) -> float:
    """Step-size factor from the local error estimate of a scheme of order ``order`` and the
    Newton iterations of the step: the error scales as h^(order + 1), so
    ``0.9 (tolerance / error)^(1 / (order + 1))`` within 0.2 ... 2.

    ``newton_shrinks``: at most ``(NEWTON_TARGET / iterations)^(1/2)``, so a step that needed
    many iterations makes the next one shorter and one that needed few lets it grow by less
    than the error alone would (for solves that a shorter step makes easier: nearly free
    rotation nodes). Otherwise at most 1 after more than ``NEWTON_TARGET`` iterations (contact
    and slack-taut steps are not easier when shorter)."""
    factor = 2.0 if error <= 0.0 else 0.9 * (tolerance / error) ** (1.0 / (order + 1))
    factor = min(2.0, max(0.2, factor))
    if not newton_shrinks:
        return min(factor, 1.0) if iterations > NEWTON_TARGET else factor
    return min(factor, (NEWTON_TARGET / max(iterations, 1)) ** 0.5)
