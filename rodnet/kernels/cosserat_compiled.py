"""Compiled Cosserat element: one loop over elements from the node state to forces and tangents.

The same equations as the NumPy path of :mod:`rodnet.kernels.cosserat` (``elements/cosserat/
FORMULATION.md`` §Kinematics, §Strains, §Strain rates, §Constitutive law, §Energy, §Internal
force, §Tangent), with the arithmetic in the same order and the same series switches. Only the
transcendental functions differ in the last bit (libm here, NumPy's own loops there), so the
kinematics of the two paths agree to a few ulp. For small rods the NumPy path costs a few dozen
array calls per evaluation whatever ``n``; here each element is a few hundred scalar operations
and a call costs little more than its dispatch.

Work is on the chord-reduced DOF ``[dd, dtheta1, dtheta2]`` of
:mod:`rodnet.kernels.cosserat_strain`; vectors and blocks are expanded to the 12 element DOF on
output. Arguments and shapes are those of :mod:`rodnet.kernels.cosserat`.

Every compiled function lives in this file and the Taylor coefficients are passed as arguments:
numba's cache sees neither edits to compiled functions of other modules nor new values of global
arrays, which it freezes at compile time.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numba
import numpy as np
from numpy.typing import ArrayLike

from rodnet.kernels import cosserat_strain, so3, threads
from rodnet.kernels.tension import REVERSED_STIFFNESS
from rodnet.kernels.cosserat_strain import ROTATION_STOP
from rodnet.kernels.so3 import FloatArray

# rows: beta, beta'/phi (cosserat_strain.midpoint_coefficient), gamma, gamma'/phi
# (so3.dexp_inv_coefficient), each a polynomial in phi^2 used below its switch angle
_SERIES = np.ascontiguousarray(np.stack([
    cosserat_strain.BETA_SERIES, cosserat_strain.BETA_D_SERIES,
    so3.GAMMA_SERIES, so3.GAMMA_D_SERIES]), dtype=np.float64)
_SWITCH_ANGLES = (float(cosserat_strain.BETA_SERIES_ANGLE), float(so3.GAMMA_SERIES_ANGLE))
SERIES_ARGUMENTS = (_SERIES, *_SWITCH_ANGLES)
"""The ``series, beta_angle, gamma_angle`` arguments of the compiled element loops: the Taylor
series of the coefficients (C11) and the angles below which they are used."""

BLOCKS = 64
"""Blocks of consecutive elements in the implicit path's parallel element loop
(:func:`_state_and_force`).

The parallel loops over elements and nodes run over blocks and call a serial kernel on each
(:func:`state_and_force_range`, and in the explicit loop :func:`rod_forces_range` and
:func:`rodnet.kernels.explicit.update_range`), so numba's parallel passes see a loop of one
call and the element's arithmetic is compiled once, not once more inside every parallel entry
point (that was most of compiling a run: validation/benchmarks/results/cold_start.md). The
loops are ``inline="always"``: their ``prange`` is a parallel loop in a ``parallel=True``
entry point and a plain loop elsewhere (numba's cache breaks on compiled functions that call
``parallel=True`` ones: docs/architecture.md). numba shares the blocks out to its threads,
evenly for 2, 4, 8, ... threads. A number, not the pool's size read in the kernel
(``numba.get_num_threads`` stops numba from caching the kernel); the explicit loop takes its
run's thread count instead (``StepControl.blocks``), since a block costs about half a
microsecond there."""


_NOT_STORED = (np.empty((0, 3)), np.empty((0, 3, 3)), np.empty((0, 3)), np.empty((0, 4)),
               np.empty((0, 18)), np.empty((0, 9)), np.empty((0, 2)))
"""The optional outputs of :func:`state_and_force_range`, none stored (no rows)."""


def _as_float(a: ArrayLike) -> FloatArray:
    """C-contiguous float64 (a no-op for the usual inputs): one compiled specialisation."""
    return np.ascontiguousarray(a, dtype=np.float64)


def _check_shapes(got: tuple[tuple[int, ...], ...], expected: tuple[tuple[int, ...], ...]) -> None:
    # the compiled loops do not check bounds
    if got != expected:
        raise ValueError(f"Cosserat kernel: array shapes {got}, expected {expected}")


def _element_arguments(*model_and_state: ArrayLike) -> tuple[FloatArray, ...]:
    """``rest_length, reference_strain, stiffness, tau, x, q, velocity``, converted and checked."""
    arrays = [np.ascontiguousarray(a, dtype=np.float64) for a in model_and_state]
    n = arrays[0].shape[0]
    _check_shapes(tuple([a.shape for a in arrays]),
                  ((n,), (n, 6), (n, 6), (n,), (n, 2, 3), (n, 2, 4), (n, 12)))
    return tuple(arrays)


def internal_force(
    # Model:
    rest_length: FloatArray, reference_strain: FloatArray, stiffness: FloatArray, tau: FloatArray,
    # State in:
    x: FloatArray, q: FloatArray, velocity: FloatArray,
    # Scalars:
    tension_only: bool, kink_strain: float,
    step: tuple[FloatArray, float] | None = None,
) -> FloatArray:
    """:func:`rodnet.kernels.cosserat.internal_force_numpy`, compiled: (n, 12). With ``step =
    (eps_ref (n, 6), inv_h)`` the strain rates are ``(eps - eps_ref) inv_h`` (C53)."""
    arrays = _element_arguments(rest_length, reference_strain, stiffness, tau, x, q, velocity)
    scalars = (bool(tension_only), float(kink_strain), _SERIES, *_SWITCH_ANGLES,
               *_step_arguments(step, arrays[0].shape[0]))
    if threads.current() == 1:
        force = np.empty((arrays[0].shape[0], 12))
        state_and_force_range(0, len(force), *arrays, *scalars, force, *_NOT_STORED)
        return force
    return _internal_force_kernel(*arrays, *scalars)


def _step_arguments(step: tuple[FloatArray, float] | None, n: int) -> tuple[FloatArray, float]:
    """``step_reference, inv_h`` of the compiled loops: no rows without a step."""
    if step is None:
        return np.empty((0, 6)), 0.0
    reference = _as_float(step[0])
    _check_shapes((reference.shape,), ((n, 6),))
    return reference, float(step[1])


def internal_force_and_tangents(
    # Model:
    rest_length: FloatArray, reference_strain: FloatArray, stiffness: FloatArray, tau: FloatArray,
    # State in:
    x: FloatArray, q: FloatArray, velocity: FloatArray,
    # Scalars:
    tension_only: bool, kink_strain: float,
    step: tuple[FloatArray, float] | None = None,
    strain_shift: FloatArray | None = None,
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """:func:`rodnet.kernels.cosserat.internal_force_and_tangents_numpy`, compiled; ``step`` as
    :func:`internal_force` (the damping tangent is then zero). With ``strain_shift`` (n, 6) the
    geometric part of the stiffness takes the stress resultants at the strains shifted by it
    (mixed Newton, C55).

    Returns the force (n, 12) and the stiffness and damping tangents (n, 12, 12).
    """
    arrays = _element_arguments(rest_length, reference_strain, stiffness, tau, x, q, velocity)
    n = arrays[0].shape[0]
    # NumPy allocates the large outputs: it asks for huge pages, numba's allocator does not, and
    # first-touch page faults would otherwise cost as much as the assembly at large n
    force = np.empty((n, 12))
    stiffness_out, damping_out = np.empty((n, 12, 12)), np.empty((n, 12, 12))
    reference, inv_h = _step_arguments(step, n)
    shift = np.empty((0, 6)) if strain_shift is None else _as_float(strain_shift)
    if threads.current() > 1:
        _internal_force_andtangents_kernel(*arrays, bool(tension_only), float(kink_strain),
                                            _SERIES, *_SWITCH_ANGLES, reference, inv_h, shift,
                                            force, stiffness_out, damping_out)
        return force, stiffness_out, damping_out
    # one thread: the same passes without a parallel region (its launch costs about as much
    # as the force of a 20-element thread)
    psi, R_m, g = np.empty((n, 3)), np.empty((n, 3, 3)), np.empty((n, 3))
    coefficients, constitutive, velocity9 = np.empty((n, 4)), np.empty((n, 18)), np.empty((n, 9))
    state_and_force_range(0, n, *arrays, bool(tension_only), float(kink_strain), _SERIES,
                          *_SWITCH_ANGLES, reference, inv_h, force, psi, R_m, g, coefficients,
                          constitutive, velocity9, _NOT_STORED[-1])
    _shifted_tangents(psi, R_m, g, coefficients, constitutive, velocity9, arrays[0], reference,
                      inv_h, shift, stiffness_out, damping_out)
    return force, stiffness_out, damping_out


def strain_energy(
    # Model:
    rest_length: FloatArray, reference_strain: FloatArray, stiffness: FloatArray,
    # State in:
    x: FloatArray, q: FloatArray,
    # Scalars:
    tension_only: bool, kink_strain: float,
) -> FloatArray:
    """:func:`rodnet.kernels.cosserat.strain_energy_numpy`, compiled: (n,)."""
    arrays = tuple(_as_float(a) for a in (rest_length, reference_strain, stiffness, x, q))
    n = arrays[0].shape[0]
    _check_shapes(tuple(a.shape for a in arrays), ((n,), (n, 6), (n, 6), (n, 2, 3), (n, 2, 4)))
    # the stored energy is the step potential of a step without damping (inv_h = 0)
    return _step_potential_kernel(arrays[0], arrays[1], arrays[2], np.zeros(n), arrays[3],
                                  arrays[4], np.zeros((n, 6)), 0.0, bool(tension_only),
                                  float(kink_strain))


def step_potential(
    # Model:
    rest_length: FloatArray, reference_strain: FloatArray, stiffness: FloatArray, tau: FloatArray,
    # State in:
    x: FloatArray, q: FloatArray,
    # Scalars:
    tension_only: bool, kink_strain: float,
    step: tuple[FloatArray, float],
) -> FloatArray:
    """:func:`rodnet.kernels.cosserat.step_potential` with a step, compiled: (n,)."""
    arrays = tuple(_as_float(a) for a in (rest_length, reference_strain, stiffness, tau, x, q))
    n = arrays[0].shape[0]
    _check_shapes(tuple(a.shape for a in arrays), ((n,), (n, 6), (n, 6), (n,), (n, 2, 3),
                                                   (n, 2, 4)))
    reference, inv_h = _step_arguments(step, n)
    return _step_potential_kernel(*arrays, reference, inv_h, bool(tension_only),
                                  float(kink_strain))


def strains_and_rates(
    # Model:
    rest_length: FloatArray, reference_strain: FloatArray,
    # State in:
    x: FloatArray, q: FloatArray, velocity: FloatArray,
) -> tuple[FloatArray, FloatArray]:
    """Strains ``[Gamma, K]`` and their rates (n, 6) of every element (§Strains, §Strain rates)."""
    arrays = tuple(_as_float(a) for a in (rest_length, reference_strain, x, q, velocity))
    n = arrays[0].shape[0]
    _check_shapes(tuple(a.shape for a in arrays), ((n,), (n, 6), (n, 2, 3), (n, 2, 4), (n, 12)))
    strain, rate = np.empty((n, 6)), np.empty((n, 6))
    _strains_and_rates_kernel(*arrays, _SERIES, *_SWITCH_ANGLES, strain, rate)
    return strain, rate


def element_rotation(x: FloatArray, q: FloatArray) -> FloatArray:
    """Angle ``|psi|`` [rad] of every element's relative rotation (§Kinematics, C11): (n,), as
    the norm of :func:`rodnet.kernels.cosserat_strain.kinematics`'s ``psi``."""
    arrays = (_as_float(x), _as_float(q))
    n = arrays[0].shape[0]
    _check_shapes(tuple(a.shape for a in arrays), ((n, 2, 3), (n, 2, 4)))
    out = np.empty(n)
    _element_rotation_kernel(*arrays, out)
    return out


def stress_resultants(
    # Model:
    stiffness: FloatArray, tau: FloatArray,
    # State in:
    strain: FloatArray, strain_rate: FloatArray,
    # Scalars:
    tension_only: bool, kink_strain: float,
) -> FloatArray:
    """:func:`rodnet.kernels.cosserat.stress_resultants_numpy`, compiled: (n, 6)."""
    arrays = tuple(_as_float(a) for a in (stiffness, tau, strain, strain_rate))
    n = arrays[0].shape[0]
    _check_shapes(tuple(a.shape for a in arrays), ((n, 6), (n,), (n, 6), (n, 6)))
    return _stress_resultants_kernel(*arrays, bool(tension_only), float(kink_strain))


def section_state(
    # Model:
    rest_length: FloatArray, reference_strain: FloatArray, stiffness: FloatArray, tau: FloatArray,
    # State in:
    x: FloatArray, q: FloatArray, velocity: FloatArray,
    # Scalars:
    tension_only: bool, kink_strain: float,
) -> tuple[FloatArray, FloatArray]:
    """Strains ``[Gamma, K]`` (n, 6) and stress resultants ``[N, M]`` (n, 6) with Kelvin-Voigt
    damping, as :func:`rodnet.kernels.cosserat_strain.strains_from_kinematics` and
    :func:`rodnet.kernels.cosserat.stress_resultants_numpy` of the strain rates give them."""
    arrays = _element_arguments(rest_length, reference_strain, stiffness, tau, x, q, velocity)
    n = arrays[0].shape[0]
    strain, stress = np.empty((n, 6)), np.empty((n, 6))
    _section_state_kernel(*arrays, bool(tension_only), float(kink_strain), _SERIES,
                          *_SWITCH_ANGLES, strain, stress)
    return strain, stress


# ---------------------------------------------------------------------------------------------
# scalar pieces


@numba.njit(cache=True)
def _horner(series, row, x):  # pragma: no cover - compiled
    """``polyval(x, series[row])``, evaluated as NumPy does."""
    m = series.shape[1]
    s = series[row, m - 1]
    for i in range(m - 2, -1, -1):
        s = series[row, i] + s * x
    return s


@numba.njit(cache=True)
def _beta(phi, series, angle):  # pragma: no cover - compiled
    """``tan(phi/4) / (2 phi)``, as :func:`rodnet.kernels.cosserat_strain.midpoint_coefficient`."""
    if phi < angle:
        return _horner(series, 0, phi * phi)
    return np.tan(0.25 * phi) / (2.0 * phi)


@numba.njit(cache=True)
def _beta_derivative(phi, series, angle):  # pragma: no cover - compiled
    """``beta'(phi) / phi``."""
    if phi < angle:
        return _horner(series, 1, phi * phi)
    t = np.tan(0.25 * phi)
    return ((1.0 + t * t) / (8.0 * phi) - t / (2.0 * phi * phi)) / phi


@numba.njit(cache=True)
def _gamma(phi, series, angle):  # pragma: no cover - compiled
    """``1/phi^2 - cot(phi/2)/(2 phi)``, as :func:`rodnet.kernels.so3.dexp_inv_coefficient`."""
    if phi < angle:
        return _horner(series, 2, phi * phi)
    inv_p = 1.0 / phi
    return inv_p * (inv_p - 0.5 / np.tan(0.5 * phi))


@numba.njit(cache=True)
def _gamma_derivative(phi, series, angle):  # pragma: no cover - compiled
    """``gamma'(phi) / phi``."""
    if phi < angle:
        return _horner(series, 3, phi * phi)
    inv_p = 1.0 / phi
    half_cot = 0.5 / np.tan(0.5 * phi)
    sin_half = np.sin(0.5 * phi)
    return inv_p * inv_p * (inv_p * (half_cot - 2.0 * inv_p) + 0.25 / (sin_half * sin_half))


@numba.njit(cache=True)
def _cross(a0, a1, a2, b0, b1, b2):  # pragma: no cover - compiled
    return a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0


@numba.njit(cache=True)
def _kinematics(x, q, e):  # pragma: no cover - compiled
    """``psi``, ``R_m`` (row-major 9-tuple) and ``g`` of element ``e`` (§Kinematics).

    As :func:`rodnet.kernels.cosserat_strain.kinematics`: ``psi = log(conj(q1) q2)`` on the
    quaternion double cover (angle in [0, 2 pi), C11), ``R_m = R(q1 exp_q(psi/2))``,
    ``g = R_m^T (x2 - x1)``.
    """
    w1, x1, y1, z1 = q[e, 0, 0], q[e, 0, 1], q[e, 0, 2], q[e, 0, 3]
    w2, x2, y2, z2 = q[e, 1, 0], q[e, 1, 1], q[e, 1, 2], q[e, 1, 3]
    # conj(q1) ⊗ q2 (quat_conjugate, quat_multiply)
    cx, cy, cz = -x1, -y1, -z1
    rw = w1 * w2 - cx * x2 - cy * y2 - cz * z2
    rx = w1 * x2 + cx * w2 + cy * z2 - cz * y2
    ry = w1 * y2 - cx * z2 + cy * w2 + cz * x2
    rz = w1 * z2 + cx * y2 - cy * x2 + cz * w2
    # logarithm on the double cover (rotvec_from_quat with shortest=False): no sign flip
    s = np.sqrt(rx * rx + ry * ry + rz * rz)
    if s < 1e-6 * rw:
        t = s / rw
        factor = 2.0 / rw * (1.0 - t * t / 3.0)
    else:
        factor = 2.0 * np.arctan2(s, rw) / s
    p0, p1, p2 = factor * rx, factor * ry, factor * rz
    # exp_q of theta = psi/2 (quat_from_rotvec): (cos(|theta|/2), sinc(|theta|/(2 pi)) theta/2)
    h0, h1, h2 = 0.5 * p0, 0.5 * p1, 0.5 * p2
    phi_h = np.sqrt(h0 * h0 + h1 * h1 + h2 * h2)
    y = np.pi * (phi_h / (2.0 * np.pi))
    c = 0.5 * (np.sin(y) / y if y != 0.0 else 1.0)
    hw, hx, hy, hz = np.cos(0.5 * phi_h), c * h0, c * h1, c * h2
    # q1 ⊗ half (quat_multiply), then quat_to_matrix
    w = w1 * hw - x1 * hx - y1 * hy - z1 * hz
    u = w1 * hx + x1 * hw + y1 * hz - z1 * hy
    v = w1 * hy - x1 * hz + y1 * hw + z1 * hx
    z = w1 * hz + x1 * hy - y1 * hx + z1 * hw
    R = (1.0 - 2.0 * (v * v + z * z), 2.0 * (u * v - w * z), 2.0 * (u * z + w * v),
         2.0 * (u * v + w * z), 1.0 - 2.0 * (u * u + z * z), 2.0 * (v * z - w * u),
         2.0 * (u * z - w * v), 2.0 * (v * z + w * u), 1.0 - 2.0 * (u * u + v * v))
    d0, d1, d2 = x[e, 1, 0] - x[e, 0, 0], x[e, 1, 1] - x[e, 0, 1], x[e, 1, 2] - x[e, 0, 2]
    g0 = R[0] * d0 + R[3] * d1 + R[6] * d2
    g1 = R[1] * d0 + R[4] * d1 + R[7] * d2
    g2 = R[2] * d0 + R[5] * d1 + R[8] * d2
    return (p0, p1, p2), R, (g0, g1, g2)


@numba.njit(cache=True)
def _stop_excess(phi):  # pragma: no cover - compiled
    """How far [rad] the element rotation ``phi`` is past the rotation stop (C52), 0 before it,
    as in :func:`rodnet.kernels.cosserat_strain.rotation_stop`."""
    return phi - ROTATION_STOP if phi > ROTATION_STOP else 0.0


@numba.njit(cache=True)
def _axial(e, e_rate, EA, tau, tension_only, kink):  # pragma: no cover - compiled
    """Axial force and its strain and strain-rate moduli (§Constitutive law).

    As :func:`rodnet.kernels.tension.axial_force` and
    :func:`rodnet.kernels.cosserat.stress_resultants_and_moduli`; both moduli vanish where the
    tension-only clamp holds.
    """
    etaA = tau * EA
    if not tension_only:
        return EA * e + etaA * e_rate, EA, etaA
    if e < -1.0:  # (C51): the mirrored ramp in s = -1 - e pushes; moduli as on the tension side
        force, modulus, viscous = _tension(-1.0 - e, -e_rate, REVERSED_STIFFNESS * EA, tau, kink)
        return -force, modulus, viscous
    return _tension(e, e_rate, EA, tau, kink)


@numba.njit(cache=True)
def _tension(e, e_rate, EA, tau, kink):  # pragma: no cover - compiled
    """The tension-only branch of :func:`_axial`: (C22)-(C26) with the total clamped at zero."""
    etaA = tau * EA
    curvature = 0.0
    if kink == 0.0:
        r, slope = (e, 1.0) if e > 0.0 else (0.0, 0.0)
    else:
        ec = e if e > 0.0 else 0.0
        if ec < kink:
            r, slope = ec * ec / (2.0 * kink), ec / kink
        else:
            r, slope = ec - 0.5 * kink, 1.0
        if e > 0.0 and e < kink:
            curvature = 1.0 / kink
    total = EA * r + etaA * slope * e_rate
    force = 0.0 if total < 0.0 else total
    if force > 0.0:
        return force, EA * (slope + tau * curvature * e_rate), tau * EA * slope
    return force, 0.0, 0.0


@numba.njit(cache=True)
def _antiderivative(x, s_ref, EA, k, delta):  # pragma: no cover - compiled
    """:func:`rodnet.kernels.tension._antiderivative` of one element (S12)."""
    outer = EA * (0.5 * x * x) + k * (0.5 * x * x - s_ref * x)
    if delta == 0.0:
        return outer
    if x < delta:
        return ((0.5 * EA + k) * x * x * x / 3.0 - 0.5 * k * s_ref * x * x) / delta
    return outer - 0.5 * EA * delta * x + EA * delta * delta / 6.0 - k * delta * delta / 6.0 \
        + 0.5 * k * s_ref * delta


@numba.njit(cache=True)
def _clamped_integral(s, s_ref, EA, k, delta):  # pragma: no cover - compiled
    """:func:`rodnet.kernels.tension._clamped_integral` of one element (S12), (S13)."""
    if delta == 0.0:
        threshold = max(0.0, k * s_ref / (EA + k))
    else:
        s1 = k * s_ref / (0.5 * EA + k)
        threshold = max(s1, 0.0) if s1 < delta else (0.5 * EA * delta + k * s_ref) / (EA + k)
    return _antiderivative(max(s, threshold), s_ref, EA, k, delta) - \
        _antiderivative(threshold, s_ref, EA, k, delta)


@numba.njit(cache=True)
def _axial_step_potential(e, e_ref, inv_h, EA, etaA, Le, tension_only,
                          kink):  # pragma: no cover - compiled
    """:func:`rodnet.kernels.tension.step_potential` of one element (S12), (C51)."""
    k = etaA * inv_h
    if not tension_only:
        return Le * (0.5 * EA * e * e + 0.5 * k * (e - e_ref) * (e - e_ref))
    value = _clamped_integral(e, max(e_ref, 0.0), EA, k, kink)
    if e < -1.0:   # (C51): the mirrored law in s = -1 - e
        value += _clamped_integral(-1.0 - e, max(-1.0 - e_ref, 0.0), REVERSED_STIFFNESS * EA,
                                   REVERSED_STIFFNESS * k, kink)
    return Le * value


@numba.njit(cache=True)
def _step_potential_kernel(rest_length, reference_strain, stiffness, tau, x, q, step_reference,
                           inv_h, tension_only, kink):  # pragma: no cover - compiled
    """Per element: ``Le [Psi_axial + sum_k D_k (eps_k^2 + tau inv_h (eps_k - eps_ref_k)^2) / 2]``
    plus the rotation stop (C52), (C53)."""
    n = rest_length.shape[0]
    energy = np.empty(n)
    for e in range(n):
        (p0, p1, p2), _, (g0, g1, g2) = _kinematics(x, q, e)
        Le = rest_length[e]
        eps = (g0 / Le - reference_strain[e, 0], g1 / Le - reference_strain[e, 1],
               g2 / Le - reference_strain[e, 2], p0 / Le - reference_strain[e, 3],
               p1 / Le - reference_strain[e, 4], p2 / Le - reference_strain[e, 5])
        bulk = 0.0
        for k in range(1, 6):
            d = eps[k] - step_reference[e, k]
            bulk += stiffness[e, k] * (eps[k] * eps[k] + tau[e] * inv_h * d * d)
        excess = _stop_excess(np.sqrt(p0 * p0 + p1 * p1 + p2 * p2))   # (C52)
        energy[e] = (0.5 * Le * bulk + 0.5 * stiffness[e, 1] * Le * (excess * excess)
                     + _axial_step_potential(eps[0], step_reference[e, 0], inv_h,
                                             stiffness[e, 0], tau[e] * stiffness[e, 0], Le,
                                             tension_only, kink))
    return energy


# ---------------------------------------------------------------------------------------------
# loops


@numba.njit(cache=True)
def _strains_and_rates(rest_length, reference_strain, x, q, velocity, e, series, beta_angle,
                       gamma_angle):  # pragma: no cover - compiled
    """Kinematics, strains and strain rates of element ``e``.

    Returns ``psi``, ``R_m`` (row-major 9-tuple), ``g``, ``phi = |psi|``, ``beta``, ``gamma``, the
    strains ``[Gamma, K]`` (:func:`rodnet.kernels.cosserat_strain.strains_from_kinematics`), their
    rates (:func:`rodnet.kernels.cosserat_strain.strain_rates_from_kinematics`) and the reduced
    velocity ``[v2 - v1, W1, W2]`` as three 3-tuples.
    """
    (p0, p1, p2), R, (g0, g1, g2) = _kinematics(x, q, e)
    Le = rest_length[e]
    phi = np.sqrt(p0 * p0 + p1 * p1 + p2 * p2)
    beta = _beta(phi, series, beta_angle)
    gamma = _gamma(phi, series, gamma_angle)
    # strains [g / Le - Gamma0, psi / Le - K0] (strains_from_kinematics)
    eps = (g0 / Le - reference_strain[e, 0], g1 / Le - reference_strain[e, 1],
           g2 / Le - reference_strain[e, 2], p0 / Le - reference_strain[e, 3],
           p1 / Le - reference_strain[e, 4], p2 / Le - reference_strain[e, 5])
    # strain rates (strain_rates_from_kinematics)
    vd0, vd1, vd2 = (velocity[e, 6] - velocity[e, 0], velocity[e, 7] - velocity[e, 1],
                     velocity[e, 8] - velocity[e, 2])
    a0, a1, a2 = velocity[e, 3], velocity[e, 4], velocity[e, 5]
    b0, b1, b2 = velocity[e, 9], velocity[e, 10], velocity[e, 11]
    w0, w1, w2 = b0 - a0, b1 - a1, b2 - a2
    c0, c1, c2 = _cross(p0, p1, p2, w0, w1, w2)
    z0 = 0.5 * (a0 + b0) + beta * c0
    z1 = 0.5 * (a1 + b1) + beta * c1
    z2 = 0.5 * (a2 + b2) + beta * c2
    s0, s1, s2 = _cross(g0, g1, g2, z0, z1, z2)
    cc0, cc1, cc2 = _cross(p0, p1, p2, c0, c1, c2)
    k0, k1, k2 = _cross(p0, p1, p2, a0, a1, a2)
    rate = ((R[0] * vd0 + R[3] * vd1 + R[6] * vd2 + s0) / Le,
            (R[1] * vd0 + R[4] * vd1 + R[7] * vd2 + s1) / Le,
            (R[2] * vd0 + R[5] * vd1 + R[8] * vd2 + s2) / Le,
            (w0 + 0.5 * c0 + gamma * cc0 + k0) / Le,
            (w1 + 0.5 * c1 + gamma * cc1 + k1) / Le,
            (w2 + 0.5 * c2 + gamma * cc2 + k2) / Le)
    return ((p0, p1, p2), R, (g0, g1, g2), phi, beta, gamma, eps, rate,
            ((vd0, vd1, vd2), (a0, a1, a2), (b0, b1, b2)))


@numba.njit(cache=True)
def _resultants(stiffness, tau, rest_length, e, eps, rate, psi, phi, tension_only,
                kink):  # pragma: no cover - compiled
    """Stress resultants ``(N0, N1, N2, M0, M1, M2)`` of element ``e`` with the axial strain and
    strain-rate moduli (:func:`rodnet.kernels.cosserat.stress_resultants_and_moduli`); ``M``
    includes the rotation stop's moment ``k_s (phi - phi_s) psi / phi`` (C52) of an element turned
    by ``phi = |psi|`` beyond it."""
    te = tau[e]
    N0, D0, V0 = _axial(eps[0], rate[0], stiffness[e, 0], te, tension_only, kink)
    N1 = stiffness[e, 1] * eps[1] + te * stiffness[e, 1] * rate[1]
    N2 = stiffness[e, 2] * eps[2] + te * stiffness[e, 2] * rate[2]
    M0 = stiffness[e, 3] * eps[3] + te * stiffness[e, 3] * rate[3]
    M1 = stiffness[e, 4] * eps[4] + te * stiffness[e, 4] * rate[4]
    M2 = stiffness[e, 5] * eps[5] + te * stiffness[e, 5] * rate[5]
    excess = _stop_excess(phi)
    if excess > 0.0:
        stop = stiffness[e, 1] * rest_length[e] * excess / phi
        M0, M1, M2 = M0 + stop * psi[0], M1 + stop * psi[1], M2 + stop * psi[2]
    return (N0, N1, N2, M0, M1, M2), D0, V0


@numba.njit(inline="always")
def _element_force(N0, N1, N2, M0, M1, M2, psi, R, g, beta, gamma, force,
                   e):  # pragma: no cover - compiled
    """Row ``e`` of ``force`` (E, 12): the internal force ``S [R_m N, P2 h - A M, P2^T h + A^T M]``,
    ``h = N x g``, of the resultants ``N``, ``M``, ``psi``, ``R_m`` (row-major 9-tuple), ``g``
    and the coefficients ``beta``, ``gamma`` (the reduced force (_reduced_force) expanded to the
    12 element DOF (expand_vector))."""
    p0, p1, p2 = psi
    g0, g1, g2 = g
    h0, h1, h2 = _cross(N0, N1, N2, g0, g1, g2)
    ph0, ph1, ph2 = _cross(p0, p1, p2, h0, h1, h2)
    pm0, pm1, pm2 = _cross(p0, p1, p2, M0, M1, M2)
    ppm0, ppm1, ppm2 = _cross(p0, p1, p2, pm0, pm1, pm2)
    AM0 = M0 + 0.5 * pm0 + gamma * ppm0
    AM1 = M1 + 0.5 * pm1 + gamma * ppm1
    AM2 = M2 + 0.5 * pm2 + gamma * ppm2
    fd0 = R[0] * N0 + R[1] * N1 + R[2] * N2
    fd1 = R[3] * N0 + R[4] * N1 + R[5] * N2
    fd2 = R[6] * N0 + R[7] * N1 + R[8] * N2
    force[e, 0], force[e, 1], force[e, 2] = -fd0, -fd1, -fd2
    force[e, 6], force[e, 7], force[e, 8] = fd0, fd1, fd2
    force[e, 3] = 0.5 * h0 + beta * ph0 - AM0
    force[e, 4] = 0.5 * h1 + beta * ph1 - AM1
    force[e, 5] = 0.5 * h2 + beta * ph2 - AM2
    force[e, 9] = 0.5 * h0 - beta * ph0 + (AM0 - pm0)
    force[e, 10] = 0.5 * h1 - beta * ph1 + (AM1 - pm1)
    force[e, 11] = 0.5 * h2 - beta * ph2 + (AM2 - pm2)


@numba.njit(cache=True)
def state_and_force_range(first, stop, rest_length, reference_strain, stiffness, tau, x, q,
                          velocity, tension_only, kink, series, beta_angle, gamma_angle,
                          step_reference, inv_h, force, psi_out, R_out, g_out, coefficients,
                          constitutive, velocity9, monitor_out):  # pragma: no cover - compiled
    """Internal force ``S [R_m N, P2 h - A M, P2^T h + A^T M]``, ``h = N x g``, of the elements
    ``first`` to ``stop - 1``.

    When ``step_reference`` (n, 6) has ``n`` rows, the strain rates are an implicit step's,
    ``(eps - step_reference) inv_h`` (C53), instead of those of the velocities.

    When ``psi_out`` has ``n`` rows, also stores what :func:`tangents_kernel` takes: ``psi``,
    ``R_m``, ``g``, ``[beta, beta'/phi, gamma, gamma'/phi]``, ``[stress, modulus,
    viscous_modulus]`` and ``[v2 - v1, W1, W2]``; when ``monitor_out`` has ``n`` rows, the axial
    force ``N_0`` [N] and the relative rotation angle ``|psi|`` [rad] of every element.
    """
    store = psi_out.shape[0] > 0
    store_monitor = monitor_out.shape[0] > 0
    stepped = step_reference.shape[0] > 0
    for e in range(first, stop):
        ((p0, p1, p2), R, (g0, g1, g2), phi, beta, gamma, eps, rate,
         ((vd0, vd1, vd2), (a0, a1, a2), (b0, b1, b2))) = _strains_and_rates(
            rest_length, reference_strain, x, q, velocity, e, series, beta_angle, gamma_angle)
        if stepped:  # the axial reference no lower than the kink (tension.step_strain_rate)
            axial_reference = step_reference[e, 0]
            if tension_only:
                if eps[0] < -1.0:
                    axial_reference = min(axial_reference, -1.0)
                else:
                    axial_reference = max(axial_reference, 0.0)
            rate = ((eps[0] - axial_reference) * inv_h,
                    (eps[1] - step_reference[e, 1]) * inv_h,
                    (eps[2] - step_reference[e, 2]) * inv_h,
                    (eps[3] - step_reference[e, 3]) * inv_h,
                    (eps[4] - step_reference[e, 4]) * inv_h,
                    (eps[5] - step_reference[e, 5]) * inv_h)
        te = tau[e]
        (N0, N1, N2, M0, M1, M2), D0, V0 = _resultants(
            stiffness, tau, rest_length, e, eps, rate, (p0, p1, p2), phi, tension_only, kink)
        _element_force(N0, N1, N2, M0, M1, M2, (p0, p1, p2), R, (g0, g1, g2), beta, gamma,
                       force, e)
        if store_monitor:  # the axial force along the chord: a reversed element's (C51) pulls
            monitor_out[e, 0] = -N0 if tension_only and N0 < 0.0 else N0
            monitor_out[e, 1] = phi
        if store:
            psi_out[e, 0], psi_out[e, 1], psi_out[e, 2] = p0, p1, p2
            for k in range(9):
                R_out[e, k // 3, k % 3] = R[k]
            g_out[e, 0], g_out[e, 1], g_out[e, 2] = g0, g1, g2
            coefficients[e, 0] = beta
            coefficients[e, 1] = _beta_derivative(phi, series, beta_angle)
            coefficients[e, 2] = gamma
            coefficients[e, 3] = _gamma_derivative(phi, series, gamma_angle)
            stress = (N0, N1, N2, M0, M1, M2)
            for k in range(6):
                constitutive[e, k] = stress[k]
            for k in range(1, 6):
                constitutive[e, 6 + k] = stiffness[e, k]
                constitutive[e, 12 + k] = te * stiffness[e, k]
            constitutive[e, 6], constitutive[e, 12] = D0, V0
            velocity9[e, 0], velocity9[e, 1], velocity9[e, 2] = vd0, vd1, vd2
            velocity9[e, 3], velocity9[e, 4], velocity9[e, 5] = a0, a1, a2
            velocity9[e, 6], velocity9[e, 7], velocity9[e, 8] = b0, b1, b2


@numba.njit(inline="always")
def _state_and_force(rest_length, reference_strain, stiffness, tau, x, q, velocity, tension_only,
                     kink, series, beta_angle, gamma_angle, step_reference, inv_h, force, psi_out,
                     R_out, g_out, coefficients, constitutive, velocity9,
                     monitor_out):  # pragma: no cover - compiled
    """:func:`state_and_force_range` of every element, in :data:`BLOCKS` blocks over numba's
    threads in a ``parallel=True`` caller."""
    n = rest_length.shape[0]
    for b in numba.prange(BLOCKS):
        state_and_force_range(b * n // BLOCKS, (b + 1) * n // BLOCKS, rest_length,
                              reference_strain, stiffness, tau, x, q, velocity, tension_only,
                              kink, series, beta_angle, gamma_angle, step_reference, inv_h, force,
                              psi_out, R_out, g_out, coefficients, constitutive, velocity9,
                              monitor_out)


@numba.njit(cache=True, parallel=threads.PRANGE_ONLY)
def _internal_force_kernel(rest_length, reference_strain, stiffness, tau, x, q, velocity,
                           tension_only, kink, series, beta_angle, gamma_angle, step_reference,
                           inv_h):  # pragma: no cover - compiled
    n = rest_length.shape[0]
    force = np.empty((n, 12))
    none1, none2, none3 = np.empty((0, 3)), np.empty((0, 3, 3)), np.empty((0, 4))
    none4, none5, none6 = np.empty((0, 18)), np.empty((0, 9)), np.empty((0, 2))
    _state_and_force(rest_length, reference_strain, stiffness, tau, x, q, velocity, tension_only,
                     kink, series, beta_angle, gamma_angle, step_reference, inv_h, force, none1,
                     none2, none1, none3, none4, none5, none6)
    return force


@numba.njit(cache=True, parallel=threads.PRANGE_ONLY)
def _internal_force_andtangents_kernel(rest_length, reference_strain, stiffness, tau, x, q,
                                        velocity, tension_only, kink, series, beta_angle,
                                        gamma_angle, step_reference, inv_h, strain_shift, force,
                                        stiffness_out, damping_out):  # pragma: no cover - compiled
    n = rest_length.shape[0]
    psi, R_m, g = np.empty((n, 3)), np.empty((n, 3, 3)), np.empty((n, 3))
    coefficients, constitutive, velocity9 = np.empty((n, 4)), np.empty((n, 18)), np.empty((n, 9))
    _state_and_force(rest_length, reference_strain, stiffness, tau, x, q, velocity, tension_only,
                     kink, series, beta_angle, gamma_angle, step_reference, inv_h, force, psi,
                     R_m, g, coefficients, constitutive, velocity9, np.empty((0, 2)))
    _shifted_tangents(psi, R_m, g, coefficients, constitutive, velocity9, rest_length,
                      step_reference, inv_h, strain_shift, stiffness_out, damping_out)


@numba.njit(cache=True)
def _shifted_tangents(psi, R_m, g, coefficients, constitutive, velocity9, rest_length,
                      step_reference, inv_h, strain_shift, stiffness_out,
                      damping_out):  # pragma: no cover - compiled
    """:func:`tangents_kernel` from what :func:`state_and_force_range` stored, the stresses of
    its geometric part at the strains shifted by ``strain_shift`` (n, 6) where that has rows
    (the mixed Newton step, C55)."""
    rate_factor = inv_h if step_reference.shape[0] > 0 else 0.0
    if strain_shift.shape[0] > 0:
        for e in range(rest_length.shape[0]):
            for k in range(6):
                constitutive[e, k] += (constitutive[e, 6 + k] + rate_factor
                                       * constitutive[e, 12 + k]) * strain_shift[e, k]
    tangents_kernel(psi, R_m, g, coefficients, constitutive, velocity9, 1.0 / rest_length,
                    rate_factor, stiffness_out, damping_out)


@numba.njit(cache=True)
def _section_state_kernel(rest_length, reference_strain, stiffness, tau, x, q, velocity,
                          tension_only, kink, series, beta_angle, gamma_angle, strain_out,
                          stress_out):  # pragma: no cover - compiled
    """Strains ``[Gamma, K]`` and stress resultants ``[N, M]`` (with damping and the rotation
    stop's moment, C52) of every element."""
    for e in range(rest_length.shape[0]):
        psi, _, _, phi, _, _, eps, rate, _ = _strains_and_rates(
            rest_length, reference_strain, x, q, velocity, e, series, beta_angle, gamma_angle)
        stress, _, _ = _resultants(stiffness, tau, rest_length, e, eps, rate, psi, phi,
                                   tension_only, kink)
        for k in range(6):
            strain_out[e, k] = eps[k]
            stress_out[e, k] = stress[k]


@numba.njit(cache=True)
def _strains_and_rates_kernel(rest_length, reference_strain, x, q, velocity, series, beta_angle,
                              gamma_angle, strain_out, rate_out):  # pragma: no cover - compiled
    for e in range(rest_length.shape[0]):
        _, _, _, _, _, _, eps, rate, _ = _strains_and_rates(
            rest_length, reference_strain, x, q, velocity, e, series, beta_angle, gamma_angle)
        for k in range(6):
            strain_out[e, k] = eps[k]
            rate_out[e, k] = rate[k]


@numba.njit(cache=True)
def _element_rotation_kernel(x, q, out):  # pragma: no cover - compiled
    for e in range(out.shape[0]):
        (p0, p1, p2), _, _ = _kinematics(x, q, e)
        out[e] = np.sqrt(p0 * p0 + p1 * p1 + p2 * p2)


@numba.njit(cache=True)
def _stress_resultants_kernel(stiffness, tau, strain, strain_rate, tension_only,
                              kink):  # pragma: no cover - compiled
    n = stiffness.shape[0]
    stress = np.empty((n, 6))
    for e in range(n):
        stress[e, 0] = _axial(strain[e, 0], strain_rate[e, 0], stiffness[e, 0], tau[e],
                              tension_only, kink)[0]
        for k in range(1, 6):
            k_e = stiffness[e, k]
            stress[e, k] = k_e * strain[e, k] + tau[e] * k_e * strain_rate[e, k]
    return stress


# ---------------------------------------------------------------------------------------------
# the rod part of the explicit step loop (FORMULATION.md §9b, (C46)-(C47)):
# rodnet.kernels.explicit runs it


class RodElements(NamedTuple):
    """The read-only arrays of the rod elements of a model, as the explicit loop takes them.

    ``pos_nodes``, ``rot_nodes`` (E, 2) int; ``offset_q`` (E, 2, 4) and ``offset_R``
    (E, 2, 3, 3) the end offsets ``Q`` (``R_end = R_node Q``; no rows without offsets);
    ``rest_length``, ``reference_strain``, ``stiffness``, ``tau`` as :func:`internal_force`;
    ``tension_only``, ``kink``; ``series``, ``beta_angle``, ``gamma_angle``:
    :data:`SERIES_ARGUMENTS`. A model without rod elements has E = 0.
    """

    pos_nodes: np.ndarray
    rot_nodes: np.ndarray
    offset_q: np.ndarray
    offset_R: np.ndarray
    rest_length: np.ndarray
    reference_strain: np.ndarray
    stiffness: np.ndarray
    tau: np.ndarray
    tension_only: bool
    kink: float
    series: np.ndarray
    beta_angle: float
    gamma_angle: float


def no_rod_elements() -> RodElements:
    """:class:`RodElements` with no element (models without rods)."""
    z = np.zeros
    return RodElements(z((0, 2), np.int64), z((0, 2), np.int64), z((0, 2, 4)), z((0, 2, 3, 3)),
                       z(0), z((0, 6)), z((0, 6)), z(0), True, 0.0, *SERIES_ARGUMENTS)


@numba.njit(cache=True)
def _quat_product(aw, ax, ay, az, bw, bx, by, bz):  # pragma: no cover - compiled
    """``a ⊗ b`` of two quaternions given by their components (quat_multiply)."""
    return (aw * bw - ax * bx - ay * by - az * bz,
            aw * bx + ax * bw + ay * bz - az * by,
            aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw)


@numba.njit(cache=True)
def _end_state(quat, W, offset_q, offset_R, e, s, r):  # pragma: no cover - compiled
    """Material quaternion ``q_node Q`` (4-tuple) and angular velocity ``Q^T W_node`` (3-tuple,
    end frame) of end ``s`` of element ``e`` on rotation node ``r``, as
    :meth:`rodnet.models.cosserat.model.CosseratModel._element_state` (no offset arrays: ``Q = I``)."""
    w, u, y, z = quat[r, 0], quat[r, 1], quat[r, 2], quat[r, 3]
    W0, W1, W2 = W[r, 0], W[r, 1], W[r, 2]
    if offset_q.shape[0] == 0:
        return (w, u, y, z), (W0, W1, W2)
    O = offset_R
    return (_quat_product(w, u, y, z, offset_q[e, s, 0], offset_q[e, s, 1], offset_q[e, s, 2],
                          offset_q[e, s, 3]),
            (O[e, s, 0, 0] * W0 + O[e, s, 1, 0] * W1 + O[e, s, 2, 0] * W2,
             O[e, s, 0, 1] * W0 + O[e, s, 1, 1] * W1 + O[e, s, 2, 1] * W2,
             O[e, s, 0, 2] * W0 + O[e, s, 1, 2] * W1 + O[e, s, 2, 2] * W2))


@numba.njit(cache=True)
def element_pose(x, quat, pos_nodes, rot_nodes, offset_q):  # pragma: no cover - compiled
    """Element end positions (E, 2, 3) and material quaternions ``q_node Q`` (E, 2, 4) from the
    node positions ``x`` (N, 3) and quaternions ``quat`` (R, 4); ``offset_q`` (E, 2, 4) holds
    the ends' offsets ``Q`` ((0, 2, 4): none)."""
    n_el = pos_nodes.shape[0]
    xe = np.empty((n_el, 2, 3))
    qe = np.empty((n_el, 2, 4))
    offset = offset_q.shape[0] > 0
    for e in range(n_el):
        for s in range(2):
            a, r = pos_nodes[e, s], rot_nodes[e, s]
            for i in range(3):
                xe[e, s, i] = x[a, i]
            if offset:
                qe[e, s, 0], qe[e, s, 1], qe[e, s, 2], qe[e, s, 3] = _quat_product(
                    quat[r, 0], quat[r, 1], quat[r, 2], quat[r, 3], offset_q[e, s, 0],
                    offset_q[e, s, 1], offset_q[e, s, 2], offset_q[e, s, 3])
            else:
                for i in range(4):
                    qe[e, s, i] = quat[r, i]
    return xe, qe


@numba.njit(cache=True)
def element_velocities(v, element_dofs, offset_R):  # pragma: no cover - compiled
    """Element velocities (E, 12) ``[v_a, Q_a^T W_a, v_b, Q_b^T W_b]`` from the generalized
    velocities ``v`` (n_dof,) at ``element_dofs`` (E, 12); ``offset_R`` (E, 2, 3, 3) holds the
    ends' offset rotations ``Q`` ((0, 2, 3, 3): none)."""
    n_el = element_dofs.shape[0]
    ve = np.empty((n_el, 12))
    offset = offset_R.shape[0] > 0
    for e in range(n_el):
        for j in range(12):
            ve[e, j] = v[element_dofs[e, j]]
        if offset:
            for s in range(2):
                o = 6 * s + 3
                w0, w1, w2 = ve[e, o], ve[e, o + 1], ve[e, o + 2]
                for i in range(3):
                    ve[e, o + i] = (offset_R[e, s, 0, i] * w0 + offset_R[e, s, 1, i] * w1
                                    + offset_R[e, s, 2, i] * w2)
    return ve


@numba.njit(cache=True)
def to_node_frames(f, K, C, offset_R):  # pragma: no cover - compiled
    """Element forces ``f`` (E, 12) and, unless they are empty, blocks ``K``, ``C`` (E, 12, 12)
    from the ends' material frames to the rotation nodes' frames, in place: ``T f``, ``T K
    T^T``, ``T C T^T`` with ``T = blockdiag(I, Q_a, I, Q_b)`` and ``Q`` = ``offset_R`` (E, 2,
    3, 3)."""
    for e in range(f.shape[0]):
        for s in range(2):
            Q = offset_R[e, s]
            o = 6 * s + 3
            f0, f1, f2 = f[e, o], f[e, o + 1], f[e, o + 2]
            for i in range(3):
                f[e, o + i] = Q[i, 0] * f0 + Q[i, 1] * f1 + Q[i, 2] * f2
            for M in (K, C):
                if M.shape[0] == 0:
                    continue
                for c in range(12):        # rows of the end's block: Q M[o:o+3, c]
                    m0, m1, m2 = M[e, o, c], M[e, o + 1, c], M[e, o + 2, c]
                    for i in range(3):
                        M[e, o + i, c] = Q[i, 0] * m0 + Q[i, 1] * m1 + Q[i, 2] * m2
                for r in range(12):        # columns: M[r, o:o+3] Q^T
                    m0, m1, m2 = M[e, r, o], M[e, r, o + 1], M[e, r, o + 2]
                    for i in range(3):
                        M[e, r, o + i] = Q[i, 0] * m0 + Q[i, 1] * m1 + Q[i, 2] * m2


@numba.njit(cache=True)
def _series8(series, row, x):  # pragma: no cover - compiled
    """:func:`_horner` unrolled for the eight coefficients of :data:`SERIES_ARGUMENTS`."""
    c = series[row]
    return c[0] + x * (c[1] + x * (c[2] + x * (c[3] + x * (c[4] + x * (c[5] + x * (c[6]
                                                                                 + x * c[7]))))))


_ATAN_SERIES_T2 = 0.0157
"""``tan(phi/4)^2`` below which (``phi`` < 0.4998 rad) :func:`_atan_series` takes the logarithm's
angle: its eleven terms leave a remainder below 1e-21 there."""


@numba.njit(cache=True)
def _atan_series(t2):  # pragma: no cover - compiled
    """``atan(t) / t`` from ``t^2``: the Taylor series through ``t^20``, by Horner's rule."""
    a = -1.0 / 19.0 + t2 * (1.0 / 21.0)
    a = 1.0 / 17.0 + t2 * a
    a = -1.0 / 15.0 + t2 * a
    a = 1.0 / 13.0 + t2 * a
    a = -1.0 / 11.0 + t2 * a
    a = 1.0 / 9.0 + t2 * a
    a = -1.0 / 7.0 + t2 * a
    a = 1.0 / 5.0 + t2 * a
    a = -1.0 / 3.0 + t2 * a
    return 1.0 + t2 * a


@numba.njit(cache=True, error_model="numpy")
def rod_forces_range(x, quat, v, W, pos, rot, oq, oR, series, stiffness, tau, rest_length,
                     reference_strain, tension_only, kink, beta_angle, gamma_angle, force,
                     monitor):  # pragma: no cover - compiled
    """Element forces ``force`` (E, 12), in the element ends' frames, from the node state
    (positions ``x``, velocities ``v`` (N, 3), quaternions ``quat``, body angular velocities
    ``W`` (R, 3)), and ``monitor`` (E, 2): the axial force [N] and the element rotation
    ``|psi|`` [rad]. The elements' arrays are the fields of :class:`RodElements`
    (``pos_nodes``, ``rot_nodes``, ``offset_q``, ``offset_R``, ...), one by one (numba's
    parallel loops take no named tuples), and a block of elements is given as these arrays'
    rows (views): the loop then starts at 0, which lets the compiler drop the checks for
    negative indices.

    The equations of :func:`state_and_force_range` (the reference path; they agree to a few ulp),
    each element read straight from the node arrays and its rotation algebra without
    trigonometry: with ``r = conj(q1) q2 = (c, s n)`` scaled to ``|r| = 1``, ``c = cos(phi/2)``,
    ``s = sin(phi/2)``, the half rotation ``exp_q(psi/2) = (cos(phi/4), sin(phi/4) n)`` follows
    from the half-angle formulas, ``t = tan(phi/4) = s / (1 + c)`` gives ``beta = t / (2 phi)``,
    ``cot(phi/2) = c / s`` gives ``gamma``, and the angle is ``phi = 4 atan(t)`` by its Taylor
    series below 0.5 rad (``atan2`` above).
    """
    for e in range(rest_length.shape[0]):
        i1, i2 = pos[e, 0], pos[e, 1]
        (w1, x1, y1, z1), (a0, a1, a2) = _end_state(quat, W, oq, oR, e, 0, rot[e, 0])
        (w2, x2, y2, z2), (b0, b1, b2) = _end_state(quat, W, oq, oR, e, 1, rot[e, 1])
        # psi = log(conj(q1) q2) on the double cover (as _kinematics)
        rw, rx, ry, rz = _quat_product(w1, -x1, -y1, -z1, w2, x2, y2, z2)
        ss = rx * rx + ry * ry + rz * rz
        s = np.sqrt(ss)
        # half-angle formulas: 2 |r| cos^2(phi/4) = |r| + rw, tan(phi/4) = s / (|r| + rw)
        norm = np.sqrt(rw * rw + ss)
        if rw >= 0.0:
            twice_cos2 = norm + rw
            inv_tc = 1.0 / twice_cos2
            t = s * inv_tc
        else:
            twice_cos2 = ss / (norm - rw)
            inv_tc = 1.0 / twice_cos2
            t = (norm - rw) / s
        t2 = t * t
        if t2 < _ATAN_SERIES_T2:  # phi = 4 atan(t) = 4 t a(t^2), phi / s = 4 a(t^2) / twice_cos2
            factor = 4.0 * _atan_series(t2) * inv_tc
        else:
            factor = 2.0 * np.arctan2(s, rw) / s
        p0, p1, p2 = factor * rx, factor * ry, factor * rz
        phi = np.sqrt(p0 * p0 + p1 * p1 + p2 * p2)
        hw = np.sqrt(0.5 * twice_cos2 / norm)
        hs = hw * inv_tc    # = 1 / (2 |r| hw)
        hx, hy, hz = hs * rx, hs * ry, hs * rz
        if phi < beta_angle:
            beta = _series8(series, 0, phi * phi)
        else:
            beta = t / (2.0 * phi)
        if phi < gamma_angle:
            gamma = _series8(series, 2, phi * phi)
        else:
            inv_p = 1.0 / phi
            gamma = inv_p * (inv_p - 0.5 * rw / s)
        # R_m = R(q1 exp_q(psi/2)), g = R_m^T (x2 - x1)
        w, u, y, z = _quat_product(w1, x1, y1, z1, hw, hx, hy, hz)
        R = (1.0 - 2.0 * (y * y + z * z), 2.0 * (u * y - w * z), 2.0 * (u * z + w * y),
             2.0 * (u * y + w * z), 1.0 - 2.0 * (u * u + z * z), 2.0 * (y * z - w * u),
             2.0 * (u * z - w * y), 2.0 * (y * z + w * u), 1.0 - 2.0 * (u * u + y * y))
        d0, d1, d2 = x[i2, 0] - x[i1, 0], x[i2, 1] - x[i1, 1], x[i2, 2] - x[i1, 2]
        g0 = R[0] * d0 + R[3] * d1 + R[6] * d2
        g1 = R[1] * d0 + R[4] * d1 + R[7] * d2
        g2 = R[2] * d0 + R[5] * d1 + R[8] * d2
        inv_le = 1.0 / rest_length[e]
        eps = (g0 * inv_le - reference_strain[e, 0], g1 * inv_le - reference_strain[e, 1],
               g2 * inv_le - reference_strain[e, 2], p0 * inv_le - reference_strain[e, 3],
               p1 * inv_le - reference_strain[e, 4], p2 * inv_le - reference_strain[e, 5])
        # strain rates (as _strains_and_rates)
        vd0, vd1, vd2 = v[i2, 0] - v[i1, 0], v[i2, 1] - v[i1, 1], v[i2, 2] - v[i1, 2]
        w0, w1_, w2_ = b0 - a0, b1 - a1, b2 - a2
        c0, c1, c2 = _cross(p0, p1, p2, w0, w1_, w2_)
        s0, s1, s2 = _cross(g0, g1, g2, 0.5 * (a0 + b0) + beta * c0, 0.5 * (a1 + b1) + beta * c1,
                            0.5 * (a2 + b2) + beta * c2)
        cc0, cc1, cc2 = _cross(p0, p1, p2, c0, c1, c2)
        k0, k1, k2 = _cross(p0, p1, p2, a0, a1, a2)
        rate = ((R[0] * vd0 + R[3] * vd1 + R[6] * vd2 + s0) * inv_le,
                (R[1] * vd0 + R[4] * vd1 + R[7] * vd2 + s1) * inv_le,
                (R[2] * vd0 + R[5] * vd1 + R[8] * vd2 + s2) * inv_le,
                (w0 + 0.5 * c0 + gamma * cc0 + k0) * inv_le,
                (w1_ + 0.5 * c1 + gamma * cc1 + k1) * inv_le,
                (w2_ + 0.5 * c2 + gamma * cc2 + k2) * inv_le)
        (N0, N1, N2, M0, M1, M2), _, _ = _resultants(
            stiffness, tau, rest_length, e, eps, rate, (p0, p1, p2), phi, tension_only, kink)
        _element_force(N0, N1, N2, M0, M1, M2, (p0, p1, p2), R, (g0, g1, g2), beta, gamma,
                       force, e)
        # the axial force along the chord: a reversed element's (C51) pulls
        monitor[e, 0] = -N0 if tension_only and N0 < 0.0 else N0
        monitor[e, 1] = phi


@numba.njit(cache=True, error_model="numpy")
def _largest(monitor):  # pragma: no cover - compiled
    """The largest axial force [N] and element rotation [rad] of ``monitor`` (E, 2)."""
    peak, phi_max = 0.0, 0.0
    for e in range(monitor.shape[0]):
        peak = max(peak, monitor[e, 0])
        phi_max = max(phi_max, monitor[e, 1])
    return peak, phi_max


@numba.njit(inline="always")
def rod_forces(x, quat, v, W, rods, force, monitor, blocks):  # pragma: no cover - compiled
    """Every element's force (:func:`rod_forces_range`, in ``blocks`` blocks of consecutive
    elements, over numba's threads in a ``parallel=True`` caller: see :data:`BLOCKS`) into
    ``force`` (E, 12); returns the largest axial force [N] and element rotation ``|psi|``
    [rad]. ``monitor`` (E, 2) is scratch."""
    pos, rot, oq, oR = rods.pos_nodes, rods.rot_nodes, rods.offset_q, rods.offset_R
    series, stiffness, tau = rods.series, rods.stiffness, rods.tau
    rest_length, reference_strain = rods.rest_length, rods.reference_strain
    tension_only, kink = rods.tension_only, rods.kink
    beta_angle, gamma_angle = rods.beta_angle, rods.gamma_angle  # no named tuple in a parallel loop
    n = rest_length.shape[0]
    if blocks == 1:  # one call: a loop of one block around it made a serial step 1.25 times as long
        rod_forces_range(x, quat, v, W, pos, rot, oq, oR, series, stiffness, tau, rest_length,
                         reference_strain, tension_only, kink, beta_angle, gamma_angle, force,
                         monitor)
        return _largest(monitor)
    for b in numba.prange(blocks):
        lo, hi = b * n // blocks, (b + 1) * n // blocks   # (empty offset arrays stay empty)
        rod_forces_range(x, quat, v, W, pos[lo:hi], rot[lo:hi], oq[lo:hi], oR[lo:hi], series,
                         stiffness[lo:hi], tau[lo:hi], rest_length[lo:hi],
                         reference_strain[lo:hi], tension_only, kink, beta_angle, gamma_angle,
                         force[lo:hi], monitor[lo:hi])
    return _largest(monitor)


@numba.njit(cache=True)
def scatter_forces(force, pos_nodes, rot_nodes, offset_R, f_node, m_node):  # pragma: no cover
    """Subtract the element forces ``force`` (E, 12), in the element ends' frames, from the
    node forces ``f_node`` (N, 3) [N], global, and moments ``m_node`` (R, 3) [N m], body frame."""
    has_offset = offset_R.shape[0] > 0
    for e in range(pos_nodes.shape[0]):
        for s in range(2):
            a, r, c = pos_nodes[e, s], rot_nodes[e, s], 6 * s
            for k in range(3):
                f_node[a, k] -= force[e, c + k]
            if has_offset:  # back to the rotation node's frame: Q m_end
                for k in range(3):
                    m_node[r, k] -= (offset_R[e, s, k, 0] * force[e, c + 3]
                                     + offset_R[e, s, k, 1] * force[e, c + 4]
                                     + offset_R[e, s, k, 2] * force[e, c + 5])
            else:
                for k in range(3):
                    m_node[r, k] -= force[e, c + 3 + k]


# ---------------------------------------------------------------------------------------------
# tangents (also behind rodnet.kernels.cosserat_tangent_compiled.tangents)


@numba.njit(cache=True)
def _put_hat(scale, v, out, r, c):  # pragma: no cover - compiled
    """``out[r:r+3, c:c+3] = scale * hat(v)``."""
    out[r, c], out[r, c + 1], out[r, c + 2] = 0.0, -scale * v[2], scale * v[1]
    out[r + 1, c], out[r + 1, c + 1], out[r + 1, c + 2] = scale * v[2], 0.0, -scale * v[0]
    out[r + 2, c], out[r + 2, c + 1], out[r + 2, c + 2] = -scale * v[1], scale * v[0], 0.0


@numba.njit(cache=True)
def _add_hat(scale, v, out, r, c):  # pragma: no cover - compiled
    """``out[r:r+3, c:c+3] += scale * hat(v)``."""
    out[r, c + 1] -= scale * v[2]
    out[r, c + 2] += scale * v[1]
    out[r + 1, c] += scale * v[2]
    out[r + 1, c + 2] -= scale * v[0]
    out[r + 2, c] -= scale * v[1]
    out[r + 2, c + 1] += scale * v[0]


@numba.njit(cache=True)
def _put_product(scale, a, b, out, r, c):  # pragma: no cover - compiled
    """``out[r:r+3, c:c+3] = scale * a @ b`` for 3 x 3 ``a``, ``b``."""
    for i in range(3):
        for j in range(3):
            out[r + i, c + j] = scale * (a[i, 0] * b[0, j] + a[i, 1] * b[1, j] + a[i, 2] * b[2, j])


@numba.njit(cache=True)
def _matmul(a, b, out):  # pragma: no cover - compiled
    for i in range(a.shape[0]):
        for j in range(b.shape[1]):
            s = 0.0
            for k in range(a.shape[1]):
                s += a[i, k] * b[k, j]
            out[i, j] = s


@numba.njit(cache=True)
def _dexp_inv_derivative(psi, w, gamma, gamma_d, out):  # pragma: no cover - compiled
    """``d(T^-1 w)/dpsi``, as :func:`rodnet.kernels.so3.dexp_inv_derivative`."""
    c0 = psi[1] * w[2] - psi[2] * w[1]
    c1 = psi[2] * w[0] - psi[0] * w[2]
    c2 = psi[0] * w[1] - psi[1] * w[0]
    a = (gamma_d * (psi[1] * c2 - psi[2] * c1) - 2.0 * gamma * w[0],
         gamma_d * (psi[2] * c0 - psi[0] * c2) - 2.0 * gamma * w[1],
         gamma_d * (psi[0] * c1 - psi[1] * c0) - 2.0 * gamma * w[2])
    pw = psi[0] * w[0] + psi[1] * w[1] + psi[2] * w[2]
    for i in range(3):
        for j in range(3):
            out[i, j] = a[i] * psi[j] + gamma * psi[i] * w[j]
        out[i, i] += gamma * pw
    _add_hat(-0.5, w, out, 0, 0)


@numba.njit(cache=True)
def _midpoint_derivative(psi, w, beta, beta_d, out):  # pragma: no cover - compiled
    """``d(P2 w)/dpsi``, as :func:`rodnet.kernels.cosserat_tangent.midpoint_derivative`."""
    c = (beta_d * (psi[1] * w[2] - psi[2] * w[1]), beta_d * (psi[2] * w[0] - psi[0] * w[2]),
         beta_d * (psi[0] * w[1] - psi[1] * w[0]))
    for i in range(3):
        for j in range(3):
            out[i, j] = c[i] * psi[j]
    _add_hat(-beta, w, out, 0, 0)


@numba.njit(cache=True)
def tangents_kernel(psi, R_m, g, coefficients, constitutive, velocity9, inv_le, inv_h,
                     stiffness_out, damping_out):  # pragma: no cover - compiled
    """Per element: ``K9 = B9^T (D B9 + D_v U9 L9) / Le + Q9 L9``, ``C9 = B9^T D_v B9 / Le``.

    ``coefficients`` (n, 4) = ``[beta, beta'/phi, gamma, gamma'/phi]``; ``constitutive`` (n, 18) =
    ``[stress, modulus, viscous_modulus]``. With ``inv_h > 0`` the strain rates are those of an
    implicit step, ``(eps - eps_ref) inv_h`` (C53): they move with the strains, so
    ``K9 = B9^T (D + inv_h D_v) B9 / Le + Q9 L9`` and ``C9 = 0``.
    """
    # scratch reused by every element; blocks that are never written stay zero
    S, A, P2, G = np.zeros((3, 3)), np.zeros((3, 3)), np.zeros((3, 3)), np.zeros((3, 3))
    hat_N, D_M, D_dW = np.zeros((3, 3)), np.zeros((3, 3)), np.zeros((3, 3))
    E_h, E_dW = np.zeros((3, 3)), np.zeros((3, 3))
    B9, U9, G_u, Z9 = np.zeros((6, 9)), np.zeros((6, 9)), np.zeros((6, 9)), np.zeros((6, 9))
    L9, Q9, K9, C9 = np.zeros((9, 9)), np.zeros((9, 9)), np.zeros((9, 9)), np.zeros((9, 9))
    N, M, h, dW = np.zeros(3), np.zeros(3), np.zeros(3), np.zeros(3)
    Rv, z = np.zeros(3), np.zeros(3)
    blocks, signs = (0, 3, 0, 6), (-1.0, 1.0, 1.0, 1.0)
    for e in range(psi.shape[0]):
        p, R = psi[e], R_m[e]
        beta, beta_d = coefficients[e, 0], coefficients[e, 1]
        gamma, gamma_d = coefficients[e, 2], coefficients[e, 3]
        # B9 = [[R^T, G P2^T, G P2], [0, -A^T, A]] and L9 = [[0, P2^T, P2], B9] (strain_operators)
        _put_hat(1.0, p, S, 0, 0)
        _matmul(S, S, A)
        for i in range(3):
            for j in range(3):
                A[i, j] = 0.5 * S[i, j] + gamma * A[i, j]
                P2[i, j] = beta * S[i, j]
            A[i, i] += 1.0
            P2[i, i] += 0.5
        _put_hat(1.0, g[e], G, 0, 0)
        for i in range(3):
            for j in range(3):
                B9[i, j] = R[j, i]
                B9[i, 3 + j] = G[i, 0] * P2[j, 0] + G[i, 1] * P2[j, 1] + G[i, 2] * P2[j, 2]
                B9[i, 6 + j] = G[i, 0] * P2[0, j] + G[i, 1] * P2[1, j] + G[i, 2] * P2[2, j]
                B9[3 + i, 3 + j] = -A[j, i]
                B9[3 + i, 6 + j] = A[i, j]
                L9[i, 3 + j] = P2[j, i]
                L9[i, 6 + j] = P2[i, j]
        for i in range(6):
            for j in range(9):
                L9[3 + i, j] = B9[i, j]
        # without viscosity (D_v = 0) the velocity terms (U9) and the damping tangent vanish
        viscous = False
        for k in range(6):
            if constitutive[e, 12 + k] != 0.0 and inv_h == 0.0:
                viscous = True
        # derivatives of B9 at fixed stress (Q9) and fixed velocity (U9) (geometric_factors)
        for k in range(3):
            N[k], M[k] = constitutive[e, k], constitutive[e, 3 + k]
            dW[k] = velocity9[e, 6 + k] - velocity9[e, 3 + k]
        h[0] = N[1] * g[e, 2] - N[2] * g[e, 1]
        h[1] = N[2] * g[e, 0] - N[0] * g[e, 2]
        h[2] = N[0] * g[e, 1] - N[1] * g[e, 0]
        _dexp_inv_derivative(p, M, gamma, gamma_d, D_M)
        _midpoint_derivative(p, h, beta, beta_d, E_h)
        _put_hat(1.0, N, hat_N, 0, 0)
        _put_product(-1.0, R, hat_N, Q9, 0, 0)
        _put_product(1.0, P2, hat_N, Q9, 3, 3)
        for i in range(3):
            for j in range(3):
                Q9[6 + i, 3 + j] = hat_N[i, j] - Q9[3 + i, 3 + j]
                Q9[3 + i, 6 + j] = E_h[i, j] - D_M[i, j]
                Q9[6 + i, 6 + j] = D_M[i, j] - E_h[i, j]
        _add_hat(1.0, M, Q9, 6, 6)
        if viscous:
            _dexp_inv_derivative(p, dW, gamma, gamma_d, D_dW)
            _midpoint_derivative(p, dW, beta, beta_d, E_dW)
            for k in range(3):
                Rv[k] = (R[0, k] * velocity9[e, 0] + R[1, k] * velocity9[e, 1]
                         + R[2, k] * velocity9[e, 2])
                z[k] = 0.0
                for j in range(3):
                    z[k] += P2[j, k] * velocity9[e, 3 + j] + P2[k, j] * velocity9[e, 6 + j]
            _put_hat(1.0, Rv, U9, 0, 0)
            _put_hat(-1.0, z, U9, 0, 3)
            _put_product(1.0, G, E_dW, U9, 0, 6)
            for i in range(3):
                for j in range(3):
                    U9[3 + i, 6 + j] = D_dW[i, j]
            _add_hat(-1.0, velocity9[e, 3:6], U9, 3, 6)
            _matmul(U9, L9, G_u)
        # K9 = B9^T Z9 + Q9 L9 with Z9 = (D B9 + D_v U9 L9) / Le;  C9 = B9^T D_v B9 / Le
        for i in range(6):
            a, b = constitutive[e, 6 + i] * inv_le[e], constitutive[e, 12 + i] * inv_le[e]
            a += inv_h * b   # 0 unless the rates are a step's
            for j in range(9):
                Z9[i, j] = a * B9[i, j] + b * G_u[i, j] if viscous else a * B9[i, j]
        # the rotation stop (C52), k_s = GA2 Le: Z9[3:] += H_s B9[3:], with
        # H_s = k_s [(1 - phi_s / phi) I + (phi_s / phi) n n^T]; its moment is in M already
        phi = np.sqrt(p[0] * p[0] + p[1] * p[1] + p[2] * p[2])
        if phi > ROTATION_STOP:
            k_s = constitutive[e, 7] / inv_le[e]
            ratio = ROTATION_STOP / phi
            for i in range(3):
                for k in range(3):
                    h_ik = k_s * ratio * p[i] * p[k] / (phi * phi)
                    if i == k:
                        h_ik += k_s * (1.0 - ratio)
                    for j in range(9):
                        Z9[3 + i, j] += h_ik * B9[3 + k, j]
        _matmul(Q9, L9, K9)
        for i in range(9):
            for j in range(9):
                s = 0.0
                for k in range(6):
                    s += B9[k, i] * Z9[k, j]
                K9[i, j] += s
                c = 0.0
                if viscous:
                    for k in range(6):
                        c += B9[k, i] * constitutive[e, 12 + k] * B9[k, j]
                C9[i, j] = c * inv_le[e]
        # expand to the element DOF (expand_matrix)
        for bi in range(4):
            for bj in range(4):
                sign = signs[bi] * signs[bj]
                for i in range(3):
                    for j in range(3):
                        r, c = blocks[bi] + i, blocks[bj] + j
                        stiffness_out[e, 3 * bi + i, 3 * bj + j] = sign * K9[r, c]
                        damping_out[e, 3 * bi + i, 3 * bj + j] = sign * C9[r, c]
