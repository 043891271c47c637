"""Explicit symplectic Euler of the lumped model with rigid bodies, compiled.

The step loop is :func:`rodnet.kernels.contact_compiled.advance_contact`: segment forces, loads,
contact, the update (S9) of the nodes and (R1)-(R4) of the free bodies without returning to
Python. The bodies' state is ``model.contact.motion``: reset to the start state here, advanced in
place, and read by the frame sink at every frame. Between two frames the step is the
scene's ``dt`` shrunk so that a whole number of steps fits, as without bodies. When a thread point
near a body would move more than the body's travel limit (E3) in one step (checked with the velocities
at the start of every step), the loop stops before that step and the rest of the frame interval is
taken with 0.9 times the step that respects the limit; the next frame interval starts again from
``dt``. ``dt`` may exceed the stable step with the contact springs, ``near_dt`` (E1): the loop
takes it only while no body is within reach (E5); when a body comes within reach the rest of the
frame interval is taken with ``near_dt`` (or shorter). Friction work goes to
``stats.extra["friction_work"]`` [J].
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
                       on_progress: ProgressSink | None, stats: StepStats,
                       near_dt: float | None = None) -> StepStats:
    """Step ``x``, ``v`` (N, 3) in place from ``times[0]`` to ``times[-1]``; the start frame has
    been handed on already. ``near_dt`` [s]: the step while a body is within reach (default
    ``dt``).

    Raises
    ------
    SimulationFailed
        When a position becomes non-finite, or a point moves so fast that the travel-limited step
        falls below ``MIN_STEP_FRACTION * dt``.
    """
    contact = model.contact
    k = model.kernel_arguments()
    lumped = (*k[:6], model.inv_mass, *k[6:])
    motion = contact.motion
    motion.set(contact.start_motion())
    bodies = (*contact.kernel_arguments(model.inv_mass)[2:],  # from the radius on
              *contact.kernel_motion(motion), motion.quaternion, motion.momentum,
              contact.inv_mass, np.ascontiguousarray(np.where(
                  contact.free[:, None, None], contact.inertia, 0.0)),
              contact.inv_inertia, np.asarray(contact.gravity))
    taken = np.zeros(len(x), dtype=np.bool_)
    body_force = np.zeros((contact.n_bodies, 3))
    body_moment = np.zeros((contact.n_bodies, 3))
    clearance = np.full(contact.n_bodies, -np.inf)
    travelled = np.zeros(contact.n_bodies)
    scratch = np.empty_like(x)
    stats.extra.setdefault("friction_work", 0.0)
    near_dt = dt if near_dt is None else min(near_dt, dt)
    for t_start, t_end in zip(times[:-1], times[1:]):
        t, step = float(t_start), dt
        while True:
            n_steps, h = whole_steps(t, t_end, step)
            peak, done, work, status, allowed = advance_contact(
                x, v, scratch, t, h, n_steps, *lumped, *bodies, taken, body_force, body_moment,
                clearance, travelled, near_dt)
            if done:
                stats.record_step(h, done)
            stats.function_evaluations += done + (status in (2, 3))
            stats.extra["friction_work"] += work
            if status == 1 or not np.isfinite(v).all():  # its peak is the divergence's: not kept
                raise diverged(t + done * h, h, model.stable_step(),
                               "this scene, contact included,")
            stats.max_tension = max(stats.max_tension, peak)
            if status == 0:
                break
            t += done * h
            step = allowed if status == 3 else 0.9 * allowed
            if step < MIN_STEP_FRACTION * dt:
                raise SimulationFailed(
                    f"at t = {t:.6g} s a thread point near a body moves so fast that a step within "
                    f"its travel limit would be {step:.3g} s; check the scene's speeds")
        on_frame(float(t_end), x, v)
        if on_progress is not None:
            on_progress(float(t_end), h, stats)
    return stats
