"""The axial law of a thread segment: tension-only Kelvin-Voigt with a C1 smoothed kink.

Shared by the lumped reference, the cable element and the Cosserat element's axial part, so that
the models agree exactly where they should. Equations: ``elements/spring/FORMULATION.md`` (S3)-(S6).

A rod's axial strain can fall below -1 (its material axis turned away from its chord); there the
tension-only law pushes back with the mirrored ramp, ``elements/cosserat/FORMULATION.md`` (C51).
A segment's strain ``l / l0 - 1`` never does, so the lumped model and cables are unaffected (the
lumped model's compiled loop leaves it out).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]

REVERSED_STIFFNESS = 0.01
"""Stiffness of the mirrored law below ``e = -1`` (C51) as a fraction of ``EA``: its bounce rings
at a tenth of the axial frequency, which the explicit step resolves, and turning an element
inside out still takes ``0.005 EA Le`` of work."""


def ramp(strain: FloatArray, kink_strain: float) -> tuple[FloatArray, FloatArray]:
    """C1 ramp ``r(e)`` standing in for ``max(e, 0)`` and its slope ``r'(e)``, (S4).

    Parameters
    ----------
    strain : (E,) float
        Axial strain ``e = l / l0 - 1``.
    kink_strain : float
        delta >= 0: ``r`` is quadratic on ``0 < e < delta``; ``delta = 0`` gives the sharp kink.

    Returns
    -------
    r, slope : (E,) float
    """
    if kink_strain == 0.0:
        positive = strain > 0.0
        return np.where(positive, strain, 0.0), positive.astype(float)
    e = np.clip(strain, 0.0, None)
    inside = e < kink_strain
    r = np.where(inside, e * e / (2.0 * kink_strain), e - 0.5 * kink_strain)
    return r, np.where(inside, e / kink_strain, 1.0)


def axial_force(strain: FloatArray, strain_rate: FloatArray, EA: FloatArray, etaA: FloatArray,
                kink_strain: float, tension_only: bool) -> FloatArray:
    """Axial force N [N] of each segment, (S3) and (S5).

    Parameters
    ----------
    strain, strain_rate : (E,) float
        ``e`` and ``de/dt`` [1/s].
    EA, etaA : (E,) float
        Axial stiffness [N] and axial viscous coefficient tau EA [N s] (tau = viscosity / E).
    kink_strain : float
        See :func:`ramp`.
    tension_only : bool
        True: the total is clamped at zero and vanishes for a slack segment (pushing only below
        ``e = -1``, (C51)); False: linear law.
    """
    if not tension_only:
        return EA * strain + etaA * strain_rate
    r, slope = ramp(strain, kink_strain)
    tension = np.maximum(EA * r + etaA * slope * strain_rate, 0.0)
    r, slope = ramp(-1.0 - strain, kink_strain)     # (C51): only below e = -1
    return tension - REVERSED_STIFFNESS * np.maximum(EA * r - etaA * slope * strain_rate, 0.0)


def axial_energy(strain: FloatArray, EA: FloatArray, rest_length: FloatArray,
                 kink_strain: float, tension_only: bool) -> FloatArray:
    """Elastic energy [J] stored in each segment, (S6); below ``e = -1`` that of (C51)."""
    if not tension_only:
        return 0.5 * EA * rest_length * strain**2
    # the tension side and the mirrored side (C51); at most one of them is non-zero
    e, d = np.clip(strain, 0.0, None) + np.clip(-1.0 - strain, 0.0, None), kink_strain
    if d == 0.0:
        integral = 0.5 * e * e
    else:
        integral = np.where(e < d, e**3 / (6.0 * d), 0.5 * e * e - 0.5 * d * e + d * d / 6.0)
    return np.where(strain < -1.0, REVERSED_STIFFNESS, 1.0) * EA * rest_length * integral
