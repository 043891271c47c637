"""Explicit symplectic Euler of the lumped model with fixed rigid bodies, compiled.

The step loop is :func:`rodnet.kernels.contact_compiled.advance_contact`: segment forces, loads,
contact and the update (S9) without returning to Python. Between two frames the step is the
scene's ``dt`` shrunk so that a whole number of steps fits, as without bodies. When a thread point
near a body would move more than the body's travel limit (E3) in one step (checked with the velocities
at the start of every step), the loop stops before that step and the rest of the frame interval is
taken with 0.9 times the step that respects the limit; the next frame interval starts again from
``dt``. Friction work goes to ``stats.extra["friction_work"]`` [J].
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from rodnet.errors import SimulationFailed
from rodnet.integrate.explicit import diverged, whole_steps
from rodnet.integrate.frames import FrameSink, ProgressSink, StepStats
from rodnet.kernels.contact_compiled import advance_contact

if TYPE_CHECKING:
    from rodnet.contact.lumped import LumpedContactModel

MIN_STEP_FRACTION = 1e-6
"""A travel-limited step below this fraction of ``dt`` ends the run."""


def march_with_contact(model: LumpedContactModel, x: NDArray[np.float64], v: NDArray[np.float64],
                       times: NDArray[np.float64], dt: float, on_frame: FrameSink,
                       on_progress: ProgressSink | None, stats: StepStats) -> StepStats:
    """Step ``x``, ``v`` (N, 3) in place from ``times[0]`` to ``times[-1]``; the start frame has
    been handed on already.

    Raises
    ------
    SimulationFailed
        When a position becomes non-finite, or a point moves so fast that the travel-limited step
        falls below ``MIN_STEP_FRACTION * dt``.
    """
    contact = model.contact
    k = model.kernel_arguments()
    lumped = (*k[:6], model.inv_mass, *k[6:])
    bodies = contact.kernel_arguments(model.inv_mass)[2:]  # from the radius on
    taken = np.zeros(len(x), dtype=np.bool_)
    body_force = np.zeros((contact.n_bodies, 3))
    scratch = np.empty_like(x)
    stats.extra.setdefault("friction_work", 0.0)
    for t_start, t_end in zip(times[:-1], times[1:]):
        t, step = float(t_start), dt
        while True:
            n_steps, h = whole_steps(t, t_end, step)
            peak, done, work, status, allowed = advance_contact(
                x, v, scratch, t, h, n_steps, *lumped, *bodies, taken, body_force)
            if done:
                stats.record_step(h, done)
            stats.function_evaluations += done + (status == 2)
            stats.max_tension = max(stats.max_tension, peak)
            stats.extra["friction_work"] += work
            if status == 1 or not np.isfinite(v).all():
                raise diverged(t + done * h, h, model.stable_step(),
                               "this scene, contact included,")
            if status == 0:
                break
            t += done * h
            step = 0.9 * allowed
            if step < MIN_STEP_FRACTION * dt:
                raise SimulationFailed(
                    f"at t = {t:.6g} s a thread point near a body moves so fast that a step within "
                    f"its travel limit would be {step:.3g} s; check the scene's speeds")
        on_frame(float(t_end), x, v)
        if on_progress is not None:
            on_progress(float(t_end), h, stats)
    return stats
