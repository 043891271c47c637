"""Static equilibria with load stepping, on a :class:`~rodnet.integrate.system.System`."""

from __future__ import annotations

from typing import Any

import numpy as np
import scipy.sparse as sp
from numpy.typing import NDArray

from rodnet.errors import SimulationFailed
from rodnet.integrate.frames import StepStats
from rodnet.integrate.implicit import rotation_cap
from rodnet.integrate.newton import LinearSolver, NewtonOptions, NewtonResult, newton
from rodnet.integrate.system import FrameSink, System
from rodnet.state import Configuration, State

FloatArray = NDArray[np.float64]

STATIC_TIME = float("inf")
"""The time at which a static run evaluates loads: every ``ramp`` is complete, so only the load
factor raises them."""


def solve_static(system: System, state: State, load_steps: int, options: NewtonOptions,
                 on_frame: FrameSink, max_halvings: int = 6,
                 stats: StepStats | None = None) -> StepStats:
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
    scale = max(float(np.max(np.abs(loads))), 1e-2 * system.force_scale)
    state.v = zero
    on_frame(0.0, state)
    done, target_steps = 0.0, [k / load_steps for k in range(1, load_steps + 1)]
    for target in target_steps:
        lam, halvings = done, 0
        while lam < target - 1e-12:
            trial = min(target, lam + (target - done) / 2 ** halvings)
            q_new, result = _static_increment(system, q, trial, options, solver, scale)
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
    return stats


def _static_increment(system: System, q_start: Configuration, load: float, options: NewtonOptions,
                      solver: LinearSolver, scale: float) -> tuple[Configuration, NewtonResult]:
    """Newton on the configuration: each iterate is re-based so rotations can grow without limit."""
    free, zero = system.free, np.zeros(system.n_dof)
    base: dict[str, Any] = {"q": q_start, "u": np.zeros(int(free.sum()))}

    def moved(u: FloatArray) -> Configuration:
        dq = np.zeros(system.n_dof)
        dq[free] = u - base["u"]
        return system.retract(base["q"], dq)

    def evaluate(u: FloatArray, need_matrix: bool) -> tuple[FloatArray, sp.csr_matrix | None]:
        q = moved(u)
        if not need_matrix:
            return system.generalized_force(q, zero, STATIC_TIME, load)[free], None
        g, K, _ = system.tangents(q, zero, STATIC_TIME, load)
        dq = np.zeros(system.n_dof)
        dq[free] = u - base["u"]
        return g[free], system.times_tangent_operator(K, dq).tocsr()

    def rebase(u: FloatArray) -> None:
        base["q"], base["u"] = moved(u), u.copy()

    rot = np.flatnonzero(np.isin(np.flatnonzero(free), system.rotation_dofs()))

    def step_limit(du: FloatArray) -> float:
        return rotation_cap(du[rot], options.max_rotation)

    try:
        result = newton(evaluate, np.zeros(int(free.sum())), scale, solver, options, step_limit,
                        on_accept=rebase)
    except RuntimeError as exc:  # exactly singular tangent
        raise SimulationFailed(
            "the static tangent stiffness is singular: the structure is not supported against "
            "rigid motion (add [[supports]]) or a DOF has no stiffness") from exc
    return moved(result.u), result
