"""Compiled assembly of the Cosserat element tangents: one loop over elements, scratch reused.

The same equations as :func:`rodnet.kernels.cosserat_tangent.tangents` (``elements/cosserat/
FORMULATION.md`` §Linearisation, §Tangent), written per element: the NumPy path spends most of its
time on many small (n, 3, 3) operations, which a loop keeps in cache. Work is on the chord-reduced
DOF ``[dd, dtheta1, dtheta2]``; blocks are expanded to the 12 element DOF on output.
"""

from __future__ import annotations

import numba
import numpy as np

from rodnet.kernels.cosserat_strain import midpoint_coefficient
from rodnet.kernels.so3 import FloatArray, dexp_inv_coefficient


def tangents(
    # Kinematics in:
    psi: FloatArray, R_m: FloatArray, g: FloatArray,
    # Constitutive state in:
    stress: FloatArray, modulus: FloatArray, viscous_modulus: FloatArray,
    # State and model in:
    velocity9: FloatArray, rest_length: FloatArray,
) -> tuple[FloatArray, FloatArray]:
    """Stiffness and damping tangents (n, 12, 12); arguments as in the NumPy path."""
    n = psi.shape[0]
    phi = np.linalg.norm(psi, axis=1)
    coefficients = np.stack([*midpoint_coefficient(phi), *dexp_inv_coefficient(phi)], axis=1)
    stiffness_out, damping_out = np.empty((n, 12, 12)), np.empty((n, 12, 12))
    constitutive = np.concatenate([stress, modulus, viscous_modulus], axis=1)
    # contiguous inputs keep to one compiled specialisation
    _tangents_kernel(np.ascontiguousarray(psi), np.ascontiguousarray(R_m), np.ascontiguousarray(g),
                     coefficients, constitutive, np.ascontiguousarray(velocity9), 1.0 / rest_length,
                     stiffness_out, damping_out)
    return stiffness_out, damping_out


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
def _tangents_kernel(psi, R_m, g, coefficients, constitutive, velocity9, inv_le,
                     stiffness_out, damping_out):  # pragma: no cover - compiled
    """Per element: ``K9 = B9^T (D B9 + D_v U9 L9) / Le + Q9 L9``, ``C9 = B9^T D_v B9 / Le``.

    ``coefficients`` (n, 4) = ``[beta, beta'/phi, gamma, gamma'/phi]``; ``constitutive`` (n, 18) =
    ``[stress, modulus, viscous_modulus]``.
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
        # derivatives of B9 at fixed stress (Q9) and fixed velocity (U9) (geometric_factors)
        for k in range(3):
            N[k], M[k] = constitutive[e, k], constitutive[e, 3 + k]
            dW[k] = velocity9[e, 6 + k] - velocity9[e, 3 + k]
        h[0] = N[1] * g[e, 2] - N[2] * g[e, 1]
        h[1] = N[2] * g[e, 0] - N[0] * g[e, 2]
        h[2] = N[0] * g[e, 1] - N[1] * g[e, 0]
        _dexp_inv_derivative(p, M, gamma, gamma_d, D_M)
        _dexp_inv_derivative(p, dW, gamma, gamma_d, D_dW)
        _midpoint_derivative(p, h, beta, beta_d, E_h)
        _midpoint_derivative(p, dW, beta, beta_d, E_dW)
        _put_hat(1.0, N, hat_N, 0, 0)
        _put_product(-1.0, R, hat_N, Q9, 0, 0)
        _put_product(1.0, P2, hat_N, Q9, 3, 3)
        for i in range(3):
            for j in range(3):
                Q9[6 + i, 3 + j] = hat_N[i, j] - Q9[3 + i, 3 + j]
                Q9[3 + i, 6 + j] = E_h[i, j] - D_M[i, j]
                Q9[6 + i, 6 + j] = D_M[i, j] - E_h[i, j]
        _add_hat(1.0, M, Q9, 6, 6)
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
        # K9 = B9^T Z9 + Q9 L9 with Z9 = (D B9 + D_v U9 L9) / Le;  C9 = B9^T D_v B9 / Le
        _matmul(U9, L9, G_u)
        for i in range(6):
            a, b = constitutive[e, 6 + i] * inv_le[e], constitutive[e, 12 + i] * inv_le[e]
            for j in range(9):
                Z9[i, j] = a * B9[i, j] + b * G_u[i, j]
        _matmul(Q9, L9, K9)
        for i in range(9):
            for j in range(9):
                s, c = 0.0, 0.0
                for k in range(6):
                    s += B9[k, i] * Z9[k, j]
                    c += B9[k, i] * constitutive[e, 12 + k] * B9[k, j]
                K9[i, j] += s
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
