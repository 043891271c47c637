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


def ramp_curvature(strain: FloatArray, kink_strain: float) -> FloatArray:
    """``r''(e)`` of :func:`ramp`: ``1 / delta`` inside the kink ``0 < e < delta``, else 0."""
    return np.where((strain > 0.0) & (strain < kink_strain), 1.0 / max(kink_strain, 1e-300), 0.0)


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


def step_strain_rate(strain: FloatArray, reference: FloatArray, inv_h: float,
                     tension_only: bool) -> FloatArray:
    """The strain rate of an implicit step, ``(e - e_ref) inv_h`` (S11), for the law of
    :func:`axial_force`.

    With the tension-only law the reference is taken no lower than the kink, ``max(e_ref, 0)``
    (below ``e = -1``: no higher than ``-1``, the mirrored kink): only the motion while taut
    is damped. A segment that was slack at the start of the step then starts pulling from
    zero (``N`` is continuous in ``e``); with ``e_ref`` itself its first taut step would jump to
    ``etaA |e_ref| inv_h`` at the kink, which the step's Newton solve cannot resolve. The
    difference is one step's damping impulse of a segment that snaps taut: it vanishes as the
    step shrinks.
    """
    if not tension_only:
        return (strain - reference) * inv_h
    clipped = np.where(strain < -1.0, np.minimum(reference, -1.0), np.maximum(reference, 0.0))
    return (strain - clipped) * inv_h


SECANT_SMALL = 1e-9
"""Below this change of strain over a step the secant force (S14) takes its limit, the force
at the mean strain: the difference quotient would lose digits, and the two differ by
``EA r''(e) de^2 / 24``."""


def secant_axial_force(start: FloatArray, end: FloatArray, EA: FloatArray, etaA: FloatArray,
                       kink_strain: float, tension_only: bool,
                       inv_step: float) -> tuple[FloatArray, FloatArray]:
    """Axial force over a step from strain ``start`` to ``end`` whose work is the change of
    the stored energy (S6) plus a dissipation, and its derivative by ``end``, (S14).

    Parameters
    ----------
    start, end : (E,) float
        ``e0`` and ``e1``.
    EA, etaA : (E,) float
    kink_strain : float
    tension_only : bool
    inv_step : float
        1 / h [1/s]: the damping acts at the strain rate ``(e1 - e0) / h`` (the tension-only
        law from ``max(e0, 0)``, as (S11)).

    Returns
    -------
    N, dN_de1 : (E,) float
    """
    de = end - start
    small = np.abs(de) <= SECANT_SMALL
    if not tension_only:
        return EA * 0.5 * (start + end) + etaA * de * inv_step, 0.5 * EA + etaA * inv_step
    safe = np.where(small, 1.0, de)
    stored = axial_energy(end, EA, 1.0, kink_strain, True) - \
        axial_energy(start, EA, 1.0, kink_strain, True)
    r_end, slope_end = ramp(end, kink_strain)
    r_mid, slope_mid = ramp(0.5 * (start + end), kink_strain)
    elastic = np.where(small, EA * r_mid, stored / safe)
    d_elastic = np.where(small, 0.5 * EA * slope_mid, (EA * r_end - elastic) / safe)
    curvature = ramp_curvature(end, kink_strain)
    taut_from = np.maximum(start, 0.0)
    viscous = etaA * slope_end * (end - taut_from) * inv_step
    d_viscous = etaA * inv_step * (curvature * (end - taut_from) + slope_end)
    total = elastic + viscous
    active = total > 0.0
    return np.where(active, total, 0.0), np.where(active, d_elastic + d_viscous, 0.0)


def secant_strain(start: FloatArray, end: FloatArray, kink_strain: float) -> FloatArray:
    """The strain ``e*`` between ``start`` and ``end`` at which the tension-only law's force is
    its secant over the step, ``r(e*) = (R(end) - R(start)) / (end - start)`` with ``R`` the
    integral of :func:`ramp` (S6): the Cosserat element's midpoint rule takes its axial
    stress there (cosserat FORMULATION.md, C56), so that its work is the change of the stored
    energy. The mean strain where the change is below :data:`SECANT_SMALL` or a strain lies
    below ``e = -1`` (C51); at or below zero where the secant is zero (slack all the step)."""
    mean = 0.5 * (start + end)
    usable = (np.abs(end - start) > SECANT_SMALL) & (np.minimum(start, end) > -1.0)
    secant, _ = secant_axial_force(start, end, np.ones_like(mean), np.zeros_like(mean),
                                   kink_strain, True, 0.0)   # r's secant: EA 1, no damping
    d = kink_strain
    inverse = np.where(secant <= 0.0, np.minimum(mean, 0.0),
                       np.where(secant < 0.5 * d, np.sqrt(2.0 * d * np.maximum(secant, 0.0)),
                                secant + 0.5 * d))
    return np.where(usable, inverse, mean)


def step_potential(strain: FloatArray, strain_reference: FloatArray, inv_h: float,
                   EA: FloatArray, etaA: FloatArray, rest_length: FloatArray, kink_strain: float,
                   tension_only: bool) -> FloatArray:
    """Incremental potential [J] of each segment over an implicit step, (S12).

    With the step's strain rate of :func:`step_strain_rate` (S11), the axial force of
    :func:`axial_force` is ``N = dPsi/de / l0``: ``Psi`` is the stored energy (S6) plus the
    step's dissipation potential, and is convex in ``e`` for the tension-only law (its ``N``
    never falls as ``e`` grows). ``inv_h = 0`` gives the stored energy (S6).

    Parameters
    ----------
    strain, strain_reference : (E,) float
        ``e`` and ``e_ref``.
    inv_h : float
        1 / h_bar [1/s] of the scheme (S11).
    EA, etaA, rest_length : (E,) float
    kink_strain : float
    tension_only : bool
    """
    k = etaA * inv_h
    if not tension_only:
        return rest_length * (0.5 * EA * strain**2 + 0.5 * k * (strain - strain_reference)**2)
    # references no lower than the kink (step_strain_rate)
    tension = _clamped_integral(strain, np.maximum(strain_reference, 0.0), EA, k, kink_strain)
    below = strain < -1.0   # (C51): the mirrored law in s = -1 - e, rate ds/dt = -de/dt
    if below.any():
        tension = tension + np.where(below, _clamped_integral(
            -1.0 - strain, np.maximum(-1.0 - strain_reference, 0.0), REVERSED_STIFFNESS * EA,
            REVERSED_STIFFNESS * k, kink_strain), 0.0)
    return rest_length * tension


def _clamped_integral(s: FloatArray, s_ref: FloatArray, EA: FloatArray, k: FloatArray,
                      delta: float) -> FloatArray:
    """``integral of max(0, f(x)) dx`` from ``-inf`` to ``s``, ``f = EA r + k r' (x - s_ref)``,
    (S12): ``f`` is positive exactly above the threshold ``s*`` (S13), so the integral is
    ``F(max(s, s*)) - F(s*)`` with ``F`` an antiderivative of ``f`` on ``x > 0``."""
    if delta == 0.0:
        threshold = np.maximum(0.0, k * s_ref / (EA + k))
    else:
        s1 = k * s_ref / (0.5 * EA + k)
        s2 = (0.5 * EA * delta + k * s_ref) / (EA + k)
        threshold = np.where(s1 < delta, np.maximum(s1, 0.0), s2)
    return _antiderivative(np.maximum(s, threshold), s_ref, EA, k, delta) - \
        _antiderivative(threshold, s_ref, EA, k, delta)


def _antiderivative(x: FloatArray, s_ref: FloatArray, EA: FloatArray, k: FloatArray,
                    delta: float) -> FloatArray:
    """``F(x)`` for ``x >= 0``, ``F(0) = 0``, ``F' = EA r(x) + k r'(x) (x - s_ref)``, (S12)."""
    outer = EA * (0.5 * x * x) + k * (0.5 * x * x - s_ref * x)
    if delta == 0.0:
        return outer
    inner = ((0.5 * EA + k) * x**3 / 3.0 - 0.5 * k * s_ref * x * x) / delta
    shift = EA * delta * delta / 6.0 - k * delta * delta / 6.0 + 0.5 * k * s_ref * delta
    return np.where(x < delta, inner, outer - 0.5 * EA * delta * x + shift)
