"""Rotations: unit quaternions, rotation vectors and the tangent maps of SO(3).

Conventions (``elements/cosserat/FORMULATION.md`` §Rotations): quaternions are unit and ordered
(w, x, y, z); ``R(q)`` maps body components to global ones; increments are body-frame rotation
vectors, ``R <- R exp(hat(dtheta))``. Every function is vectorised over leading axes: a
quaternion argument is ``(..., 4)``, a vector ``(..., 3)``, a matrix ``(..., 3, 3)``.

The tangent operator is the right-trivialised one (§Rotations, linearisation of the logarithm):
``exp(psi + dpsi) = exp(psi) exp(hat(T(psi) dpsi)) + O(dpsi^2)``. The left-trivialised operator is
``T(-psi)``; ``T(psi)^T = T(-psi)``.
"""

from __future__ import annotations

import numpy as np
from numpy.polynomial.polynomial import polyval
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]

# Below this angle (phi - sin phi)/phi^3 is taken from its series: the closed form loses digits to
# cancellation, the series through phi^8 is exact to round-off (next term < 1e-20 relative).
DEXP_SERIES_ANGLE = 0.1


def hat(v: FloatArray) -> FloatArray:
    """Skew matrix with ``hat(v) @ w = v x w``: (..., 3) -> (..., 3, 3)."""
    out = np.zeros(v.shape + (3,))
    out[..., 0, 1], out[..., 0, 2] = -v[..., 2], v[..., 1]
    out[..., 1, 0], out[..., 1, 2] = v[..., 2], -v[..., 0]
    out[..., 2, 0], out[..., 2, 1] = -v[..., 1], v[..., 0]
    return out


def quat_multiply(p: FloatArray, q: FloatArray) -> FloatArray:
    """Hamilton product ``p ⊗ q`` (rotation ``R(p) R(q)``): (..., 4), (..., 4) -> (..., 4)."""
    pw, px, py, pz = p[..., 0], p[..., 1], p[..., 2], p[..., 3]
    qw, qx, qy, qz = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    return np.stack([pw * qw - px * qx - py * qy - pz * qz,
                     pw * qx + px * qw + py * qz - pz * qy,
                     pw * qy - px * qz + py * qw + pz * qx,
                     pw * qz + px * qy - py * qx + pz * qw], axis=-1)


def quat_conjugate(q: FloatArray) -> FloatArray:
    """Conjugate (inverse of a unit quaternion): (..., 4) -> (..., 4)."""
    return q * np.array([1.0, -1.0, -1.0, -1.0])


def quat_normalize(q: FloatArray) -> FloatArray:
    """Unit quaternion along ``q``: (..., 4) -> (..., 4)."""
    return q / np.linalg.norm(q, axis=-1, keepdims=True)


def quat_to_matrix(q: FloatArray) -> FloatArray:
    """Rotation matrix of a unit quaternion: (..., 4) -> (..., 3, 3); columns are the body axes."""
    w, x, y, z = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    out = np.empty(q.shape[:-1] + (3, 3))
    out[..., 0, 0] = 1.0 - 2.0 * (y * y + z * z)
    out[..., 0, 1] = 2.0 * (x * y - w * z)
    out[..., 0, 2] = 2.0 * (x * z + w * y)
    out[..., 1, 0] = 2.0 * (x * y + w * z)
    out[..., 1, 1] = 1.0 - 2.0 * (x * x + z * z)
    out[..., 1, 2] = 2.0 * (y * z - w * x)
    out[..., 2, 0] = 2.0 * (x * z - w * y)
    out[..., 2, 1] = 2.0 * (y * z + w * x)
    out[..., 2, 2] = 1.0 - 2.0 * (x * x + y * y)
    return out


def quat_from_matrix(R: FloatArray) -> FloatArray:
    """Unit quaternion (w >= 0) of a rotation matrix: (..., 3, 3) -> (..., 4).

    Shepperd's method: the largest of ``4w^2, 4x^2, 4y^2, 4z^2`` is taken from the diagonal and
    the other components from off-diagonal sums, so no branch divides by a small number.
    """
    t = np.trace(R, axis1=-2, axis2=-1)
    d0, d1, d2 = R[..., 0, 0], R[..., 1, 1], R[..., 2, 2]
    s21, s02, s10 = (R[..., 2, 1] - R[..., 1, 2], R[..., 0, 2] - R[..., 2, 0],
                     R[..., 1, 0] - R[..., 0, 1])
    a01, a02, a12 = (R[..., 0, 1] + R[..., 1, 0], R[..., 0, 2] + R[..., 2, 0],
                     R[..., 1, 2] + R[..., 2, 1])
    candidates = np.stack([
        np.stack([1.0 + t, s21, s02, s10], axis=-1),
        np.stack([s21, 1.0 + d0 - d1 - d2, a01, a02], axis=-1),
        np.stack([s02, a01, 1.0 - d0 + d1 - d2, a12], axis=-1),
        np.stack([s10, a02, a12, 1.0 - d0 - d1 + d2], axis=-1),
    ], axis=-2)
    pick = np.argmax(np.stack([t, d0, d1, d2], axis=-1), axis=-1)
    q = np.take_along_axis(candidates, pick[..., None, None], axis=-2)[..., 0, :]
    q = quat_normalize(q)
    return np.where(q[..., :1] < 0.0, -q, q)


def quat_from_rotvec(theta: FloatArray) -> FloatArray:
    """Exponential map: quaternion of the rotation vector ``theta``: (..., 3) -> (..., 4)."""
    phi = np.linalg.norm(theta, axis=-1, keepdims=True)
    # sin(phi/2)/phi = sinc(phi/2)/2 has no cancellation and is exact at 0
    return np.concatenate([np.cos(0.5 * phi), 0.5 * np.sinc(phi / (2.0 * np.pi)) * theta], axis=-1)


def rotvec_from_quat(q: FloatArray, shortest: bool = True) -> FloatArray:
    """Logarithm: rotation vector of a quaternion: (..., 4) -> (..., 3).

    ``shortest``: the sign of ``q`` is chosen with ``w >= 0``, the shorter of the two equivalent
    rotations, angle in [0, pi]. Otherwise the logarithm on the double cover: ``q`` and ``-q``
    give rotation vectors of angles ``a`` and ``2 pi - a`` about opposite axes, angle in
    [0, 2 pi]. ``2 atan2(|v|, w)`` is accurate at every angle, including 0 and pi. ``q`` need not
    be unit.
    """
    if shortest:
        q = np.where(q[..., :1] < 0.0, -q, q)
    w, v = q[..., :1], q[..., 1:]
    s = np.linalg.norm(v, axis=-1, keepdims=True)
    small = s < 1e-6 * w
    s_safe = np.where(small, 1.0, s)
    w_safe = np.where(small, w, 1.0)
    t2 = (s / w_safe) ** 2
    factor = np.where(small, 2.0 / w_safe * (1.0 - t2 / 3.0), 2.0 * np.arctan2(s, w) / s_safe)
    return factor * v


def rotvec_from_matrix(R: FloatArray) -> FloatArray:
    """Logarithm of a rotation matrix, angle in [0, pi]: (..., 3, 3) -> (..., 3)."""
    return rotvec_from_quat(quat_from_matrix(R))


def _rodrigues_coefficients(phi: FloatArray) -> tuple[FloatArray, FloatArray]:
    """``sin(phi)/phi`` and ``(1 - cos(phi))/phi^2``, both free of cancellation."""
    sinc_half = np.sinc(phi / (2.0 * np.pi))
    return np.sinc(phi / np.pi), 0.5 * sinc_half * sinc_half


def so3_exp(theta: FloatArray) -> FloatArray:
    """Rodrigues' formula ``exp(hat(theta))``: (..., 3) -> (..., 3, 3).

    The coefficients are written with ``sinc``, exact at 0 and free of cancellation at small
    angles, which is what a Taylor branch would otherwise provide.
    """
    phi = np.linalg.norm(theta, axis=-1)
    a, b = _rodrigues_coefficients(phi)
    S = hat(theta)
    return np.eye(3) + a[..., None, None] * S + b[..., None, None] * (S @ S)


def _dexp_coefficient(phi: FloatArray) -> FloatArray:
    """``(phi - sin phi)/phi^3``."""
    p2 = phi * phi
    series = 1 / 6 - p2 * (1 / 120 - p2 * (1 / 5040 - p2 * (1 / 362880 - p2 / 39916800)))
    small = phi < DEXP_SERIES_ANGLE
    p = np.where(small, 1.0, phi)
    return np.where(small, series, (p - np.sin(p)) / (p * p * p))


# Taylor coefficients in phi^2 of gamma and gamma'/phi (exact rationals, through phi^14)
GAMMA_SERIES = np.array([1 / 12, 1 / 720, 1 / 30240, 1 / 1209600, 1 / 47900160,
                          691 / 1307674368000, 1 / 74724249600, 3617 / 10670622842880000])
GAMMA_D_SERIES = np.array([1 / 360, 1 / 7560, 1 / 201600, 1 / 5987520, 691 / 130767436800,
                            1 / 6227020800, 3617 / 762187345920000, 43867 / 319318388573184000])
# Below this angle the closed forms of gamma lose more digits to cancellation than the series
# (through phi^14) loses to truncation; at the switch both agree to ~1e-14 (gamma) and ~1e-12
# (gamma'/phi) relative.
GAMMA_SERIES_ANGLE = 0.5


def dexp_inv_coefficient(phi: FloatArray) -> tuple[FloatArray, FloatArray]:
    """``gamma = 1/phi^2 - cot(phi/2)/(2 phi)`` and ``gamma'(phi)/phi``: (...) -> (...), (...).

    ``gamma`` is the coefficient of ``hat(psi)^2`` in :func:`dexp_inv`, ``phi = |psi| < 2 pi``.
    """
    p2 = phi * phi
    small = phi < GAMMA_SERIES_ANGLE
    p = np.where(small, 1.0, phi)
    inv_p = 1.0 / p
    half_cot = 0.5 / np.tan(0.5 * p)
    sin_half = np.sin(0.5 * p)
    closed = inv_p * (inv_p - half_cot)
    closed_d = inv_p * inv_p * (inv_p * (half_cot - 2.0 * inv_p) + 0.25 / (sin_half * sin_half))
    return (np.where(small, polyval(p2, GAMMA_SERIES), closed),
            np.where(small, polyval(p2, GAMMA_D_SERIES), closed_d))


def dexp(psi: FloatArray) -> FloatArray:
    """Tangent operator ``T(psi) = I - (1-cos)/phi^2 hat(psi) + (phi-sin)/phi^3 hat(psi)^2``.

    (..., 3) -> (..., 3, 3); see the module docstring for the convention.
    """
    phi = np.linalg.norm(psi, axis=-1)
    S = hat(psi)
    b = _rodrigues_coefficients(phi)[1]
    return np.eye(3) - b[..., None, None] * S + _dexp_coefficient(phi)[..., None, None] * (S @ S)


def dexp_inv(psi: FloatArray) -> FloatArray:
    """Inverse tangent operator ``T(psi)^-1 = I + hat(psi)/2 + gamma(phi) hat(psi)^2``.

    (..., 3) -> (..., 3, 3); regular for ``|psi| < 2 pi``.
    """
    S = hat(psi)
    g = dexp_inv_coefficient(np.linalg.norm(psi, axis=-1))[0]
    return np.eye(3) + 0.5 * S + g[..., None, None] * (S @ S)


def dexp_inv_apply(psi: FloatArray, w: FloatArray) -> FloatArray:
    """``T(psi)^-1 w = w + psi x w / 2 + gamma psi x (psi x w)``: (..., 3), (..., 3) -> (..., 3).

    ``T(psi)^-T w`` is ``dexp_inv_apply(-psi, w)``.
    """
    g = dexp_inv_coefficient(np.linalg.norm(psi, axis=-1))[0]
    psi_w = np.cross(psi, w)
    return w + 0.5 * psi_w + g[..., None] * np.cross(psi, psi_w)


def dexp_inv_derivative(psi: FloatArray, w: FloatArray) -> FloatArray:
    """Derivative ``d (T(psi)^-1 w) / d psi`` at fixed ``w``: (..., 3), (..., 3) -> (..., 3, 3).

    With ``T^-1 w = w + psi x w / 2 + gamma (psi (psi.w) - phi^2 w)``, the derivative is
    ``-hat(w)/2 + (gamma'/phi) (psi x (psi x w)) psi^T + gamma ((psi.w) I + psi w^T - 2 w psi^T)``.
    """
    g, g_d = dexp_inv_coefficient(np.linalg.norm(psi, axis=-1))
    pw = np.einsum("...i,...i->...", psi, w)
    a = g_d[..., None] * np.cross(psi, np.cross(psi, w)) - 2.0 * g[..., None] * w
    out = np.einsum("...i,...j->...ij", a, psi)
    out += np.einsum("...i,...j->...ij", g[..., None] * psi, w)
    out -= 0.5 * hat(w)
    d = g * pw
    out[..., 0, 0] += d
    out[..., 1, 1] += d
    out[..., 2, 2] += d
    return out


def retract(q: FloatArray, dtheta: FloatArray) -> FloatArray:
    """Body-frame update ``q <- q ⊗ exp_q(dtheta/2)``, renormalised.

    (..., 4), (..., 3) -> (..., 4); the rotation becomes ``R(q) exp(hat(dtheta))``.
    """
    return quat_normalize(quat_multiply(q, quat_from_rotvec(dtheta)))
