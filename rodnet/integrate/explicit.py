"""Explicit symplectic Euler for the lumped model, compiled, stepping exactly onto frame times.

Scheme: ``elements/spring/FORMULATION.md`` (S9); stable step (S10). A model with rigid bodies
runs the compiled loop with contact of :mod:`rodnet.integrate.explicit_contact` instead; a model
without them never touches contact code.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from rodnet.errors import SimulationFailed
from rodnet.integrate.frames import FrameSink, ProgressSink, StepStats
from rodnet.kernels.lumped_explicit import advance
from rodnet.reference.lumped import LumpedModel


def explicit_step(model: LumpedModel, dt: float, adaptive: bool, safety: float) -> float:
    """The step to use: ``safety`` times the stability limit when adaptive, else ``dt`` itself."""
    return safety * model.stable_step() if adaptive else dt


def whole_steps(t_start: float, t_end: float, step: float) -> tuple[int, float]:
    """Steps from ``t_start`` to ``t_end`` [s]: ``step`` [s] shrunk so that a whole number fits.

    Returns
    -------
    n_steps : int
        How many steps, at least one.
    h : float
        Their length [s].
    """
    n_steps = max(1, math.ceil((t_end - t_start) / step - 1e-9))
    return n_steps, (t_end - t_start) / n_steps


def diverged(t: float, h: float, limit: float, scene: str = "this scene") -> SimulationFailed:
    """The error of an explicit run whose state became non-finite.

    Parameters
    ----------
    t : float
        Time [s] at which it was found.
    h : float
        Step [s] in use.
    limit : float
        Stability limit [s] of the scene.
    scene : str
        What ``limit`` is the limit of, as the message names it.
    """
    return SimulationFailed(
        f"the explicit solution diverged (non-finite state) at t = {t:.6g} s with dt = {h:.3g} s; "
        f"the stability limit of {scene} is {limit:.3g} s")


def integrate_explicit(model: LumpedModel, x0: NDArray[np.float64], v0: NDArray[np.float64],
                       times: NDArray[np.float64], dt: float, on_frame: FrameSink,
                       on_progress: ProgressSink | None = None,
                       stats: StepStats | None = None, near_dt: float | None = None) -> StepStats:
    """Step from ``times[0]`` to ``times[-1]``, handing every frame time's state to ``on_frame``.

    Between two frames the step is ``dt`` shrunk so that a whole number of steps fits. With rigid
    bodies, ``near_dt`` [s] (default ``dt``) is the step while a body is within reach of a thread
    (:func:`rodnet.integrate.explicit_contact.march_with_contact`).

    Raises
    ------
    SimulationFailed
        When a position becomes non-finite; every earlier frame has been handed on.
    """
    x, v = np.array(x0, dtype=float), np.array(v0, dtype=float)
    scratch = np.empty_like(x)
    stats = StepStats() if stats is None else stats  # filled in place: kept if the run fails
    on_frame(float(times[0]), x, v)
    if getattr(model, "contact", None) is not None:
        from rodnet.integrate.explicit_contact import march_with_contact

        return march_with_contact(model, x, v, times, dt, on_frame, on_progress, stats, near_dt)
    k = model.kernel_arguments()
    args = (*k[:6], model.inv_mass, *k[6:])
    for t_start, t_end in zip(times[:-1], times[1:]):
        n_steps, h = whole_steps(t_start, t_end, dt)
        peak, done = advance(x, v, scratch, float(t_start), h, n_steps, *args)
        stats.record_step(h, done)
        stats.function_evaluations += done
        if done < n_steps or not np.isfinite(v).all():  # its peak is the divergence's: not kept
            raise diverged(t_start + done * h, h, model.stable_step())
        stats.max_tension = max(stats.max_tension, peak)
        on_frame(float(t_end), x, v)
        if on_progress is not None:
            on_progress(float(t_end), h, stats)
    return stats
