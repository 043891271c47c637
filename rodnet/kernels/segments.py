"""Compiled forces of the lumped model's segments and of the bending hinges of Kirchhoff threads.

The force law is the one of :mod:`rodnet.kernels.tension` (``elements/spring/FORMULATION.md``
(S3)-(S5)), written out per segment; the hinges are ``elements/kirchhoff/FORMULATION.md`` (K3),
(K4). The explicit step loop (:mod:`rodnet.kernels.explicit`) calls both every step;
``tests/reference/test_lumped.py`` checks them against the vectorised NumPy forces.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numba
import numpy as np

from rodnet.kernels.tension import REVERSED_STIFFNESS


class Segments(NamedTuple):
    """Spring-damper segments (S9): node ``pairs`` (S, 2), ``rest_length``, ``EA`` [N],
    ``etaA`` [N s] (S,), ``kink_strain``, ``tension_only``."""

    pairs: np.ndarray
    rest_length: np.ndarray
    EA: np.ndarray
    etaA: np.ndarray
    kink_strain: float
    tension_only: bool


SLACK_MARGIN = 1e-12
"""A tension-only segment whose squared length is below ``(1 - SLACK_MARGIN)`` times its
squared rest length is slack however the square root and the strain round (the margin is
thousands of rounding errors): :func:`segment_forces` passes it over without its square root
and divisions, with the same result to the last bit."""


@numba.njit(cache=True, error_model="numpy")
def segment_forces(x, v, force, pairs, rest_length, EA, etaA, kink_strain,
                   tension_only):  # pragma: no cover - compiled
    """Add the forces [N] of the tension-only (or linear) Kelvin-Voigt segments ``pairs`` (S, 2)
    at positions ``x`` and velocities ``v`` (N, 3) to ``force`` (N, 3), (S3)-(S5), (S7); return
    the largest segment force [N].

    A tension-only segment that is slack costs a squared length and a comparison
    (:data:`SLACK_MARGIN`); the strain is found before the direction, so a segment the strain
    shows slack skips the divisions. Divisions follow IEEE rules (no zero-divisor checks: every
    divisor is a positive length or the kink strain of a taut branch)."""
    max_tension = 0.0
    for s in range(pairs.shape[0]):
        a, b = pairs[s, 0], pairs[s, 1]
        d0 = x[b, 0] - x[a, 0]
        d1 = x[b, 1] - x[a, 1]
        d2 = x[b, 2] - x[a, 2]
        square = d0 * d0 + d1 * d1 + d2 * d2
        rest = rest_length[s]
        if tension_only and square < rest * rest * (1.0 - SLACK_MARGIN):
            continue
        length = math.sqrt(square)
        if length == 0.0:
            continue
        strain = length / rest - 1.0
        if tension_only and strain <= 0.0:
            continue
        d0, d1, d2 = d0 / length, d1 / length, d2 / length
        rate = ((v[b, 0] - v[a, 0]) * d0 + (v[b, 1] - v[a, 1]) * d1
                + (v[b, 2] - v[a, 2]) * d2) / rest
        if tension_only:  # (S4), (S5): C1 ramp, total clamped at zero
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


@numba.njit(cache=True, error_model="numpy")
def segment_states(x, v, pairs, rest_length, EA, etaA, kink_strain, tension_only,
                   tension):  # pragma: no cover - compiled
    """The axial force [N] of every segment into ``tension`` (S,) and the elastic energy [J]
    they store, summed: :func:`rodnet.kernels.tension.axial_force` (S3)-(S5) and
    :func:`rodnet.kernels.tension.axial_energy` (S6) of the segments ``pairs`` (S, 2) at
    positions ``x`` and velocities ``v`` (N, 3), for a saved frame."""
    energy = 0.0
    delta = kink_strain
    for s in range(pairs.shape[0]):
        a, b = pairs[s, 0], pairs[s, 1]
        d0 = x[b, 0] - x[a, 0]
        d1 = x[b, 1] - x[a, 1]
        d2 = x[b, 2] - x[a, 2]
        length = math.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
        rest = rest_length[s]
        scale = length if length > 0.0 else 1.0
        rate = ((v[b, 0] - v[a, 0]) * (d0 / scale) + (v[b, 1] - v[a, 1]) * (d1 / scale)
                + (v[b, 2] - v[a, 2]) * (d2 / scale)) / rest
        strain = length / rest - 1.0
        if not tension_only:  # (S3)
            tension[s] = EA[s] * strain + etaA[s] * rate
            energy += 0.5 * EA[s] * rest * strain * strain
            continue
        n, e, factor = 0.0, 0.0, 1.0
        if strain > 0.0:  # (S4), (S5)
            e = strain
            if strain < delta:
                r, slope = strain * strain / (2.0 * delta), strain / delta
            else:
                r, slope = strain - 0.5 * delta, 1.0
            n = max(EA[s] * r + etaA[s] * slope * rate, 0.0)
        elif strain < -1.0:  # (C51): never for a segment, whose strain is at least -1
            e, factor = -1.0 - strain, REVERSED_STIFFNESS
            if e < delta:
                r, slope = e * e / (2.0 * delta), e / delta
            else:
                r, slope = e - 0.5 * delta, 1.0
            n = -REVERSED_STIFFNESS * max(EA[s] * r - etaA[s] * slope * rate, 0.0)
        tension[s] = n
        if delta == 0.0:
            integral = 0.5 * e * e
        elif e < delta:
            integral = e * e * e / (6.0 * delta)
        else:
            integral = 0.5 * e * e - 0.5 * delta * e + delta * delta / 6.0
        energy += factor * EA[s] * rest * integral
    return energy


HINGE_FASTMATH = {"contract", "arcp", "reassoc", "nsz"}
"""Floating-point licences of the hinge loop (fused multiply-add, reordering); none assumes
finite values, so a non-finite state still shows."""


@numba.njit(cache=True, fastmath=HINGE_FASTMATH)
def hinge_forces(x, v, force, hinges, stiffness, tau, rest):  # pragma: no cover - compiled
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
