"""Kinematics of the two-node Simo-Reissner element: strains and the strain-displacement matrix.

Formulation card: ``elements/cosserat/FORMULATION.md`` (§Kinematics, §Strains, §Linearisation).
Shapes: n = number of elements. Per element the node pair is stacked on axis 1:
positions ``x (n, 2, 3)``, unit quaternions ``q (n, 2, 4)`` (w, x, y, z). Element DOF order is
``[dx1, dtheta1, dx2, dtheta2]`` with body-frame rotation increments. Strains are packed
``(n, 6) = [Gamma (axial, shear 2, shear 3), K (twist, bend 2, bend 3)]``.
"""

from __future__ import annotations

import numpy as np
from numpy.polynomial.polynomial import polyval

from rodnet.kernels.so3 import (
    FloatArray, dexp_inv, dexp_inv_apply, hat, quat_conjugate, quat_from_rotvec, quat_multiply,
    quat_to_matrix, rotvec_from_quat,
)

# Taylor coefficients in phi^2 of beta and beta'/phi (exact rationals, through phi^14); the switch
# angle is chosen as for gamma in rodnet.kernels.so3.
BETA_SERIES = np.array([1 / 8, 1 / 384, 1 / 15360, 17 / 10321920, 31 / 743178240,
                         691 / 653996851200, 5461 / 204047017574400, 929569 / 1371195958099968000])
BETA_D_SERIES = np.array([1 / 192, 1 / 3840, 17 / 1720320, 31 / 92897280, 691 / 65399685120,
                           5461 / 17003918131200, 929569 / 97942568435712000,
                           3202291 / 11655165643849728000])
BETA_SERIES_ANGLE = 0.5

ROTATION_STOP = 5.0
"""The element relative rotation ``|psi|`` [rad] beyond which the rotation stop (C52) acts."""


def midpoint_coefficient(phi: FloatArray) -> tuple[FloatArray, FloatArray]:
    """``beta = tan(phi/4) / (2 phi)`` and ``beta'(phi)/phi``: (...) -> (...), (...).

    ``beta`` is the coefficient of the midpoint-triad variation (§Linearisation): with
    ``R_m = R1 exp(hat(psi/2))``, ``dphi_m = P2^T dtheta1 + P2 dtheta2``, ``P2 = I/2 + beta hat(psi)``.
    """
    p2 = phi * phi
    small = phi < BETA_SERIES_ANGLE
    p = np.where(small, 1.0, phi)
    t = np.tan(0.25 * p)
    closed = t / (2.0 * p)
    closed_d = ((1.0 + t * t) / (8.0 * p) - t / (2.0 * p * p)) / p
    return (np.where(small, polyval(p2, BETA_SERIES), closed),
            np.where(small, polyval(p2, BETA_D_SERIES), closed_d))


def kinematics(x: FloatArray, q: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Relative rotation, midpoint triad and the chord in that triad (§Kinematics).

    Parameters
    ----------
    x : (n, 2, 3)
        Node positions (global).
    q : (n, 2, 4)
        Node quaternions.

    Returns
    -------
    psi : (n, 3)
        ``log(conj(q1) q2)`` on the quaternion double cover, angle in [0, 2 pi) (C11): it
        follows the quaternions continuously past pi.
    R_m : (n, 3, 3)
        Midpoint triad ``R1 exp(hat(psi/2))``.
    g : (n, 3)
        ``R_m^T (x2 - x1)``, the chord in midpoint-triad components.
    """
    psi = rotvec_from_quat(quat_multiply(quat_conjugate(q[:, 0]), q[:, 1]), shortest=False)
    R_m = quat_to_matrix(quat_multiply(q[:, 0], quat_from_rotvec(0.5 * psi)))
    g = np.einsum("nji,nj->ni", R_m, x[:, 1] - x[:, 0])
    return psi, R_m, g


def rotation_stop(psi: FloatArray, rest_length: FloatArray,
                  shear_stiffness: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray]:
    """The rotation stop (C52): energy, moment and its derivative of each element.

    ``W_s = k_s (phi - phi_s)^2 / 2`` for ``phi = |psi| > phi_s`` (:data:`ROTATION_STOP`), with
    ``k_s = GA2 Le`` [N m]; 0 below.

    Parameters
    ----------
    psi : (n, 3)
        Element relative rotations [rad].
    rest_length, shear_stiffness : (n,)
        ``Le`` [m] and ``GA2`` [N].

    Returns
    -------
    energy : (n,)
        ``W_s`` [J].
    moment : (n, 3)
        ``dW_s / dpsi = k_s (phi - phi_s) psi / phi`` [N m], added to the bending and torsion
        moment ``M`` (it is parallel to ``psi``).
    hessian : (n, 3, 3)
        ``d moment / d psi = k_s [(1 - phi_s / phi) I + (phi_s / phi) n n^T]``, ``n = psi / phi``.
    """
    phi = np.linalg.norm(psi, axis=1)
    active = phi > ROTATION_STOP
    k = np.where(active, shear_stiffness * rest_length, 0.0)
    safe = np.where(active, phi, 1.0)
    excess = np.where(active, phi - ROTATION_STOP, 0.0)
    n = psi / safe[:, None]
    ratio = np.where(active, ROTATION_STOP / safe, 0.0)
    hessian = k[:, None, None] * ((1.0 - ratio)[:, None, None] * np.eye(3)
                                  + ratio[:, None, None] * n[:, :, None] * n[:, None, :])
    return 0.5 * k * excess**2, (k * excess)[:, None] * n, hessian


def reference_strains(rest_length: FloatArray, x: FloatArray, q: FloatArray) -> FloatArray:
    """Strains of the stress-free configuration, ``[R_m^T (x2 - x1), psi] / Le``: (n, 6).

    Parameters
    ----------
    rest_length : (n,)
        Element rest length ``Le``.
    x : (n, 2, 3), q : (n, 2, 4)
        Stress-free node positions and quaternions.
    """
    psi, _, g = kinematics(x, q)
    return np.concatenate([g, psi], axis=1) / rest_length[:, None]


def strains_from_kinematics(psi: FloatArray, g: FloatArray, rest_length: FloatArray,
                            reference_strain: FloatArray) -> FloatArray:
    """``[g / Le - Gamma0, psi / Le - K0]`` (§Strains): (n, 6)."""
    return np.concatenate([g, psi], axis=1) / rest_length[:, None] - reference_strain


def strains(rest_length: FloatArray, reference_strain: FloatArray, x: FloatArray,
            q: FloatArray) -> FloatArray:
    """Material strains ``[Gamma, K]`` measured from the stress-free state (§Strains).

    Parameters
    ----------
    rest_length : (n,)
        ``Le``.
    reference_strain : (n, 6)
        ``[Gamma0, K0]`` from :func:`reference_strains`.
    x : (n, 2, 3), q : (n, 2, 4)
        Node positions and quaternions.

    Returns
    -------
    (n, 6)
        ``[Gamma, K]``; component 0 is the axial strain, 3 the twist.
    """
    psi, _, g = kinematics(x, q)
    return strains_from_kinematics(psi, g, rest_length, reference_strain)


def reduce_velocity(velocity: FloatArray) -> FloatArray:
    """Element velocities ``[v1, W1, v2, W2]`` (n, 12) -> reduced ``[v2 - v1, W1, W2]`` (n, 9).

    The element sees the node positions only through the chord ``x2 - x1``, so its operators are
    built on the 9 reduced DOF ``[dd, dtheta1, dtheta2]`` and expanded to the 12 element DOF by
    :func:`expand_vector` and :func:`expand_matrix` (a node-1 translation acts as ``-dd``).
    """
    return np.concatenate(
        [velocity[:, 6:9] - velocity[:, 0:3], velocity[:, 3:6], velocity[:, 9:12]], axis=1)


def strain_rates_from_kinematics(psi: FloatArray, R_m: FloatArray, g: FloatArray,
                                 velocity9: FloatArray, rest_length: FloatArray) -> FloatArray:
    """Exact strain rates ``B u`` (§Strain rates): (n, 6).

    ``[R_m^T v_d + g x z, A W2 - A^T W1] / Le`` with ``z = P2^T W1 + P2 W2`` the midpoint-triad
    angular velocity and ``A = T(psi)^-1``; ``velocity9`` is ``[v2 - v1, W1, W2]`` (n, 9).
    """
    v_d, W1, W2 = velocity9[:, 0:3], velocity9[:, 3:6], velocity9[:, 6:9]
    beta = midpoint_coefficient(np.linalg.norm(psi, axis=1))[0]
    z = 0.5 * (W1 + W2) + beta[:, None] * np.cross(psi, W2 - W1)
    gamma_rate = np.einsum("nji,nj->ni", R_m, v_d) + np.cross(g, z)
    # A W2 - A^T W1 = A (W2 - W1) + psi x W1, as A - A^T = hat(psi)
    kappa_rate = dexp_inv_apply(psi, W2 - W1) + np.cross(psi, W1)
    return np.concatenate([gamma_rate, kappa_rate], axis=1) / rest_length[:, None]


# element block k (x1, theta1, x2, theta2) <- reduced block _BLOCKS[k] times _SIGNS[k]
_BLOCKS = (slice(0, 3), slice(3, 6), slice(0, 3), slice(6, 9))
_SIGNS = (-1.0, 1.0, 1.0, 1.0)


def expand_vector(v9: FloatArray) -> FloatArray:
    """Reduced (..., 9) -> element (..., 12) vector ``S v9 = [-v_d, v_theta1, v_d, v_theta2]``."""
    return np.concatenate([-v9[..., 0:3], v9[..., 3:6], v9[..., 0:3], v9[..., 6:9]], axis=-1)


def expand_matrix(m9: FloatArray) -> FloatArray:
    """Reduced (n, 9, 9) -> element (n, 12, 12) matrix ``S m9 S^T``, ``S`` of :func:`expand_vector`."""
    out = np.empty(m9.shape[:-2] + (12, 12))
    for i, (rows, si) in enumerate(zip(_BLOCKS, _SIGNS)):
        for j, (cols, sj) in enumerate(zip(_BLOCKS, _SIGNS)):
            block = m9[..., rows, cols]
            out[..., 3 * i:3 * i + 3, 3 * j:3 * j + 3] = block if si * sj > 0.0 else -block
    return out


def strain_operators(psi: FloatArray, R_m: FloatArray,
                     g: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Linearised strains on the reduced DOF ``[dd, dtheta1, dtheta2]`` (§Linearisation).

    Returns
    -------
    B9 : (n, 6, 9)
        ``Le * B`` reduced: ``d[Gamma, K] = B9 @ [dd, dtheta1, dtheta2] / Le`` with Gamma rows
        ``[R_m^T, hat(g) P2^T, hat(g) P2]`` and K rows ``[0, -A^T, A]``, ``A = T(psi)^-1``
        (``dpsi = A dtheta2 - A^T dtheta1``).
    P2 : (n, 3, 3)
        ``I/2 + beta hat(psi)``; the midpoint triad varies by ``dphi_m = P2^T dtheta1 + P2 dtheta2``
        (:func:`midpoint_coefficient`).
    """
    beta = midpoint_coefficient(np.linalg.norm(psi, axis=1))[0]
    P2 = hat(beta[:, None] * psi)
    P2[:, 0, 0] = P2[:, 1, 1] = P2[:, 2, 2] = 0.5
    A = dexp_inv(psi)
    G = hat(g)
    B9 = np.zeros((psi.shape[0], 6, 9))
    B9[:, :3, 0:3] = np.swapaxes(R_m, 1, 2)
    B9[:, :3, 3:6] = G @ np.swapaxes(P2, 1, 2)
    B9[:, :3, 6:9] = G @ P2
    B9[:, 3:, 3:6] = -np.swapaxes(A, 1, 2)
    B9[:, 3:, 6:9] = A
    return B9, P2


def strain_matrix(rest_length: FloatArray, x: FloatArray, q: FloatArray) -> FloatArray:
    """Strain-displacement matrix ``B = d[Gamma, K] / d(element DOF)``: (n, 6, 12).

    ``rest_length (n,)``, ``x (n, 2, 3)``, ``q (n, 2, 4)``. The same matrix maps element
    velocities ``[v1, W1, v2, W2]`` to the strain rates (§Strain rates).
    """
    B9 = strain_operators(*kinematics(x, q))[0]
    return expand_vector(B9) / rest_length[:, None, None]
