"""The explicit driver: the compiled step loop of :mod:`rodnet.kernels.explicit`, one call per
saved frame, for any system.

Between two frames the step is the system's ``dt`` shrunk so that a whole number of steps fits
(the step control may shorten it further: rotation-controlled steps of rods (C50), and near
rigid bodies (E3), (E5)). The loop runs on numba's threads when more than one is set
(:func:`rodnet.kernels.threads.use_threads`).
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from rodnet.errors import SimulationFailed
from rodnet.integrate.frames import ProgressSink, StepStats, whole_steps
from rodnet.integrate.system import FrameSink, System
from rodnet.kernels.contact_compiled import contact_scratch
from rodnet.kernels import threads
from rodnet.kernels.explicit import (Bodies, ExplicitProblem, Marched, Scratch, StepControl,
                                     march_for, march_nodes, node_forces_only)
from rodnet.kernels.schedule import factor_slopes
from rodnet.state import State


def scratch(problem: ExplicitProblem) -> Scratch:
    """Work arrays of the loop for ``problem``."""
    n, r = problem.nodes.inv_mass.shape[0], problem.rotations.inertia.shape[0]
    e, b = problem.rods.rest_length.shape[0], problem.contact.kind.shape[0]
    return Scratch(np.empty((n, 3)), np.empty((r, 3)), np.empty((e, 12)), np.empty((e, 2)),
                   np.empty((9, 3)), contact_scratch(n, b), NO_RATE)


NO_RATE = np.zeros((0, 3))
"""The loads' rate while no time factor changes (:attr:`Scratch.load_rate`)."""


def _bodies(state: State) -> Bodies:
    m = state.bodies
    if m is None:
        z = np.zeros
        return Bodies(z((0, 3)), z((0, 3)), z((0, 4)), z((0, 3, 3)), z((0, 3)), z((0, 3)))
    return Bodies(m.position, m.velocity, m.quaternion, m.rotation, m.momentum, m.omega)


def _failure(done: Marched, h: float, control: StepControl, problem: ExplicitProblem) -> str:
    """The message of a failed call of the loop."""
    rods = problem.rods.rest_length.shape[0] > 0
    rotation = (f" and the largest element rotation reached {done.phi_max:.3g} rad (limit 2 pi)"
                if rods else "")
    if done.status == 2:
        cause = (f"; the largest element rotation reached {done.phi_max:.3g} rad, near the "
                 "element's limit of 2 pi: the solution diverged there; use more "
                 "elements_per_thread" if rods and done.phi_max > 0.9 * 2.0 * math.pi
                 else "; check the scene's speeds")
        return (f"at t = {done.t:.6g} s a thread point near a body moves so fast that a step "
                f"within its travel limit would be below {control.min_dt:.3g} s{cause}")
    scene = "this scene" if problem.contact.kind.shape[0] == 0 else "the threads alone"
    advice = ("; reduce simulation.explicit_safety, or use more elements_per_thread if that "
              "rotation is near 2 pi") if rods else ""
    return (f"the explicit solution diverged (non-finite state) at t = {done.t:.6g} s with "
            f"dt = {h:.3g} s; the stability limit of {scene} is {control.stable_step:.3g} s"
            f"{rotation}{advice}")


def integrate_explicit(system: System, state: State, times: NDArray[np.float64],
                       on_frame: FrameSink, on_progress: ProgressSink | None = None,
                       stats: StepStats | None = None) -> StepStats:
    """Step ``state`` (in place) from ``times[0]`` to ``times[-1]``, handing every frame time's
    state to ``on_frame``.

    Raises
    ------
    SimulationFailed
        When the state becomes non-finite, or a point near a body moves so fast that its
        travel-limited step falls below the step control's ``min_dt``; every earlier frame has
        been handed on.
    """
    problem, control = system.explicit_problem()
    if control is None:
        raise ValueError("the system was not prepared for the explicit integrator")
    work = scratch(problem)
    bodies = _bodies(state)
    x, quat, v, W = state.q.x, state.q.quat, state.velocities, state.spin
    loop = march_for(problem, threads.current() > 1)
    control = control._replace(blocks=threads.current())   # a block of elements per thread
    rods = problem.rods.rest_length.shape[0] > 0
    nodes_only = node_forces_only(problem, control)   # the fused loop of nodes-only problems
    bodies_near = state.bodies is not None and control.near_dt < control.dt
    stats = StepStats() if stats is None else stats  # filled in place: kept if the run fails

    loads = problem.loads

    def march(a: float, b: float, steps: int, h: float) -> Marched:
        slope, jump = factor_slopes(loads.schedule, a, b)   # linear between a and b
        rate = slope[:, None] * loads.force if slope.any() else NO_RATE
        if nodes_only:
            done = march_nodes(x, v, a, b, steps, h, problem, work.f_node, rate)
        else:
            done = loop(x, quat, v, W, bodies, a, b, steps, h, problem, control,
                        work._replace(load_rate=rate))
        if done.status == 0 and jump.any():   # a factor's jump at b, at b's positions
            return done._replace(load_factor_energy=done.load_factor_energy - float(
                np.einsum("l,li,li->", jump, loads.force, x[loads.nodes])))
        return done

    t0 = float(times[0])   # a call of no steps compiles the loop before the first frame's outputs
    march(t0, t0, 0, control.dt)
    on_frame(t0, state)
    for t_start, t_end in zip(times[:-1], times[1:]):
        n, h = whole_steps(t_start, t_end, control.dt)
        peak = 0.0   # counted once the frame has passed its checks
        pieces = -(-n // CALL_STEPS)
        if bodies_near:   # near a body the loop steps at near_dt: at most CALL_STEPS of those
            pieces = min(n, max(pieces, math.ceil((t_end - t_start) / control.near_dt
                                                  / CALL_STEPS)))
        ends = [0] + [round(i * n / pieces) for i in range(1, pieces + 1)]
        for k in range(pieces):   # one call per frame, unless it would run for minutes
            a = float(t_start) if k == 0 else float(t_start) + ends[k] * h
            b = float(t_end) if k == pieces - 1 else float(t_start) + ends[k + 1] * h
            steps = ends[k + 1] - ends[k]
            done = march(a, b, steps, h)
            stats.function_evaluations += done.evaluations
            state.friction_work += done.friction_work
            state.load_factor_energy += done.load_factor_energy
            if rods:
                stats.max_element_rotation = max(stats.max_element_rotation or 0.0, done.phi_max)
            finite = np.isfinite(v).all() and np.isfinite(W).all()
            if done.status == 0 and finite:  # a failed call's steps and peak are the divergence's
                if done.steps:
                    stats.record_steps(done.steps, done.h_min, done.h_max)
                peak = max(peak, done.peak)
                stats.record_contact(done.contact_force, done.contact_count, done.contact_depth)
            else:
                stats.steps += done.steps
                raise SimulationFailed(_failure(done, h, control, problem))
            if k < pieces - 1 and on_progress is not None:   # progress, and a stop, between
                on_progress(b, h, stats)
        if state.bodies is not None:   # every frame interval takes at least one step
            state.applied_to_bodies = (work.contact.body_force.copy(),
                                       work.contact.body_moment.copy())
        on_frame(float(t_end), state)
        stats.max_tension = max(stats.max_tension, peak)
        if on_progress is not None:
            on_progress(float(t_end), h, stats)
    return stats


CALL_STEPS = 500_000
"""The most steps of one call of the compiled loop: a frame interval of more steps is split, so
that progress is shown and a stop request is acted on within seconds (a signal cannot interrupt
the compiled loop). Fixed steps are the same to the last bit; the rods' step control (C50)
starts afresh at each call."""
