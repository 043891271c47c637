"""The axial law of a thread segment: tension-only Kelvin-Voigt with a C1 smoothed kink.

Shared by the lumped reference, the cable element and the Cosserat element's axial part, so that
the models agree exactly where they should. Equations: ``elements/spring/FORMULATION.md`` (S3)-(S6).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]


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
        True: the total is clamped at zero and vanishes for a slack segment; False: linear law.
    """
    if not tension_only:
        return EA * strain + etaA * strain_rate
    r, slope = ramp(strain, kink_strain)
    return np.maximum(EA * r + etaA * slope * strain_rate, 0.0)


def axial_energy(strain: FloatArray, EA: FloatArray, rest_length: FloatArray,
                 kink_strain: float, tension_only: bool) -> FloatArray:
    """Elastic energy [J] stored in each segment, (S6)."""
    if not tension_only:
        return 0.5 * EA * rest_length * strain**2
    e, d = np.clip(strain, 0.0, None), kink_strain
    if d == 0.0:
        integral = 0.5 * e * e
    else:
        integral = np.where(e < d, e**3 / (6.0 * d), 0.5 * e * e - 0.5 * d * e + d * d / 6.0)
    return EA * rest_length * integral
