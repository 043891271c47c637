"""Compiled force loop and explicit (symplectic Euler) step loop of the lumped model.

One call advances the state by ``n_steps`` steps without returning to Python; the force law is
the one of :mod:`rodnet.kernels.tension` (``elements/spring/FORMULATION.md`` (S3)-(S5)), written
out per segment, and the update is (S9). ``tests/reference/test_lumped.py`` checks this loop
against the vectorised NumPy forces.
"""

from __future__ import annotations

import math

import numba
import numpy as np


@numba.njit(cache=True)
def accumulate_forces(x, v, t, force,
                      segments, rest_length, EA, etaA, kink_strain, tension_only,
                      gravity_force, load_nodes, load_force, load_ramp):  # pragma: no cover
    """Overwrite ``force`` (N, 3) with the total nodal force [N] at positions ``x`` and
    velocities ``v`` (N, 3) at time ``t``; return the largest segment force [N]."""
    n_nodes, n_seg = x.shape[0], segments.shape[0]
    max_tension = 0.0
    for i in range(n_nodes):
        for k in range(3):
            force[i, k] = gravity_force[i, k]
    for j in range(load_nodes.shape[0]):
        scale = 1.0 if load_ramp[j] <= 0.0 else min(1.0, t / load_ramp[j])
        for k in range(3):
            force[load_nodes[j], k] += scale * load_force[j, k]
    for s in range(n_seg):
        a, b = segments[s, 0], segments[s, 1]
        d0 = x[b, 0] - x[a, 0]
        d1 = x[b, 1] - x[a, 1]
        d2 = x[b, 2] - x[a, 2]
        length = math.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
        if length == 0.0:
            continue
        d0, d1, d2 = d0 / length, d1 / length, d2 / length
        strain = length / rest_length[s] - 1.0
        rate = ((v[b, 0] - v[a, 0]) * d0 + (v[b, 1] - v[a, 1]) * d1
                + (v[b, 2] - v[a, 2]) * d2) / rest_length[s]
        if tension_only:  # (S4), (S5): C1 ramp, total clamped at zero
            if strain <= 0.0:
                continue
            if strain < kink_strain:
                r, slope = strain * strain / (2.0 * kink_strain), strain / kink_strain
            else:
                r, slope = strain - 0.5 * kink_strain, 1.0
            n = EA[s] * r + etaA[s] * slope * rate
            if n <= 0.0:
                continue
        else:  # (S3)
            n = EA[s] * strain + etaA[s] * rate
        max_tension = max(max_tension, n)
        force[a, 0] += n * d0
        force[a, 1] += n * d1
        force[a, 2] += n * d2
        force[b, 0] -= n * d0
        force[b, 1] -= n * d1
        force[b, 2] -= n * d2
    return max_tension


@numba.njit(cache=True)
def update_state(x, v, force, inv_mass, dt):  # pragma: no cover - compiled
    """One symplectic Euler update (S9) of ``x``, ``v`` (N, 3) in place: ``v += dt force / m``,
    then ``x += dt v``, with ``force`` (N, 3) [N] and ``inv_mass`` (N,) [1/kg].

    Returns
    -------
    finite : bool
        False when a position became non-finite.
    """
    finite = True
    for i in range(x.shape[0]):
        for k in range(3):
            v[i, k] += dt * force[i, k] * inv_mass[i]
            x[i, k] += dt * v[i, k]
        if not (math.isfinite(x[i, 0]) and math.isfinite(x[i, 1]) and math.isfinite(x[i, 2])):
            finite = False
    return finite


@numba.njit(cache=True)
def advance(x, v, force, t0, dt, n_steps,
            segments, rest_length, EA, etaA, kink_strain, tension_only,
            inv_mass, gravity_force, load_nodes, load_force, load_ramp):  # pragma: no cover
    """Advance positions ``x`` (N, 3) and velocities ``v`` (N, 3) in place by ``n_steps``
    symplectic Euler steps (S9).

    ``force`` (N, 3) is scratch space. Returns the largest segment force [N] met on the way
    (snap loads fall between saved frames) and the number of steps done: fewer than ``n_steps``
    when a non-finite value appeared.
    """
    max_tension = 0.0
    for step in range(n_steps):
        peak = accumulate_forces(x, v, t0 + step * dt, force, segments, rest_length, EA, etaA,
                                 kink_strain, tension_only, gravity_force, load_nodes,
                                 load_force, load_ramp)
        max_tension = max(max_tension, peak)
        if not update_state(x, v, force, inv_mass, dt):
            return max_tension, step + 1
    return max_tension, n_steps
