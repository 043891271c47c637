"""Compiled force loop and explicit (symplectic Euler) step loop of the lumped model.

One call advances the state by ``n_steps`` steps without returning to Python; the force law is
the one of :mod:`rodnet.kernels.tension` (``elements/spring/FORMULATION.md`` (S3)-(S5)), written
out per segment, plus the bending hinges of Kirchhoff threads (``elements/kirchhoff/FORMULATION.md``
(K3), (K4); none for the lumped model and cables), and the update is (S9). ``tests/reference/test_lumped.py`` checks this loop
against the vectorised NumPy forces.
"""

from __future__ import annotations

import math

import numba
import numpy as np


@numba.njit(cache=True)
def accumulate_forces(x, v, t, force,
                      segments, rest_length, EA, etaA, kink_strain, tension_only,
                      gravity_force, load_nodes, load_force, load_ramp,
                      hinges, hinge_stiffness, hinge_tau, hinge_rest):  # pragma: no cover
    """Overwrite ``force`` (N, 3) with the total nodal force [N] at positions ``x`` and
    velocities ``v`` (N, 3) at time ``t``; return the largest segment force [N].

    ``hinges`` (H, 3), ``hinge_stiffness``, ``hinge_tau`` (H,) and ``hinge_rest`` (H, 2): the
    bending hinges of Kirchhoff threads (:func:`add_hinge_forces`), no rows for the lumped model
    and cables.
    """
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
    add_hinge_forces(x, v, force, hinges, hinge_stiffness, hinge_tau, hinge_rest)
    return max_tension


HINGE_FASTMATH = {"contract", "arcp", "reassoc", "nsz"}
"""Floating-point licences of the hinge loop (fused multiply-add, reordering); none assumes
finite values, so a non-finite state still shows."""


@numba.njit(cache=True, fastmath=HINGE_FASTMATH)
def add_hinge_forces(x, v, force, hinges, stiffness, tau, rest):  # pragma: no cover - compiled
    """Add the forces [N] of the bending hinges ``(a, b, c)`` (H, 3) to ``force`` (N, 3):
    (K3), (K4), as :func:`rodnet.kernels.hinge.hinge_force`.

    ``stiffness`` (H,): ``k_h`` [N m]; ``tau`` (H,): retardation time [s]; ``rest`` (H, 2): rest
    lengths of the segments ``(a, b)``, ``(b, c)`` [m]; ``x``, ``v`` (N, 3) [m], [m/s].
    """
    for h in range(hinges.shape[0]):
        a, b, c = hinges[h, 0], hinges[h, 1], hinges[h, 2]
        i0, i1 = 1.0 / rest[h, 0], 1.0 / rest[h, 1]
        # kappa = e1 / l1 - e0 / l0 and its rate (K2)
        k0 = (x[c, 0] - x[b, 0]) * i1 - (x[b, 0] - x[a, 0]) * i0
        k1 = (x[c, 1] - x[b, 1]) * i1 - (x[b, 1] - x[a, 1]) * i0
        k2 = (x[c, 2] - x[b, 2]) * i1 - (x[b, 2] - x[a, 2]) * i0
        r0 = (v[c, 0] - v[b, 0]) * i1 - (v[b, 0] - v[a, 0]) * i0
        r1 = (v[c, 1] - v[b, 1]) * i1 - (v[b, 1] - v[a, 1]) * i0
        r2 = (v[c, 2] - v[b, 2]) * i1 - (v[b, 2] - v[a, 2]) * i0
        size2 = k0 * k0 + k1 * k1 + k2 * k2
        g = stiffness[h]
        if size2 > 1e-20:  # hinge.STRAIGHT: below it the damping term is left out
            g = g * (1.0 + tau[h] * (r0 * k0 + r1 * k1 + r2 * k2) / size2)
        force[a, 0] -= g * i0 * k0
        force[a, 1] -= g * i0 * k1
        force[a, 2] -= g * i0 * k2
        force[b, 0] += g * (i0 + i1) * k0
        force[b, 1] += g * (i0 + i1) * k1
        force[b, 2] += g * (i0 + i1) * k2
        force[c, 0] -= g * i1 * k0
        force[c, 1] -= g * i1 * k1
        force[c, 2] -= g * i1 * k2


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
            inv_mass, gravity_force, load_nodes, load_force, load_ramp, hinges, hinge_stiffness,
            hinge_tau, hinge_rest):  # pragma: no cover
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
                                 load_force, load_ramp, hinges, hinge_stiffness, hinge_tau,
                                 hinge_rest)
        max_tension = max(max_tension, peak)
        if not update_state(x, v, force, inv_mass, dt):
            return max_tension, step + 1
    return max_tension, n_steps
