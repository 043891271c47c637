"""Rotation kernels: exp/log, quaternion algebra and the tangent operator of SO(3)."""

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from rodnet.kernels import so3

ANGLES = [0.0, 1e-12, 1e-9, 1e-6, 1e-3, 0.05, 0.0999999, 0.1000001, 0.5, 1.0, 2.0, 3.0,
          np.pi - 1e-6, np.pi - 1e-9]


def rotvecs(rng, angles):
    """Rotation vectors with the given angles about random axes: (len(angles), 3)."""
    axes = rng.normal(size=(len(angles), 3))
    return axes / np.linalg.norm(axes, axis=1, keepdims=True) * np.asarray(angles)[:, None]


def random_quats(rng, n):
    return so3.quat_normalize(rng.normal(size=(n, 4)))


def to_scipy(q):
    return Rotation.from_quat(q[..., [1, 2, 3, 0]])


def test_quat_to_matrix_matches_scipy_and_is_a_rotation():
    q = random_quats(np.random.default_rng(1), 50)
    R = so3.quat_to_matrix(q)
    np.testing.assert_allclose(R, to_scipy(q).as_matrix(), atol=1e-15)
    np.testing.assert_allclose(R @ np.swapaxes(R, 1, 2), np.broadcast_to(np.eye(3), R.shape), atol=1e-15)
    np.testing.assert_allclose(np.linalg.det(R), 1.0, atol=1e-14)


def test_quat_multiply_composes_rotations():
    rng = np.random.default_rng(2)
    p, q = random_quats(rng, 30), random_quats(rng, 30)
    np.testing.assert_allclose(so3.quat_to_matrix(so3.quat_multiply(p, q)),
                               so3.quat_to_matrix(p) @ so3.quat_to_matrix(q), atol=1e-15)
    np.testing.assert_allclose(so3.quat_to_matrix(so3.quat_multiply(so3.quat_conjugate(q), q)),
                               np.broadcast_to(np.eye(3), (30, 3, 3)), atol=1e-15)


def test_exp_log_round_trip_from_zero_to_pi():
    theta = rotvecs(np.random.default_rng(3), ANGLES)
    back_q = so3.rotvec_from_quat(so3.quat_from_rotvec(theta))
    back_R = so3.rotvec_from_matrix(so3.so3_exp(theta))
    np.testing.assert_allclose(back_q, theta, rtol=0, atol=2e-15)
    # near pi, the matrix loses the angle to O(eps / (pi - angle)) through w = cos(angle / 2)
    np.testing.assert_allclose(back_R, theta, rtol=0, atol=1e-13)
    tiny = theta[1:4]
    np.testing.assert_allclose(back_q[1:4], tiny, rtol=1e-15, atol=0)
    np.testing.assert_allclose(back_R[1:4], tiny, rtol=1e-12, atol=0)


def test_log_at_exactly_pi_gives_an_equivalent_rotation_vector():
    axes = np.vstack([np.eye(3), np.array([[1.0, -2.0, 0.5]]) / np.linalg.norm([1.0, -2.0, 0.5])])
    theta = np.pi * axes
    logs = (so3.rotvec_from_matrix(so3.so3_exp(theta)), so3.rotvec_from_quat(so3.quat_from_rotvec(theta)))
    for log in logs:
        np.testing.assert_allclose(np.linalg.norm(log, axis=1), np.pi, atol=1e-12)
        np.testing.assert_allclose(so3.so3_exp(log), so3.so3_exp(theta), atol=1e-12)


def test_log_of_a_quaternion_ignores_sign_and_scale():
    rng = np.random.default_rng(4)
    theta = rotvecs(rng, [0.0, 1e-8, 0.7, 2.9])
    q = so3.quat_from_rotvec(theta)
    np.testing.assert_allclose(so3.rotvec_from_quat(-3.0 * q), theta, atol=1e-15)


def test_quat_from_matrix_takes_every_branch():
    rng = np.random.default_rng(5)
    angles = [0.3, 3.1, 3.1, 3.1, np.pi]
    # largest of w, x, y, z in turn, and an exact half turn
    axes = np.array([[0.2, 0.3, 0.9], [1.0, 0.1, 0.1], [0.1, 1.0, 0.1], [0.1, 0.1, 1.0],
                     [0.0, 0.6, 0.8]])
    theta = axes / np.linalg.norm(axes, axis=1, keepdims=True) * np.array(angles)[:, None]
    theta = np.vstack([theta, rotvecs(rng, rng.uniform(0, np.pi, 40))])
    q = so3.quat_from_rotvec(theta)
    q_back = so3.quat_from_matrix(so3.quat_to_matrix(q))
    assert np.all(q_back[:, 0] >= 0.0)
    np.testing.assert_allclose(np.abs(np.sum(q_back * q, axis=1)), 1.0, atol=1e-14)


def test_so3_exp_matches_quaternion_and_scipy():
    theta = rotvecs(np.random.default_rng(6), ANGLES)
    R = so3.so3_exp(theta)
    np.testing.assert_allclose(R, so3.quat_to_matrix(so3.quat_from_rotvec(theta)), atol=2e-15)
    np.testing.assert_allclose(R, Rotation.from_rotvec(theta).as_matrix(), atol=2e-15)


def test_small_angle_operators_follow_their_series():
    theta = rotvecs(np.random.default_rng(7), [1e-9, 1e-5])
    S = so3.hat(theta)
    I = np.eye(3)
    np.testing.assert_allclose(so3.so3_exp(theta), I + S + S @ S / 2, atol=1e-16)
    np.testing.assert_allclose(so3.dexp(theta), I - S / 2 + S @ S / 6, atol=1e-16)
    np.testing.assert_allclose(so3.dexp_inv(theta), I + S / 2 + S @ S / 12, atol=1e-16)


@pytest.mark.parametrize("angle", ANGLES[1:])
def test_dexp_matches_finite_differences_of_the_exponential(angle):
    """``exp(psi + h e_j) = exp(psi) exp(h T(psi) e_j)``: the right-trivialised derivative."""
    psi = rotvecs(np.random.default_rng(8), [angle])
    q = so3.quat_from_rotvec(psi)
    h = 1e-6
    fd = np.empty((3, 3))
    for j in range(3):
        e = np.zeros((1, 3))
        e[0, j] = h
        relative = [so3.rotvec_from_quat(so3.quat_multiply(so3.quat_conjugate(q), so3.quat_from_rotvec(p)))
                    for p in (psi + e, psi - e)]
        fd[:, j] = (relative[0] - relative[1])[0] / (2 * h)
    np.testing.assert_allclose(so3.dexp(psi)[0], fd, atol=1e-9)


def test_dexp_inv_is_the_inverse_and_transposes_by_sign():
    psi = rotvecs(np.random.default_rng(9), ANGLES)
    T, T_inv = so3.dexp(psi), so3.dexp_inv(psi)
    np.testing.assert_allclose(T @ T_inv, np.broadcast_to(np.eye(3), T.shape), atol=1e-13)
    np.testing.assert_allclose(np.swapaxes(T, 1, 2), so3.dexp(-psi), atol=1e-15)
    np.testing.assert_allclose(np.einsum("nij,nj->ni", T, psi), psi, atol=1e-15)
    w = np.random.default_rng(10).normal(size=psi.shape)
    np.testing.assert_allclose(so3.dexp_inv_apply(psi, w), np.einsum("nij,nj->ni", T_inv, w), atol=1e-14)
    np.testing.assert_allclose(so3.dexp_inv_apply(-psi, w), np.einsum("nji,nj->ni", T_inv, w), atol=1e-14)


def test_dexp_inv_coefficient_is_accurate_on_both_sides_of_the_series_switch():
    """Against the closed forms in extended precision (np.longdouble, ~19 digits on x86)."""
    phi = np.concatenate([np.linspace(0.2, 3.1, 300), [0.5 - 1e-12, 0.5 + 1e-12]])
    p = phi.astype(np.longdouble)
    half_cot = 0.5 / np.tan(0.5 * p)
    gamma_ref = (1 - p * half_cot) / p**2
    gamma_d_ref = (-2 / p**3 + half_cot / p**2 + 0.25 / (p * np.sin(0.5 * p) ** 2)) / p
    gamma, gamma_d = so3.dexp_inv_coefficient(phi)
    np.testing.assert_allclose(gamma, gamma_ref.astype(float), rtol=1e-13)
    np.testing.assert_allclose(gamma_d, gamma_d_ref.astype(float), rtol=1e-11)
    np.testing.assert_allclose(so3.dexp_inv_coefficient(np.array([0.0, 1e-8])),
                               [[1 / 12] * 2, [1 / 360] * 2], rtol=1e-15)


@pytest.mark.parametrize("angle", ANGLES)
def test_dexp_inv_derivative_matches_finite_differences(angle):
    rng = np.random.default_rng(11)
    psi = rotvecs(rng, [angle])
    w = rng.normal(size=(1, 3))
    h = 1e-6
    fd = np.empty((3, 3))
    for j in range(3):
        e = np.zeros((1, 3))
        e[0, j] = h
        fd[:, j] = (so3.dexp_inv_apply(psi + e, w) - so3.dexp_inv_apply(psi - e, w))[0] / (2 * h)
    np.testing.assert_allclose(so3.dexp_inv_derivative(psi, w)[0], fd, atol=1e-9)


def test_retract_is_the_body_frame_exponential_update():
    rng = np.random.default_rng(12)
    q, dtheta = random_quats(rng, 20), rotvecs(rng, rng.uniform(0, 3.0, 20))
    q_new = so3.retract(q, dtheta)
    np.testing.assert_allclose(np.linalg.norm(q_new, axis=1), 1.0, atol=1e-15)
    np.testing.assert_allclose(so3.quat_to_matrix(q_new), so3.quat_to_matrix(q) @ so3.so3_exp(dtheta),
                               atol=1e-14)


def test_hat_is_the_cross_product():
    rng = np.random.default_rng(13)
    a, b = rng.normal(size=(2, 10, 3))
    np.testing.assert_allclose(np.einsum("nij,nj->ni", so3.hat(a), b), np.cross(a, b), atol=1e-15)


def test_compiled_retract_and_gyroscopic_match_numpy() -> None:
    from rodnet.kernels import so3_compiled

    rng = np.random.default_rng(7)
    q = so3.quat_normalize(rng.normal(size=(50, 4)))
    dtheta = rng.normal(size=(50, 3)) * np.logspace(-9, 0.5, 50)[:, None]
    np.testing.assert_allclose(so3_compiled.retract(q, dtheta), so3.retract(q, dtheta), atol=1e-15)
    W, J = rng.normal(size=(50, 3)), rng.uniform(0.5, 2.0, size=(50, 3))
    f, d = so3_compiled.gyroscopic(W, J)
    np.testing.assert_allclose(f, np.cross(W, J * W), atol=1e-14)
    np.testing.assert_allclose(d, so3.hat(W) * J[:, None, :] - so3.hat(J * W), atol=1e-14)
