"""Pieces the tests share to drive a prepared system directly (below ``rodnet.run``)."""

from __future__ import annotations

from typing import Any, Callable

import numpy as np

from rodnet.integrate.explicit import integrate_explicit, scratch
from rodnet.kernels.explicit import forces
from rodnet.models.system import ThreadSystem
from rodnet.state import Configuration, State


def compiled_forces(system: ThreadSystem, x: np.ndarray, v: np.ndarray, t: float,
                    quat: np.ndarray | None = None, W: np.ndarray | None = None) -> np.ndarray:
    """The compiled force (N, 3) [N] of the explicit loop at positions and velocities (N, 3)."""
    problem, _ = system.explicit_problem()
    work = scratch(problem)
    quat = np.zeros((0, 4)) if quat is None else quat
    W = np.zeros((0, 3)) if W is None else W
    forces(t, np.ascontiguousarray(x), np.ascontiguousarray(quat), np.ascontiguousarray(v),
           np.ascontiguousarray(W), problem, work)
    return work.f_node.copy()


def with_explicit_step(system: ThreadSystem, dt: float, stable_step: float | None = None,
                       near_dt: float | None = None) -> ThreadSystem:
    """``system`` stepped explicitly with the fixed step ``dt`` [s] (with bodies, ``near_dt``
    while one is within reach, default ``dt``)."""
    from rodnet.kernels.explicit import StepControl

    control = system.control or StepControl(dt, dt, 0.0, False, np.zeros(1), np.ones(1),
                                            stable_step or dt)
    near = dt if near_dt is None else min(near_dt, dt)
    return ThreadSystem(system.model, system.contact,
                        control._replace(dt=dt, near_dt=near, min_dt=1e-6 * dt))


def run_explicit(system: ThreadSystem, q0: Configuration, v0: np.ndarray, times: np.ndarray,
                 dt: float, on_frame: Callable[[float, State], Any] | None = None) -> State:
    """Step ``system`` from ``q0``, ``v0`` over ``times`` with the fixed step ``dt``; returns
    the final state."""
    stepped = with_explicit_step(system, dt)
    state = stepped.initial_state(q0.copy(), np.array(v0, dtype=float))
    integrate_explicit(stepped, state, times, on_frame or (lambda t, s: None))
    return state


def implicit_scheme(system: ThreadSystem, integrator: str, rho_inf: float, options: Any):
    """The implicit scheme ``integrator`` on ``system`` (``rho_inf`` for generalized-alpha)."""
    from rodnet.integrate.implicit import SCHEMES

    cls = SCHEMES[integrator]
    extra = {"rho_inf": rho_inf} if "rho_inf" in cls.__dataclass_fields__ else {}
    return cls(system, options, **extra)
