"""Cosserat element tangents in NumPy, with the derivatives of ``B`` at fixed stress or velocity.

Formulation card: ``elements/cosserat/FORMULATION.md`` (§Linearisation, §Tangent). Work is on the
chord-reduced DOF ``[dd, dtheta1, dtheta2]`` of :mod:`rodnet.kernels.cosserat_strain`. Both parts
come as factors of ``L9 = [L_m; B9]`` (n, 9, 9), whose rows are the variations of, in order, the
midpoint triad ``dphi_m``, the chord in that triad ``dg = Le dGamma`` and ``dpsi = Le dK``;
``L_m = [0, P2^T, P2]``.
"""

from __future__ import annotations

import numpy as np

from rodnet.kernels.cosserat_strain import (expand_matrix, midpoint_coefficient, rotation_stop,
                                            strain_operators)
from rodnet.kernels.so3 import FloatArray, dexp_inv_derivative, hat


def midpoint_derivative(psi: FloatArray, w: FloatArray) -> FloatArray:
    """``d (P2 w) / d psi = d (beta(|psi|) psi x w) / d psi`` at fixed ``w``.

    (..., 3), (..., 3) -> (..., 3, 3): ``(beta'/phi) (psi x w) psi^T - beta hat(w)``.
    """
    beta, beta_d = midpoint_coefficient(np.linalg.norm(psi, axis=-1))
    out = np.einsum("...i,...j->...ij", beta_d[..., None] * np.cross(psi, w), psi)
    out -= hat(beta[..., None] * w)
    return out


def kinematic_variations(P2: FloatArray, B9: FloatArray) -> FloatArray:
    """``L9 = [L_m; B9]`` (n, 9, 9): ``[dphi_m; dg; dpsi] = L9 @ [dd, dtheta1, dtheta2]``."""
    L9 = np.zeros((B9.shape[0], 9, 9))
    L9[:, :3, 3:6] = np.swapaxes(P2, 1, 2)
    L9[:, :3, 6:9] = P2
    L9[:, 3:] = B9
    return L9


def geometric_factors(psi: FloatArray, R_m: FloatArray, g: FloatArray, P2: FloatArray,
                      stress: FloatArray, velocity9: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Factors of the geometric tangent terms (§Tangent).

    Parameters
    ----------
    psi, R_m, g : (n, 3), (n, 3, 3), (n, 3)
        From :func:`rodnet.kernels.cosserat_strain.kinematics`.
    P2 : (n, 3, 3)
        From :func:`rodnet.kernels.cosserat_strain.strain_operators`.
    stress : (n, 6)
        ``[N, M]``, held fixed.
    velocity9 : (n, 9)
        ``[v2 - v1, W1, W2]``, held fixed.

    Returns
    -------
    Q9 : (n, 9, 9)
        ``d(B9^T stress)/d r = Q9 @ L9``. With ``f9 = B9^T [N; M]``: ``f_d = R_m N``,
        ``f_theta1 = P2 (N x g) - A M``, ``f_theta2 = P2^T (N x g) + A^T M``, ``A = T(psi)^-1``.
    U9 : (n, 6, 9)
        ``d(B9 @ velocity9)/d r = U9 @ L9``, where
        ``B9 @ u = [R_m^T v_d + g x (P2^T W1 + P2 W2); A W2 - A^T W1]``.
    """
    N, M = stress[:, :3], stress[:, 3:]
    v_d, W1, W2 = velocity9[:, 0:3], velocity9[:, 3:6], velocity9[:, 6:9]
    dW = W2 - W1
    h = np.cross(N, g)
    # T^-1(-psi) w = T^-1(psi)^T w, so d(A^T w)/dpsi = hat(w) + d(A w)/dpsi, and both derivatives
    # are linear in w: two stacked evaluations serve all four moment and velocity terms.
    D_M, D_dW = np.moveaxis(dexp_inv_derivative(psi[:, None], np.stack([M, dW], axis=1)), 1, 0)
    E_h, E_dW = np.moveaxis(midpoint_derivative(psi[:, None], np.stack([h, dW], axis=1)), 1, 0)

    hat_N = hat(N)
    P2_hat_N = P2 @ hat_N
    Q9 = np.zeros((psi.shape[0], 9, 9))
    Q9[:, 0:3, 0:3] = -R_m @ hat_N
    Q9[:, 3:6, 3:6] = P2_hat_N
    Q9[:, 6:9, 3:6] = hat_N - P2_hat_N          # P2^T hat(N), as P2 + P2^T = I
    Q9[:, 3:6, 6:9] = E_h - D_M
    Q9[:, 6:9, 6:9] = hat(M) + D_M - E_h

    z = np.einsum("nji,nj->ni", P2, W1) + np.einsum("nij,nj->ni", P2, W2)
    U9 = np.zeros((psi.shape[0], 6, 9))
    U9[:, :3, 0:3] = hat(np.einsum("nji,nj->ni", R_m, v_d))
    U9[:, :3, 3:6] = -hat(z)
    U9[:, :3, 6:9] = hat(g) @ E_dW
    U9[:, 3:, 6:9] = D_dW - hat(W1)
    return Q9, U9


def tangents(
    # Kinematics in:
    psi: FloatArray, R_m: FloatArray, g: FloatArray,
    # Constitutive state in:
    stress: FloatArray, modulus: FloatArray, viscous_modulus: FloatArray,
    # State and model in:
    velocity9: FloatArray, rest_length: FloatArray,
) -> tuple[FloatArray, FloatArray]:
    """Stiffness and damping tangents of the element, NumPy path (§Tangent).

    Parameters
    ----------
    psi, R_m, g : (n, 3), (n, 3, 3), (n, 3)
        From :func:`rodnet.kernels.cosserat_strain.kinematics`.
    stress, modulus, viscous_modulus : (n, 6)
        From :func:`rodnet.kernels.cosserat.stress_resultants_and_moduli`.
    velocity9 : (n, 9)
        ``[v2 - v1, W1, W2]``.
    rest_length : (n,)

    Returns
    -------
    stiffness_tangent, damping_tangent : (n, 12, 12)
        ``K = S K9 S^T`` with ``K9 = B9^T (D B9 + D_v U9 L9) / Le + Q9 L9`` (plus
        ``B9_psi^T H_s B9_psi`` of the rotation stop (C52); ``stress`` includes its moment) and
        ``C = S (B9^T D_v B9 / Le) S^T``, ``S`` of :func:`rodnet.kernels.cosserat_strain.expand_vector`.
    """
    B9, P2 = strain_operators(psi, R_m, g)
    Q9, U9 = geometric_factors(psi, R_m, g, P2, stress, velocity9)
    L9 = kinematic_variations(P2, B9)
    inv_le = 1.0 / rest_length[:, None, None]
    D, D_v = modulus[:, :, None] * inv_le, viscous_modulus[:, :, None] * inv_le
    # K9 as one product [B9^T, Q9] @ [Z9; L9] with Z9 = (D B9 + D_v U9 L9) / Le
    right = np.concatenate([D * B9 + D_v * (U9 @ L9), L9], axis=1)
    # the rotation stop (C52): its moment is in ``stress``, its derivative acts on dpsi = B9[3:] r
    right[:, 3:6] += rotation_stop(psi, rest_length, modulus[:, 1])[2] @ B9[:, 3:6]
    left = np.concatenate([np.swapaxes(B9, 1, 2), Q9], axis=2)
    return expand_matrix(left @ right), expand_matrix(left[:, :, :6] @ (D_v * B9))
