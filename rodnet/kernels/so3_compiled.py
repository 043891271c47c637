"""Compiled versions of the per-node rotation updates used every Newton iteration.

Same formulas as :mod:`rodnet.kernels.so3` (``retract``, ``dexp``) and the gyroscopic term of
:class:`~rodnet.models.cosserat.model.CosseratModel`; ``tests/kernels/test_so3.py`` checks
``retract`` and ``gyroscopic`` against the NumPy versions. ``dexp`` only enters Newton's iteration
matrix, where its last bits do not matter.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from rodnet.kernels import so3


@numba.njit(cache=True)
def retract(q, dtheta):  # pragma: no cover - compiled
    """``q ⊗ exp_q(dtheta / 2)``, renormalised: (n, 4), (n, 3) -> (n, 4)."""
    out = np.empty_like(q)
    for i in range(q.shape[0]):
        x, y, z = dtheta[i, 0], dtheta[i, 1], dtheta[i, 2]
        angle = math.sqrt(x * x + y * y + z * z)
        half = 0.5 * angle
        c = math.cos(half)
        s = 0.5 - angle * angle / 48.0 if angle < 1e-4 else math.sin(half) / angle
        bw, bx, by, bz = c, s * x, s * y, s * z
        aw, ax, ay, az = q[i, 0], q[i, 1], q[i, 2], q[i, 3]
        w = aw * bw - ax * bx - ay * by - az * bz
        xx = aw * bx + ax * bw + ay * bz - az * by
        yy = aw * by - ax * bz + ay * bw + az * bx
        zz = aw * bz + ax * by - ay * bx + az * bw
        norm = math.sqrt(w * w + xx * xx + yy * yy + zz * zz)
        out[i, 0], out[i, 1], out[i, 2], out[i, 3] = w / norm, xx / norm, yy / norm, zz / norm
    return out


@numba.njit(cache=True)
def gyroscopic(W, J):  # pragma: no cover - compiled
    """``W x (J W)`` (n, 3) and its derivative ``hat(W) J - hat(J W)`` (n, 3, 3), J diagonal (n, 3)."""
    n = W.shape[0]
    f = np.empty((n, 3))
    d = np.zeros((n, 3, 3))
    for i in range(n):
        w0, w1, w2 = W[i, 0], W[i, 1], W[i, 2]
        j0, j1, j2 = J[i, 0] * w0, J[i, 1] * w1, J[i, 2] * w2
        f[i, 0] = w1 * j2 - w2 * j1
        f[i, 1] = w2 * j0 - w0 * j2
        f[i, 2] = w0 * j1 - w1 * j0
        # hat(W) diag(J): column k of hat(W) scaled by J_k; minus hat(J W)
        d[i, 0, 1] = -w2 * J[i, 1] + j2
        d[i, 0, 2] = w1 * J[i, 2] - j1
        d[i, 1, 0] = w2 * J[i, 0] - j2
        d[i, 1, 2] = -w0 * J[i, 2] + j0
        d[i, 2, 0] = -w1 * J[i, 0] + j1
        d[i, 2, 1] = w0 * J[i, 1] - j0
    return f, d


def dexp(psi: np.ndarray) -> np.ndarray:
    """Tangent operators ``T(psi)`` (n, 3, 3) of rotation vectors ``psi`` (n, 3), as
    :func:`rodnet.kernels.so3.dexp`."""
    return _dexp_kernel(np.ascontiguousarray(psi, dtype=np.float64), so3.DEXP_SERIES_ANGLE)


@numba.njit(cache=True)
def _dexp_kernel(psi, series_angle):  # pragma: no cover - compiled
    """``I - (1 - cos phi)/phi^2 hat(psi) + (phi - sin phi)/phi^3 hat(psi)^2`` per row, with
    ``hat(psi)^2 = psi psi^T - phi^2 I`` and the Taylor series of the last coefficient below
    ``series_angle``."""
    n = psi.shape[0]
    out = np.empty((n, 3, 3))
    for i in range(n):
        x, y, z = psi[i, 0], psi[i, 1], psi[i, 2]
        p2 = x * x + y * y + z * z
        phi = math.sqrt(p2)
        # (1 - cos phi)/phi^2 = sinc(phi/2)^2 / 2, free of cancellation
        half = 0.5 * phi
        sinc_half = math.sin(half) / half if half != 0.0 else 1.0
        b = 0.5 * sinc_half * sinc_half
        if phi < series_angle:
            c = 1 / 6 - p2 * (1 / 120 - p2 * (1 / 5040 - p2 * (1 / 362880 - p2 / 39916800)))
        else:
            c = (phi - math.sin(phi)) / (phi * phi * phi)
        diagonal = 1.0 - c * p2
        out[i, 0, 0] = diagonal + c * x * x
        out[i, 1, 1] = diagonal + c * y * y
        out[i, 2, 2] = diagonal + c * z * z
        out[i, 0, 1] = b * z + c * x * y
        out[i, 1, 0] = -b * z + c * x * y
        out[i, 0, 2] = -b * y + c * x * z
        out[i, 2, 0] = b * y + c * x * z
        out[i, 1, 2] = b * x + c * y * z
        out[i, 2, 1] = -b * x + c * y * z
    return out
