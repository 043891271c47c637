"""The Cosserat element oracle (elements/cosserat/reference.py) against its own physics.

Checks are analytic values, finite differences on the Lie algebra, invariants and the frozen
golden data. Round-off checks use 1e-12 relative, finite-difference checks 1e-7 relative.
"""

import importlib.util
import json
import sys
from pathlib import Path

import numpy as np
import pytest
from scipy.linalg import expm

ELEMENT_DIR = Path(__file__).resolve().parents[2] / "elements" / "cosserat"


def _load_reference():
    path = ELEMENT_DIR / "reference.py"
    spec = importlib.util.spec_from_file_location("cosserat_reference", path)
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module
    spec.loader.exec_module(module)
    return module


ref = _load_reference()

STIFFNESS = dict(EA=1e3, GA2=4e2, GA3=3e2, GJ=2e-2, EI2=3e-2, EI3=2.5e-2)
E1, E2, E3 = np.eye(3)
ROUND_OFF = 1e-12
FD_RTOL = 1e-7


def random_quat(rng):
    q = rng.normal(size=4)
    return q / np.linalg.norm(q)


def rotate_node(q_rot, x, q, shift=np.zeros(3)):
    """Superpose the rigid motion x -> Q x + shift, R -> Q R on one node."""
    return ref.quat_to_matrix(q_rot) @ x + shift, ref.quat_multiply(q_rot, q)


def make_state(rng, gamma, psi_norm=1.0, Le=0.1):
    """Element arguments (x1, q1, x2, q2, Le, Gamma0, K0) whose strain Gamma equals ``gamma``."""
    q1, x1 = random_quat(rng), rng.normal(size=3)
    psi = rng.normal(size=3)
    _, q2 = ref.retract_node(x1, q1, np.zeros(3), psi * psi_norm / np.linalg.norm(psi))
    x2 = x1 + Le * ref.quat_to_matrix(q1) @ (E1 + rng.uniform(-0.05, 0.05, size=3))
    Gamma_raw, K_raw = ref.stress_free_strains(x1, q1, x2, q2, Le)
    return x1, q1, x2, q2, Le, Gamma_raw - np.asarray(gamma), K_raw - rng.uniform(-2, 2, size=3)


def random_velocities(rng):
    """[v1, W1, v2, W2]: 0.1 m/s and 1 rad/s scales."""
    return np.concatenate([0.1 * rng.normal(size=3), rng.normal(size=3),
                           0.1 * rng.normal(size=3), rng.normal(size=3)])


def derivative(fun, x, h):
    return (fun(x + h) - fun(x - h)) / (2 * h)


def retracted(args, u):
    x1, q1, x2, q2, *rest = args
    y1, p1 = ref.retract_node(x1, q1, u[0:3], u[3:6])
    y2, p2 = ref.retract_node(x2, q2, u[6:9], u[9:12])
    return (y1, p1, y2, p2, *rest)


STATES = {  # name: (axial, shear 2, shear 3 strain), section overrides
    "taut": ([0.02, 0.004, -0.003], {}),
    "slack": ([-0.01, 0.002, 0.005], {}),
    "inside ramp": ([0.02, 0.001, 0.002], dict(delta=0.05)),
    "linear compressed": ([-0.01, -0.003, 0.002], dict(axial="linear")),
}


# ----------------------------------------------------------------------------- SO(3) tools


@pytest.mark.parametrize(
    "angle", [0.0, 1e-9, 1e-3, 9.9e-3, 1.01e-2, 0.5, 2.0, np.pi - 2e-3, np.pi - 1e-4]
)
def test_exp_matches_matrix_exponential_and_log_inverts_it(angle):
    for axis in np.random.default_rng(1).normal(size=(8, 3)):  # axes of every sign pattern
        phi = angle * axis / np.linalg.norm(axis)
        R = ref.so3_exp(phi)
        np.testing.assert_allclose(R, expm(ref.hat(phi)), atol=ROUND_OFF)
        np.testing.assert_allclose(ref.so3_log(R), phi, atol=1e-10 if angle > 3.0 else ROUND_OFF)
        _, q = ref.retract_node(np.zeros(3), np.array([1.0, 0, 0, 0]), np.zeros(3), phi)
        np.testing.assert_allclose(ref.quat_to_matrix(q), R, atol=ROUND_OFF)


@pytest.mark.parametrize("angle", [1e-6, 5e-3, 0.02, 1.0, 3.0])
def test_tangent_operator_is_the_derivative_of_exp(angle):
    """(C7): d exp(phi) = exp(phi) hat(T(phi) dphi); (C8) inverts T; (C10) half-angle identity."""
    rng = np.random.default_rng(2)
    phi, dphi = rng.normal(size=3), rng.normal(size=3)
    phi *= angle / np.linalg.norm(phi)
    h = 1e-6
    fd = (ref.so3_exp(phi + h * dphi) - ref.so3_exp(phi - h * dphi)) / (2 * h)
    T = ref.tangent_operator(phi)
    np.testing.assert_allclose(fd, ref.so3_exp(phi) @ ref.hat(T @ dphi), atol=1e-9)
    np.testing.assert_allclose(ref.tangent_operator_inv(phi) @ T, np.eye(3), atol=ROUND_OFF)
    half = 0.5 * ref.tangent_operator(0.5 * phi) @ ref.tangent_operator_inv(phi)
    expected = np.linalg.inv(np.eye(3) + ref.so3_exp(-0.5 * phi))
    np.testing.assert_allclose(half, expected, atol=ROUND_OFF)


# ----------------------------------------------------------------------------- derivatives


@pytest.mark.parametrize("name", STATES)
def test_b_matrix_is_the_derivative_of_the_strains(name):
    args = make_state(np.random.default_rng(3), STATES[name][0])
    B = ref.b_matrix(*args[:5])
    for j in range(12):
        u = np.zeros(12)
        u[j] = 1e-6
        plus, minus = (np.concatenate(ref.strains(*retracted(args, s * u))) for s in (1, -1))
        np.testing.assert_allclose((plus - minus) / 2e-6, B[:, j], atol=FD_RTOL * np.abs(B).max())
    assert np.linalg.matrix_rank(B) == 6


@pytest.mark.parametrize("name", STATES)
def test_internal_force_is_the_lie_algebra_gradient_of_the_energy(name):
    gamma, overrides = STATES[name]
    rng = np.random.default_rng(4)
    args = make_state(rng, gamma)
    section = ref.Section(**STIFFNESS, **overrides)
    f = ref.internal_force(*args, section)
    for _ in range(6):
        u = rng.normal(size=12) * np.repeat([args[4], 1.0, args[4], 1.0], 3)
        dW = derivative(lambda s: ref.energy(*retracted(args, s * u), section), 0.0, 1e-6)
        assert abs(dW - f @ u) <= FD_RTOL * np.linalg.norm(f) * np.linalg.norm(u)


@pytest.mark.parametrize("name", STATES)
def test_damping_matrix_matches_finite_differences(name):
    gamma, overrides = STATES[name]
    rng = np.random.default_rng(5)
    args = make_state(rng, gamma)
    section = ref.Section(**STIFFNESS, **overrides, tau=2e-3)
    vel = random_velocities(rng)
    C = ref.damping_matrix(*args, section, vel)
    C_fd = ref.damping_fd(*args, section, vel)
    np.testing.assert_allclose(C_fd, C, atol=FD_RTOL * np.abs(C).max())


def test_tangent_asymmetry_is_the_nodal_moment():
    """(C34): K_T - K_T^T = hat(m_a) in each rotational block, symmetric elsewhere (tau = 0)."""
    args = make_state(np.random.default_rng(6), STATES["taut"][0], psi_norm=1.2)
    section = ref.Section(**STIFFNESS)
    f = ref.internal_force(*args, section)
    K_T = ref.tangent_fd(*args, section)
    expected = np.zeros((12, 12))
    expected[3:6, 3:6], expected[9:12, 9:12] = ref.hat(f[3:6]), ref.hat(f[9:12])
    rotational = max(np.abs(K_T[3:6, 3:6]).max(), np.abs(K_T[9:12, 9:12]).max())
    assert np.abs(expected).max() > 0.01 * rotational  # far from equilibrium: a visible asymmetry
    np.testing.assert_allclose(K_T - K_T.T, expected, atol=1e-9 * np.abs(K_T).max())


# ----------------------------------------------------------------------------- invariance


def rigid_velocities(x1, q1, x2, q2, rng):
    """[v1, W1, v2, W2] of a rigid motion: v = c + w x x, W = R^T w."""
    c, w = rng.normal(size=3), 3.0 * rng.normal(size=3)
    return np.concatenate([c + np.cross(w, x1), ref.quat_to_matrix(q1).T @ w,
                           c + np.cross(w, x2), ref.quat_to_matrix(q2).T @ w])


@pytest.mark.parametrize("shape", ["straight", "curved"])
def test_stress_free_element_has_no_force_under_large_rigid_motion(shape):
    rng = np.random.default_rng(7)
    Le, q1, x1 = 0.1, random_quat(rng), rng.normal(size=3)
    if shape == "straight":
        q2, x2 = q1, x1 + Le * ref.quat_to_matrix(q1)[:, 0]
    else:
        _, q2 = ref.retract_node(x1, q1, np.zeros(3), np.array([0.3, -0.9, 0.6]))
        x2 = x1 + Le * ref.quat_to_matrix(q1) @ np.array([0.95, 0.1, -0.2])
    Gamma0, K0 = ref.stress_free_strains(x1, q1, x2, q2, Le)
    if shape == "straight":
        np.testing.assert_allclose(Gamma0, E1, atol=1e-15)
        np.testing.assert_allclose(K0, 0.0, atol=1e-15)
    q_rot = np.array([np.cos(1.3), *(np.sin(1.3) * np.array([0.6, -0.8, 0.0]))])  # 2.6 rad
    shift = np.array([10.0, -5.0, 3.0])
    y1, p1 = rotate_node(q_rot, x1, q1, shift)
    y2, p2 = rotate_node(q_rot, x2, q2, shift)
    vel = rigid_velocities(y1, p1, y2, p2, rng)
    for axial in ("tension-only", "linear"):
        section = ref.Section(**STIFFNESS, tau=1e-2, axial=axial)
        f = ref.internal_force(y1, p1, y2, p2, Le, Gamma0, K0, section, vel)
        assert np.abs(f).max() <= ROUND_OFF * STIFFNESS["EA"]


@pytest.mark.parametrize("name", STATES)
def test_superposed_rigid_motion_leaves_energy_unchanged_and_rotates_forces(name):
    gamma, overrides = STATES[name]
    rng = np.random.default_rng(8)
    x1, q1, x2, q2, *rest = make_state(rng, gamma, psi_norm=2.0)
    section = ref.Section(**STIFFNESS, **overrides, tau=1e-3)
    vel = random_velocities(rng)
    q_rot, shift = random_quat(rng), 7.0 * rng.normal(size=3)
    Q = ref.quat_to_matrix(q_rot)
    y1, p1 = rotate_node(q_rot, x1, q1, shift)
    y2, p2 = rotate_node(q_rot, x2, q2, shift)
    W = ref.energy(x1, q1, x2, q2, *rest, section)
    assert abs(ref.energy(y1, p1, y2, p2, *rest, section) - W) <= ROUND_OFF * W
    # velocities: translational ones rotate with Q, body angular velocities do not
    vel_rot = np.concatenate([Q @ vel[0:3], vel[3:6], Q @ vel[6:9], vel[9:12]])
    f = ref.internal_force(x1, q1, x2, q2, *rest, section, vel)
    f_rot = ref.internal_force(y1, p1, y2, p2, *rest, section, vel_rot)
    expected = np.concatenate([Q @ f[0:3], f[3:6], Q @ f[6:9], f[9:12]])
    np.testing.assert_allclose(f_rot, expected, atol=ROUND_OFF * np.abs(f).max())
    # a superposed rigid velocity field does not change the strain rates (objectivity of (C21))
    B = ref.b_matrix(x1, q1, x2, q2, rest[0])
    assert np.abs(B @ rigid_velocities(x1, q1, x2, q2, rng)).max() <= ROUND_OFF * np.abs(B).max()


# ----------------------------------------------------------------------------- analytic states


@pytest.mark.parametrize("axis", [0, 1, 2])
@pytest.mark.parametrize("angle", [1e-5, 0.3, 2.5])
def test_uniform_bending_and_twist_give_exact_strains(axis, angle):
    """R2 = R1 exp(kappa Le e_k) gives K = kappa e_k; x2 on the arc gives the chord stretch."""
    rng = np.random.default_rng(9)
    Le, q1, x1 = 0.2, random_quat(rng), rng.normal(size=3)
    kappa, e_k = angle / Le, np.eye(3)[axis]
    _, q2 = ref.retract_node(x1, q1, np.zeros(3), angle * e_k)
    if axis == 0:  # twist: the centreline stays straight
        chord_length, stretch = Le, 0.0
    else:  # bending: the arc's chord points along the midpoint director d1
        chord_length = 2.0 * np.sin(0.5 * angle) / kappa
        stretch = chord_length / Le - 1.0
    x2 = x1 + chord_length * ref.quat_to_matrix(q1) @ ref.so3_exp(0.5 * angle * e_k) @ E1
    Gamma, K = ref.strains(x1, q1, x2, q2, Le, E1, np.zeros(3))
    np.testing.assert_allclose(K, kappa * e_k, rtol=0, atol=ROUND_OFF * max(kappa, 1.0))
    np.testing.assert_allclose(Gamma, [stretch, 0.0, 0.0], rtol=0, atol=ROUND_OFF)


def test_relative_rotation_at_pi_is_refused():
    q1 = random_quat(np.random.default_rng(10))
    _, q2 = ref.retract_node(np.zeros(3), q1, np.zeros(3), (np.pi - 1e-8) * E3)
    with pytest.raises(ValueError, match="psi"):
        ref.strains(np.zeros(3), q1, 0.1 * E1, q2, 0.1, E1, np.zeros(3))


def test_ramp_is_c1_with_a_c2_integral():
    """(C22), (C23): r, r' and Rint are continuous at the kinks 0 and delta; Rint' = r."""
    delta = 0.1
    for kink in (0.0, delta):
        below, above = ref.ramp(kink - 1e-13, delta), ref.ramp(kink + 1e-13, delta)
        np.testing.assert_allclose(below, above, rtol=0, atol=1e-9)
    for e in (0.3 * delta, 0.7 * delta, 2 * delta, 0.05):
        r, dr, _ = ref.ramp(e, delta)
        assert derivative(lambda s: ref.ramp(s, delta)[2], e, 1e-8) == pytest.approx(r, rel=1e-6)
        assert derivative(lambda s: ref.ramp(s, delta)[0], e, 1e-8) == pytest.approx(dr, rel=1e-6)
    assert ref.ramp(-0.1, delta) == (0.0, 0.0, 0.0)


def test_tension_only_axial_force_never_pushes():
    """Random states incl. fast shortening: N0 >= 0; the clamp is exercised; linear would push."""
    rng = np.random.default_rng(11)
    tension_only = ref.Section(**STIFFNESS, tau=2e-3)
    linear = ref.Section(**STIFFNESS, tau=2e-3, axial="linear")
    clamped = pulled = 0
    for _ in range(300):
        args = make_state(rng, [rng.uniform(-0.02, 0.02), *rng.uniform(-0.01, 0.01, size=2)])
        vel = rng.normal(size=12) * np.array([10, 10, 10, 50, 50, 50] * 2) * rng.uniform(0, 1)
        Gamma, K = ref.strains(*args)
        rates = ref.b_matrix(*args[:5]) @ vel
        N, _ = ref.stress_resultants(Gamma, K, rates[:3], rates[3:], tension_only)
        N_linear, _ = ref.stress_resultants(Gamma, K, rates[:3], rates[3:], linear)
        assert N[0] >= 0.0
        if Gamma[0] <= 0.0:
            assert N[0] == 0.0  # a slack thread neither pushes nor pulls, whatever its rate
            continue
        # past the kink the ramp is the linear law lowered by EA delta / 2, then clamped (C22)
        shifted = N_linear[0] - 0.5 * tension_only.EA * tension_only.delta
        assert N[0] == pytest.approx(max(0.0, shifted), rel=1e-12, abs=1e-12)
        if N_linear[0] < 0.0:
            assert N[0] == 0.0  # taut but shortening fast: the Kelvin-Voigt total is clamped
            clamped += 1
        else:
            pulled += 1
    assert clamped > 10 and pulled > 10


# ----------------------------------------------------------------------------- inertia


def test_lumped_inertia_and_euler_equations():
    m, J = ref.lumped_node_inertia(0.2, 3.0, np.array([2e-3, 1e-3, 1e-3]))
    assert m == pytest.approx(0.3) and np.allclose(J, [2e-4, 1e-4, 1e-4])
    J, W, W_dot = np.array([1.0, 2.0, 3.0]), np.array([0.7, -1.1, 0.4]), np.array([0.2, 0.3, -0.5])
    a = np.array([1.0, -2.0, 0.5])
    f = ref.node_inertial_force(m, J, a, W, W_dot)
    euler = [J[0] * W_dot[0] - (J[1] - J[2]) * W[1] * W[2],
             J[1] * W_dot[1] - (J[2] - J[0]) * W[2] * W[0],
             J[2] * W_dot[2] - (J[0] - J[1]) * W[0] * W[1]]
    np.testing.assert_allclose(f, np.concatenate([m * a, euler]), rtol=ROUND_OFF)
    fd = np.column_stack([derivative(lambda s: np.cross(W + s * e, J * (W + s * e)), 0.0, 1e-6)
                          for e in np.eye(3)])
    np.testing.assert_allclose(ref.gyroscopic_matrix(J, W), fd, atol=1e-9)


# ----------------------------------------------------------------------------- golden data

GOLDEN = json.loads((ELEMENT_DIR / "golden.json").read_text())


@pytest.mark.parametrize("case", GOLDEN["cases"], ids=lambda case: case["name"])
def test_golden_data_reproduces(case):
    inputs, expected = case["inputs"], case["outputs"]
    args = tuple(np.asarray(inputs[k]) if k != "Le" else inputs[k]
                 for k in ("x1", "q1", "x2", "q2", "Le", "Gamma0", "K0"))
    vel = None if inputs["velocities"] is None else np.asarray(inputs["velocities"])
    section = ref.Section(**inputs["section"])
    Gamma, K = ref.strains(*args)
    computed = dict(
        Gamma=Gamma, K=K, energy=ref.energy(*args, section), B=ref.b_matrix(*args[:5]),
        internal_force=ref.internal_force(*args, section, vel),
        damping_matrix=ref.damping_matrix(*args, section, vel),
    )
    for key, value in computed.items():
        want = np.asarray(expected[key])
        atol = ROUND_OFF * max(np.abs(want).max(), 1.0)
        np.testing.assert_allclose(value, want, rtol=0, atol=atol, err_msg=key)
    K_T = np.asarray(expected["tangent_fd"])
    K_T_now = ref.tangent_fd(*args, section, vel)
    np.testing.assert_allclose(K_T_now, K_T, rtol=0, atol=1e-9 * np.abs(K_T).max())
