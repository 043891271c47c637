"""Adaptive Dormand-Prince RK45 (scipy) on the lumped model: the independent reference integrator.

It plays the part of the general-purpose ODE solver the seed paper validated against; frames are
taken from its dense output, so they do not constrain its steps.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray
from scipy.integrate import RK45

from rodnet.errors import SimulationFailed
from rodnet.integrate.frames import FrameSink, ProgressSink, StepStats
from rodnet.kernels.lumped_explicit import accumulate_forces
from rodnet.reference.lumped import LumpedModel


def integrate_rk45(model: LumpedModel, x0: NDArray[np.float64], v0: NDArray[np.float64],
                   times: NDArray[np.float64], rtol: float, on_frame: FrameSink,
                   on_progress: ProgressSink | None = None,
                   first_step: float | None = None,
                       stats: StepStats | None = None) -> StepStats:
    """Integrate with RK45 (relative tolerance ``rtol``; absolute tolerance ``rtol`` times 1 mm
    and 1 mm/s) and hand the interpolated state at every frame time to ``on_frame``.

    Raises
    ------
    SimulationFailed
        When the solver fails or the state becomes non-finite; earlier frames are kept.
    """
    n = len(x0)
    stats = StepStats() if stats is None else stats  # filled in place: kept if the run fails

    def rhs(t: float, y: NDArray[np.float64]) -> NDArray[np.float64]:
        x, v = y[:3 * n].reshape(n, 3), y[3 * n:].reshape(n, 3)
        accumulate_forces(x, v, t, force, *args)
        return np.concatenate([y[3 * n:], (force * inv_mass).ravel()])

    force, args, inv_mass = np.empty((n, 3)), model.kernel_arguments(), model.inv_mass[:, None]
    y0 = np.concatenate([np.ravel(x0), np.ravel(v0)]).astype(float)
    solver = RK45(rhs, float(times[0]), y0, float(times[-1]), rtol=rtol, atol=rtol * 1e-3,
                  first_step=first_step)
    on_frame(float(times[0]), np.asarray(x0, float), np.asarray(v0, float))
    next_frame = 1
    while next_frame < len(times):
        message = solver.step()
        if solver.status == "failed" or not np.isfinite(solver.y).all():
            raise SimulationFailed(f"RK45 failed at t = {solver.t:.6g} s: {message or 'non-finite state'}")
        stats.record_step(solver.step_size)
        dense = solver.dense_output()
        while next_frame < len(times) and times[next_frame] <= solver.t + 1e-12:
            y = dense(times[next_frame]) if times[next_frame] < solver.t else solver.y
            on_frame(float(times[next_frame]), y[:3 * n].reshape(n, 3), y[3 * n:].reshape(n, 3))
            next_frame += 1
        if on_progress is not None and stats.steps % 50 == 0:
            on_progress(float(solver.t), float(solver.step_size), stats)
    stats.function_evaluations = solver.nfev
    return stats
