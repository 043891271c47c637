"""Cosserat element kernels: strains, forces and tangents against analytic values, finite
differences on the Lie algebra, and rigid-motion invariance."""

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from rodnet.kernels import cosserat, so3
from rodnet.kernels.tension import REVERSED_STIFFNESS
from rodnet.kernels.cosserat_strain import (
    kinematics, midpoint_coefficient, reduce_velocity, strain_rates_from_kinematics,
)

E1 = np.array([1.0, 0.0, 0.0])
TENSION_ONLY, LINEAR = True, False


# ---------------------------------------------------------------------------------------------
# states


def random_quats(rng, n):
    return so3.quat_normalize(rng.normal(size=(n, 4)))


def random_rotvecs(rng, n, max_angle):
    axis = rng.normal(size=(n, 3))
    return axis / np.linalg.norm(axis, axis=1, keepdims=True) * rng.uniform(0.0, max_angle, (n, 1))


def stress_free(rng, n, curved):
    """Reference element geometry: rest length, positions, quaternions and reference strains."""
    rest_length = rng.uniform(0.5, 1.5, n)
    q1 = random_quats(rng, n)
    kappa0 = random_rotvecs(rng, n, 1.5) if curved else np.zeros((n, 3))
    q = np.stack([q1, so3.retract(q1, kappa0)], axis=1)
    chord = np.tile(E1, (n, 1))
    if curved:
        chord += 0.1 * rng.normal(size=(n, 3))
    x1 = rng.normal(size=(n, 3))
    R_m = kinematics(np.zeros((n, 2, 3)), q)[1]
    x = np.stack([x1, x1 + rest_length[:, None] * np.einsum("nij,nj->ni", R_m, chord)], axis=1)
    return rest_length, x, q, cosserat.reference_strains(rest_length, x, q)


def set_chord(x, q, rest_length, reference_strain, gamma):
    """Move node 2 so that the element has exactly the strains ``gamma`` (n, 3)."""
    R_m = kinematics(x, q)[1]
    chord = rest_length[:, None] * (reference_strain[:, :3] + gamma)
    x = x.copy()
    x[:, 1] = x[:, 0] + np.einsum("nij,nj->ni", R_m, chord)
    return x


def deformed(rng, n, axial_strain, curved=True, max_angle=1.2):
    """Large-deformation state: rest data, positions, quaternions, with axial strain set exactly."""
    rest_length, x0, q0, ref = stress_free(rng, n, curved)
    q = so3.retract(q0, random_rotvecs(rng, 2 * n, max_angle).reshape(n, 2, 3))
    gamma = np.column_stack([np.full(n, axial_strain), 0.15 * rng.normal(size=(n, 2))])
    x = set_chord(x0 + rng.normal(size=x0.shape), q, rest_length, ref, gamma)
    return rest_length, ref, x, q


def set_axial_rate(x, q, velocity, rest_length, rate):
    """Shift v2 along the midpoint axial director so that the axial strain rate equals ``rate``."""
    psi, R_m, g = kinematics(x, q)
    current = strain_rates_from_kinematics(psi, R_m, g, reduce_velocity(velocity), rest_length)[:, 0]
    velocity = velocity.copy()
    velocity[:, 6:9] += R_m[:, :, 0] * (rest_length * (rate - current))[:, None]
    return velocity


def section(rng, n):
    """Section stiffness [EA, GA2, GA3, GJ, EI2, EI3] of comparable size, so that every term shows."""
    return rng.uniform(0.5, 2.0, (n, 6)) * np.array([10.0, 4.0, 4.0, 1.0, 1.5, 1.5])


def perturb(x, q, dq):
    """Element state moved by the element increment ``dq`` (n, 12): x + dx, R exp(hat(dtheta))."""
    dq = dq.reshape(-1, 2, 6)
    return x + dq[:, :, :3], so3.retract(q, dq[:, :, 3:])


def lie_gradient(fun, x, q, h):
    """Central differences of ``fun(x, q)`` (n, ...) along the 12 element DOF: (n, ..., 12)."""
    columns = []
    for j in range(12):
        dq = np.zeros((x.shape[0], 12))
        dq[:, j] = h
        columns.append((fun(*perturb(x, q, dq)) - fun(*perturb(x, q, -dq))) / (2 * h))
    return np.stack(columns, axis=-1)


def relative_error(a, b):
    """Per element ``max |a - b| / max |b|``: (n,)."""
    axes = tuple(range(1, b.ndim))
    return np.max(np.abs(a - b), axis=axes) / np.max(np.abs(b), axis=axes)


# ---------------------------------------------------------------------------------------------
# strains


def test_strains_match_an_independent_evaluation():
    rng = np.random.default_rng(1)
    rest_length, ref, x, q = deformed(rng, 40, 0.1)
    R = Rotation.from_quat(q[..., [1, 2, 3, 0]].reshape(-1, 4)).as_matrix().reshape(40, 2, 3, 3)
    psi = Rotation.from_matrix(np.swapaxes(R[:, 0], 1, 2) @ R[:, 1]).as_rotvec()
    R_m = R[:, 0] @ Rotation.from_rotvec(psi / 2).as_matrix()
    gamma = np.einsum("nji,nj->ni", R_m, x[:, 1] - x[:, 0]) / rest_length[:, None] - ref[:, :3]
    expected = np.concatenate([gamma, psi / rest_length[:, None] - ref[:, 3:]], axis=1)
    np.testing.assert_allclose(cosserat.strains(rest_length, ref, x, q), expected, atol=1e-13)


def test_uniform_stretch_gives_the_axial_force():
    rng = np.random.default_rng(2)
    n, e, kink = 6, 0.02, 1e-3
    rest_length, x, q, ref = stress_free(rng, n, curved=False)
    x = set_chord(x, q, rest_length, ref, np.tile([e, 0.0, 0.0], (n, 1)))
    stiffness, tau, velocity = section(rng, n), np.zeros(n), np.zeros((n, 12))
    d1 = so3.quat_to_matrix(q[:, 0])[:, :, 0]
    np.testing.assert_allclose(cosserat.strains(rest_length, ref, x, q),
                               np.tile([e, 0, 0, 0, 0, 0], (n, 1)), atol=1e-15)
    for tension_only, axial in ((LINEAR, e), (TENSION_ONLY, e - kink / 2)):
        f = cosserat.internal_force(rest_length, ref, stiffness, tau, x, q, velocity, tension_only, kink)
        N = stiffness[:, 0] * axial
        atol = 1e-13 * np.abs(N).max()
        np.testing.assert_allclose(f[:, 6:9], N[:, None] * d1, rtol=0, atol=atol)
        np.testing.assert_allclose(f[:, 0:3], -N[:, None] * d1, rtol=0, atol=atol)
        np.testing.assert_allclose(f[:, [3, 4, 5, 9, 10, 11]], 0.0, rtol=0, atol=atol)


@pytest.mark.parametrize("angle", [1e-9, 0.3, 2.0, 3.0, 4.5, 6.0])
def test_circular_arc_gives_uniform_curvature_and_end_moments(angle):
    """Nodes on a circle of radius Le/angle, director d1 tangent: K = angle/Le e3 and the chord
    seen by the one-point rule is 2 sin(angle/2)/angle shorter; slack in tension-only mode.
    Beyond ROTATION_STOP (5 rad) the stop (C52) adds k_s (angle - 5) to the end moments, to the
    reported section moment and k_s (angle - 5)^2 / 2 to the energy, k_s = GA2 Le."""
    Le, EI3 = 0.7, 3.0
    stiffness = np.array([[100.0, 40.0, 40.0, 1.0, 2.0, EI3]])
    rho = Le / angle
    x = np.array([[[0.0, 0.0, 0.0], [rho * np.sin(angle), 2.0 * rho * np.sin(angle / 2) ** 2, 0.0]]])
    q2 = so3.quat_from_rotvec(np.array([[0.0, 0.0, angle]]))
    q = np.stack([np.array([[1.0, 0.0, 0.0, 0.0]]), q2], axis=1)
    ref = np.array([[1.0, 0.0, 0.0, 0.0, 0.0, 0.0]])
    eps = cosserat.strains(np.array([Le]), ref, x, q)
    np.testing.assert_allclose(eps[0], [2 * np.sin(angle / 2) / angle - 1.0, 0, 0, 0, 0, angle / Le],
                               atol=1e-15)
    args = (np.array([Le]), ref, stiffness, np.zeros(1), x, q, np.zeros((1, 12)), TENSION_ONLY, 1e-6)
    k_s, excess = stiffness[0, 1] * Le, max(angle - 5.0, 0.0)
    M = EI3 * angle / Le + k_s * excess
    np.testing.assert_allclose(cosserat.internal_force(*args)[0], [0, 0, 0, 0, 0, -M, 0, 0, 0, 0, 0, M],
                               atol=1e-13 * M)
    np.testing.assert_allclose(cosserat.internal_force_numpy(*args)[0],
                               [0, 0, 0, 0, 0, -M, 0, 0, 0, 0, 0, M], atol=1e-13 * M)
    for state_of in (cosserat.section_state, cosserat.section_state_numpy):  # reported moment
        np.testing.assert_allclose(state_of(*args)[1][0, 3:], [0, 0, M], atol=1e-13 * M)
    expected = 0.5 * EI3 * (angle / Le) ** 2 * Le + 0.5 * k_s * excess**2
    for energy_of in (cosserat.strain_energy, cosserat.strain_energy_numpy):
        energy = energy_of(np.array([Le]), ref, stiffness, x, q, TENSION_ONLY, 1e-6)
        np.testing.assert_allclose(energy, expected, rtol=1e-13)


def test_tension_only_energy_follows_the_ramp():
    rng = np.random.default_rng(3)
    n, kink = 3, 1e-3
    rest_length, x, q, ref = stress_free(rng, n, curved=True)
    stiffness = section(rng, n)
    mirrored = REVERSED_STIFFNESS   # material axis against the chord (C51): the ramp mirrored
    for e, integral in ((-0.1, 0.0), (kink / 2, (kink / 2) ** 3 / (6 * kink)),
                        (0.05, 0.05**2 / 2 - kink * 0.05 / 2 + kink**2 / 6),
                        (-1.0 - kink / 2, mirrored * (kink / 2) ** 3 / (6 * kink)),
                        (-1.05, mirrored * (0.05**2 / 2 - kink * 0.05 / 2 + kink**2 / 6))):
        xe = set_chord(x, q, rest_length, ref, np.tile([e, 0.0, 0.0], (n, 1)))
        energy = cosserat.strain_energy(rest_length, ref, stiffness, xe, q, TENSION_ONLY, kink)
        # shear strains are round-off here: their energy is ~1e-32 EA Le
        np.testing.assert_allclose(energy, stiffness[:, 0] * rest_length * integral, rtol=1e-10,
                                   atol=1e-25 * np.max(stiffness[:, 0] * rest_length))


def test_strain_rates_are_the_time_derivatives_of_the_strains():
    """Move along x + t v, R exp(t hat(W)); B u and the vector formula match central differences."""
    rng = np.random.default_rng(4)
    n = 20
    rest_length, ref, x, q = deformed(rng, n, 0.1)
    velocity = rng.normal(size=(n, 12))
    h = 1e-6
    fd = (cosserat.strains(rest_length, ref, *perturb(x, q, h * velocity))
          - cosserat.strains(rest_length, ref, *perturb(x, q, -h * velocity))) / (2 * h)
    B = cosserat.strain_matrix(rest_length, x, q)
    np.testing.assert_allclose(np.einsum("nij,nj->ni", B, velocity), fd, rtol=0,
                               atol=1e-8 * np.abs(fd).max())
    rates = strain_rates_from_kinematics(*kinematics(x, q), reduce_velocity(velocity), rest_length)
    np.testing.assert_allclose(rates, np.einsum("nij,nj->ni", B, velocity), atol=1e-13)


def test_midpoint_coefficient_is_accurate_on_both_sides_of_the_series_switch():
    phi = np.concatenate([np.linspace(0.2, 3.1, 300), [0.5 - 1e-12, 0.5 + 1e-12]])
    p = phi.astype(np.longdouble)
    t = np.tan(p / 4)
    beta, beta_d = midpoint_coefficient(phi)
    np.testing.assert_allclose(beta, (t / (2 * p)).astype(float), rtol=1e-14)
    beta_d_ref = ((1 + t * t) / (8 * p) - t / (2 * p * p)) / p
    np.testing.assert_allclose(beta_d, beta_d_ref.astype(float), rtol=1e-11)
    np.testing.assert_allclose(midpoint_coefficient(np.array([0.0])), [[1 / 8], [1 / 192]], rtol=1e-15)


# ---------------------------------------------------------------------------------------------
# force = energy gradient, tangents = force derivatives


@pytest.mark.parametrize("tension_only, axial_strain", [
    (LINEAR, -0.2), (LINEAR, 0.3), (TENSION_ONLY, -0.1), (TENSION_ONLY, 5e-4), (TENSION_ONLY, 0.25),
    (TENSION_ONLY, -1.0005), (TENSION_ONLY, -1.3)])
def test_internal_force_is_the_lie_algebra_gradient_of_the_energy(tension_only, axial_strain):
    rng = np.random.default_rng(5)
    n, kink = 30, 1e-3
    rest_length, ref, x, q = deformed(rng, n, axial_strain)
    stiffness = section(rng, n)
    force = cosserat.internal_force(rest_length, ref, stiffness, np.zeros(n), x, q, np.zeros((n, 12)),
                                    tension_only, kink)
    energy_at = lambda xx, qq: cosserat.strain_energy(  # noqa: E731
        rest_length, ref, stiffness, xx, qq, tension_only, kink)
    fd = lie_gradient(energy_at, x, q, 1e-6)
    assert np.all(relative_error(force, fd) < 1e-7)


# (tension_only, axial strain, axial strain rate, retardation time); kink strain 1e-3
TANGENT_CASES = {
    "linear": (LINEAR, 0.2, 0.0, 0.0),
    "linear, compressed, damped": (LINEAR, -0.15, -1.0, 0.05),
    "tension-only, taut": (TENSION_ONLY, 0.25, 0.0, 0.0),
    "tension-only, slack": (TENSION_ONLY, -0.1, 0.0, 0.0),
    "tension-only, ramp": (TENSION_ONLY, 4e-4, 0.0, 0.0),
    "tension-only, taut, damped": (TENSION_ONLY, 0.2, 2.0, 0.05),
    "tension-only, ramp, damped": (TENSION_ONLY, 5e-4, 0.02, 0.05),
    "tension-only, clamped": (TENSION_ONLY, 0.2, -10.0, 0.05),
    "tension-only, ramp, clamped": (TENSION_ONLY, 5e-4, -0.2, 0.05),
    # material axis against the chord: the mirrored law (C51) pushes
    "tension-only, reversed": (TENSION_ONLY, -1.3, 0.0, 0.0),
    "tension-only, reversed, ramp": (TENSION_ONLY, -1.0004, 0.0, 0.0),
    "tension-only, reversed, damped": (TENSION_ONLY, -1.2, -2.0, 0.05),
    "tension-only, reversed, clamped": (TENSION_ONLY, -1.2, 10.0, 0.05),
}


def tangent_case(name, n=25, seed=6):
    tension_only, axial_strain, axial_rate, tau = TANGENT_CASES[name]
    rng = np.random.default_rng(seed)
    rest_length, ref, x, q = deformed(rng, n, axial_strain)
    velocity = set_axial_rate(x, q, rng.normal(size=(n, 12)), rest_length, axial_rate)
    return (rest_length, ref, section(rng, n), np.full(n, tau)), (x, q, velocity), (tension_only, 1e-3)


@pytest.mark.parametrize("name", TANGENT_CASES)
def test_stiffness_tangent_matches_lie_algebra_finite_differences(name):
    model, (x, q, velocity), law = tangent_case(name)
    force, K, _ = cosserat.internal_force_and_tangents(*model, x, q, velocity, *law)
    force_at = lambda xx, qq: cosserat.internal_force(*model, xx, qq, velocity, *law)  # noqa: E731
    np.testing.assert_array_equal(force, force_at(x, q))
    fd = lie_gradient(force_at, x, q, 1e-7)
    assert np.all(relative_error(K, fd) < 1e-6)
    # the check has teeth: the material part alone, Le B^T D B, is far off
    stress, modulus, _ = cosserat.stress_resultants_and_moduli(
        model[2], model[3], cosserat.strains(model[0], model[1], x, q), np.zeros((x.shape[0], 6)), *law)
    B = cosserat.strain_matrix(model[0], x, q)
    material = model[0][:, None, None] * np.swapaxes(B, 1, 2) @ (modulus[:, :, None] * B)
    assert np.all(relative_error(material, fd) > 1e-2)


@pytest.mark.parametrize("name", TANGENT_CASES)
def test_damping_tangent_matches_velocity_finite_differences(name):
    model, (x, q, velocity), law = tangent_case(name)
    rest_length, _, stiffness, tau = model
    _, _, C = cosserat.internal_force_and_tangents(*model, x, q, velocity, *law)
    h = 1e-7
    force_at = lambda u: cosserat.internal_force(*model, x, q, u, *law)  # noqa: E731
    fd = np.stack([(force_at(velocity + h * np.eye(12)[j]) - force_at(velocity - h * np.eye(12)[j]))
                   / (2 * h) for j in range(12)], axis=-1)
    if tau[0] == 0.0:
        np.testing.assert_array_equal(C, 0.0)
        np.testing.assert_array_equal(fd, 0.0)
        return
    assert np.all(relative_error(C, fd) < 1e-6)
    # Le B^T diag(tau C) B, without the axial entry where the clamp holds or the thread is slack
    axial = 0.0 if "clamped" in name else REVERSED_STIFFNESS if "reversed" in name else 1.0
    B = cosserat.strain_matrix(rest_length, x, q)
    viscous = tau[:, None] * stiffness * [axial, 1, 1, 1, 1, 1]
    if "ramp" in name and "clamped" not in name:
        viscous[:, 0] *= cosserat.strains(rest_length, model[1], x, q)[:, 0] / law[1]
    expected = rest_length[:, None, None] * np.swapaxes(B, 1, 2) @ (viscous[:, :, None] * B)
    np.testing.assert_allclose(C, expected, rtol=0, atol=1e-12 * np.abs(C).max())


@pytest.mark.parametrize("name", ["linear, compressed, damped", "tension-only, ramp, damped",
                                  "tension-only, clamped"])
def test_compiled_and_numpy_tangents_agree(name):
    model, state, law = tangent_case(name, n=200)
    compiled = cosserat.internal_force_and_tangents(*model, *state, *law)
    reference = cosserat.internal_force_and_tangents_numpy(*model, *state, *law)
    # The paths agree on the kinematics to a few ulp (NumPy's and libm's atan2 and tan differ in
    # the last bit); inside the ramp the axial moduli EA e / delta magnify that by 1 / e.
    for a, b in zip(compiled, reference):
        assert np.all(np.isfinite(a))
        np.testing.assert_allclose(a, b, rtol=0, atol=1e-12 * np.abs(b).max())


@pytest.mark.parametrize("angle", [0.0, 1e-9, np.pi - 1e-3, np.pi + 1e-3, 4.5, 2 * np.pi - 0.3])
def test_tangent_at_the_ends_of_the_relative_rotation_range(angle):
    """Identical node frames (psi = 0 exactly), nearly opposite ones and relative rotations past
    pi on the quaternion double cover (C11) stay finite and exact."""
    rng = np.random.default_rng(7)
    n = 5
    rest_length, x, q0, ref = stress_free(rng, n, curved=False)
    axis = random_rotvecs(rng, n, 1.0)
    axis /= np.linalg.norm(axis, axis=1, keepdims=True)
    q = np.stack([q0[:, 0], so3.retract(q0[:, 0], angle * axis)], axis=1)
    x = set_chord(x + rng.normal(size=x.shape), q, rest_length, ref,
                  np.tile([0.1, 0.05, -0.05], (n, 1)))
    model, velocity = (rest_length, ref, section(rng, n), np.full(n, 0.05)), rng.normal(size=(n, 12))
    _, K, _ = cosserat.internal_force_and_tangents(*model, x, q, velocity, LINEAR, 1e-3)
    force_at = lambda xx, qq: cosserat.internal_force(  # noqa: E731
        *model, xx, qq, velocity, LINEAR, 1e-3)
    psi = cosserat.strains(rest_length, ref, x, q)[:, 3:] * rest_length[:, None]
    np.testing.assert_allclose(np.linalg.norm(psi, axis=1), angle, rtol=1e-9, atol=1e-15)
    fd = lie_gradient(force_at, x, q, 1e-7)
    assert np.all(np.isfinite(K))
    assert np.all(relative_error(K, fd) < 1e-6)


def test_finite_difference_error_of_the_tangent_falls_as_h_squared():
    """A consistent tangent leaves only the O(h^2) truncation of the central difference."""
    model, (x, q, velocity), law = tangent_case("tension-only, taut, damped", n=10)
    _, K, _ = cosserat.internal_force_and_tangents(*model, x, q, velocity, *law)
    force_at = lambda xx, qq: cosserat.internal_force(*model, xx, qq, velocity, *law)  # noqa: E731
    coarse = relative_error(K, lie_gradient(force_at, x, q, 2e-3))
    fine = relative_error(K, lie_gradient(force_at, x, q, 1e-3))
    assert np.all(coarse > 1e-8)
    np.testing.assert_allclose(coarse / fine, 4.0, rtol=0.05)


# ---------------------------------------------------------------------------------------------
# objectivity


def rigid_motion(rng, x, q, velocity=None):
    """Apply one large rigid rotation Q (about a random point) to every element; return Q too."""
    n = x.shape[0]
    Q_rotvec = np.tile(random_rotvecs(rng, 1, 3.0), (n, 1))
    Q = so3.so3_exp(Q_rotvec)
    shift = rng.normal(size=3) * 10.0
    x_new = np.einsum("nij,nkj->nki", Q, x) + shift
    q_new = so3.quat_multiply(so3.quat_from_rotvec(Q_rotvec)[:, None, :], q)
    return x_new, q_new, Q


@pytest.mark.parametrize("curved", [False, True])
def test_no_force_under_large_rigid_motion_of_a_stress_free_element(curved):
    rng = np.random.default_rng(8)
    n = 50
    rest_length, x0, q0, ref = stress_free(rng, n, curved)
    stiffness = section(rng, n) * [1e4, 1e4, 1e4, 1.0, 1.0, 1.0]
    x, q, Q = rigid_motion(rng, x0, q0)
    # a rigid velocity field: spin omega about the origin plus a drift; W = R^T omega per node
    omega, drift = rng.normal(size=3), rng.normal(size=3)
    R = so3.quat_to_matrix(q)
    v = np.cross(omega, x) + drift
    W = np.einsum("nkji,j->nki", R, omega)
    velocity = np.concatenate([v[:, 0], W[:, 0], v[:, 1], W[:, 1]], axis=1)
    for tension_only in (LINEAR, TENSION_ONLY):
        f = cosserat.internal_force(rest_length, ref, stiffness, np.full(n, 0.1), x, q, velocity,
                                    tension_only, 1e-6)
        assert np.all(np.abs(f) <= 1e-12 * stiffness[:, :1])
    np.testing.assert_allclose(cosserat.strains(rest_length, ref, x, q), 0.0, atol=1e-13)


def test_superposed_rotation_keeps_energy_and_rotates_forces_and_tangents():
    rng = np.random.default_rng(9)
    n = 30
    model, (x, q, velocity), law = tangent_case("tension-only, taut, damped", n=n, seed=9)
    energy = cosserat.strain_energy(model[0], model[1], model[2], x, q, *law)
    f, K, C = cosserat.internal_force_and_tangents(*model, x, q, velocity, *law)
    x_rot, q_rot, Q = rigid_motion(rng, x, q)
    v_rot = velocity.reshape(n, 4, 3).copy()
    # global velocities turn with Q, body angular velocities do not
    v_rot[:, [0, 2]] = np.einsum("nij,nkj->nki", Q, v_rot[:, [0, 2]])
    f_rot, K_rot, C_rot = cosserat.internal_force_and_tangents(*model, x_rot, q_rot,
                                                               v_rot.reshape(n, 12), *law)
    energy_rot = cosserat.strain_energy(model[0], model[1], model[2], x_rot, q_rot, *law)
    np.testing.assert_allclose(energy_rot, energy, rtol=1e-12)
    T = np.zeros((n, 12, 12))
    for b, rotated in enumerate((True, False, True, False)):
        T[:, 3 * b:3 * b + 3, 3 * b:3 * b + 3] = Q if rotated else np.eye(3)
    scale = np.abs(f).max()
    np.testing.assert_allclose(f_rot, np.einsum("nij,nj->ni", T, f), atol=1e-12 * scale)
    TT = np.swapaxes(T, 1, 2)
    np.testing.assert_allclose(K_rot, T @ K @ TT, atol=1e-11 * np.abs(K).max())
    np.testing.assert_allclose(C_rot, T @ C @ TT, atol=1e-11 * np.abs(C).max())


def test_internal_forces_balance_in_force_and_moment():
    """Frame indifference implies zero resultant and zero moment about the origin."""
    model, (x, q, velocity), law = tangent_case("linear, compressed, damped", n=20, seed=10)
    f = cosserat.internal_force(*model, x, q, velocity, *law).reshape(-1, 4, 3)
    R = so3.quat_to_matrix(q)
    np.testing.assert_allclose(f[:, 0] + f[:, 2], 0.0, atol=1e-13 * np.abs(f).max())
    moment = (np.cross(x[:, 0], f[:, 0]) + np.cross(x[:, 1], f[:, 2])
              + np.einsum("nij,nj->ni", R[:, 0], f[:, 1]) + np.einsum("nij,nj->ni", R[:, 1], f[:, 3]))
    np.testing.assert_allclose(moment, 0.0, atol=1e-12 * np.abs(f).max() * (1 + np.abs(x).max()))


def test_compiled_element_rotation_is_the_angle_of_the_relative_rotation() -> None:
    """The compiled angle of each element's relative rotation is ``|psi|`` of the NumPy
    kinematics, and for a section turned about the chord by a known angle (past half a turn, on
    the quaternion double cover) it is that angle."""
    from rodnet.kernels.cosserat_compiled import element_rotation

    rng = np.random.default_rng(7)
    _, _, x, q = deformed(rng, 50, 0.01, max_angle=3.0)
    expected = np.linalg.norm(kinematics(x, q)[0], axis=1)
    assert np.allclose(element_rotation(x, q), expected, rtol=1e-13, atol=1e-15)
    angles = np.array([0.0, 1e-8, 0.7, 3.5, 6.0])
    q1 = random_quats(rng, len(angles))
    q2 = so3.quat_multiply(q1, so3.quat_from_rotvec(angles[:, None] * E1))
    x = np.zeros((len(angles), 2, 3))
    assert np.allclose(element_rotation(x, np.stack([q1, q2], axis=1)), angles, rtol=1e-12,
                       atol=1e-15)
