"""Cable (axial-only) segment: internal force and its tangents, vectorised over segments.

The force law is :mod:`rodnet.kernels.tension`; the tangents are ``elements/cable/FORMULATION.md``
(stiffness and damping matrices). Used by the lumped model's implicit integrators and by rods
without bending and torsion. The residual convention is ``g = f_int``: ``-N t`` at the start node
and ``+N t`` at the end node (the forces the segment receives from its nodes).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from rodnet.kernels.tension import (axial_force, ramp, ramp_curvature, secant_axial_force,
                                    step_strain_rate)

FloatArray = NDArray[np.float64]


def cable_tangents(x_a: FloatArray, x_b: FloatArray, v_a: FloatArray, v_b: FloatArray,
                   rest_length: FloatArray, EA: FloatArray, etaA: FloatArray,
                   kink_strain: float, tension_only: bool,
                   step: tuple[FloatArray, float] | None = None,
                   strain_shift: FloatArray | None = None, convex: bool = False,
                   ) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
    """Axial force and the end-node blocks of the internal force and its tangents.

    Parameters
    ----------
    x_a, x_b, v_a, v_b : (E, 3) float
        End positions [m] and velocities [m/s].
    rest_length, EA, etaA : (E,) float
        l0 [m], axial stiffness [N], axial viscous coefficient tau EA [N s].
    step : ((E,) float, float), optional
        ``(e_ref, inv_h)`` of an implicit step: the strain rate is ``(e - e_ref) inv_h``
        (spring FORMULATION.md, S11) instead of (S2), so the velocities are not used and
        ``C_bb`` is zero.
    strain_shift : (E,) float, optional
        The geometric stiffness ``N / l (I - t t^T)`` takes the axial force at the strain
        shifted by it (the mixed Newton step, cosserat FORMULATION.md C55).
    convex : bool
        Leave a compressive force out of the geometric stiffness (the linear law), so every
        block is positive semidefinite.

    Returns
    -------
    N : (E,) float
        Axial force [N].
    g_b : (E, 3) float
        Internal force at the end node (``-g_b`` at the start node).
    K_bb, C_bb : (E, 3, 3) float
        d g_b / d x_b and d g_b / d v_b; the element blocks are ``[[K, -K], [-K, K]]``.
    """
    d = x_b - x_a
    length = np.sqrt(np.einsum("ij,ij->i", d, d))
    with np.errstate(invalid="ignore"):   # a segment of no length (a trial point of Newton's
        t = d / length[:, None]           # shifted steps) has no direction: NaN, rejected there
    dv = v_b - v_a
    strain = length / rest_length - 1.0
    if step is None:
        rate = np.einsum("ij,ij->i", dv, t) / rest_length
    else:
        rate = step_strain_rate(strain, step[0], step[1], tension_only)
    n = axial_force(strain, rate, EA, etaA, kink_strain, tension_only)
    if tension_only:
        _, slope = ramp(strain, kink_strain)
        curvature = ramp_curvature(strain, kink_strain)
        active = n > 0.0
    else:
        slope, curvature, active = np.ones_like(strain), np.zeros_like(strain), np.ones(len(n), bool)
    transverse = np.eye(3)[None] - t[:, :, None] * t[:, None, :]
    if step is None:
        rate_grad = np.einsum("eij,ej->ei", transverse, dv) / (length * rest_length)[:, None]
        dn_dx = ((EA * slope + etaA * curvature * rate) / rest_length)[:, None] * t \
            + (etaA * slope)[:, None] * rate_grad
        C = ((etaA * slope * active) / rest_length)[:, None, None] * t[:, :, None] * t[:, None, :]
    else:  # the rate moves with the strain: dN/de = EA r' + etaA (r'' rate + r' inv_h)
        dn_dx = ((EA * slope + etaA * (curvature * rate + slope * step[1]))
                 / rest_length)[:, None] * t
        C = np.zeros((len(n), 3, 3))
    dn_dx *= active[:, None]
    n_geometric = n
    if strain_shift is not None:
        shifted = strain + strain_shift
        n_geometric = axial_force(shifted, rate if step is None else step_strain_rate(
            shifted, step[0], step[1], tension_only), EA, etaA, kink_strain, tension_only)
    if convex:
        n_geometric = np.maximum(n_geometric, 0.0)
    K = t[:, :, None] * dn_dx[:, None, :] + (n_geometric / length)[:, None, None] * transverse
    return n, n[:, None] * t, K, C


def cable_secant_tangents(x_a: FloatArray, x_b: FloatArray, x0_a: FloatArray, x0_b: FloatArray,
                          rest_length: FloatArray, EA: FloatArray, etaA: FloatArray,
                          kink_strain: float, tension_only: bool, inv_step: float,
                          ) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
    """The midpoint rule's secant form (spring FORMULATION.md, S15) of :func:`cable_tangents`:
    the force at the step's midpoint ends ``x_a, x_b`` (E, 3) from the start ends ``x0_a,
    x0_b`` (E, 3), whose end is ``2 x - x0``: ``N_bar c / l_bar`` along the midpoint chord
    ``c``, ``N_bar`` the secant axial force (S14) between the start and end strains and
    ``l_bar`` the mean of the start and end lengths. Its work over the step is the change of
    the stored energy plus a dissipation, so the midpoint rule conserves the energy of an
    undamped structure (and its momenta, the force lying along the chord).

    Returns
    -------
    N : (E,) float
        ``N_bar`` [N].
    g_b : (E, 3) float
        Internal force at the end node (``-g_b`` at the start node).
    K_bb, C_bb : (E, 3, 3) float
        d g_b / d x_b at fixed start, and zeros (the rate is the step's).
    """
    c = x_b - x_a
    c0 = x0_b - x0_a
    c1 = 2.0 * c - c0
    l0 = np.sqrt(np.einsum("ij,ij->i", c0, c0))
    l1 = np.sqrt(np.einsum("ij,ij->i", c1, c1))
    n1 = c1 / l1[:, None]
    mean_length = 0.5 * (l0 + l1)
    n, dn_de1 = secant_axial_force(l0 / rest_length - 1.0, l1 / rest_length - 1.0, EA, etaA,
                                   kink_strain, tension_only, inv_step)
    per_length = n / mean_length
    # d/dc of (N / l_bar) c with dl1/dc = 2 n1 and dl_bar/dc = n1
    K = (c / mean_length[:, None])[:, :, None] * (2.0 * dn_de1 / rest_length)[:, None, None] \
        * n1[:, None, :] + per_length[:, None, None] * np.eye(3)[None] \
        - (per_length / mean_length)[:, None, None] * c[:, :, None] * n1[:, None, :]
    return n, per_length[:, None] * c, K, np.zeros_like(K)


def element_blocks(K_bb: FloatArray) -> FloatArray:
    """(E, 6, 6) element matrix ``[[K, -K], [-K, K]]`` from the end-node block (E, 3, 3)."""
    return np.block([[K_bb, -K_bb], [-K_bb, K_bb]])
