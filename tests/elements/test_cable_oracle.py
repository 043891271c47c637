"""The cable element oracle (elements/cable/reference.py) against its own physics.

Checks are finite differences, invariants, the bridges to the lumped spring and to the Cosserat
element, and the frozen golden data. Round-off checks use 1e-12 relative, finite-difference
checks 1e-7 relative.
"""

import importlib.util
import json
import sys
from pathlib import Path

import numpy as np
import pytest

ELEMENTS = Path(__file__).resolve().parents[2] / "elements"


def _load_reference(formulation):
    path = ELEMENTS / formulation / "reference.py"
    spec = importlib.util.spec_from_file_location(f"{formulation}_reference", path)
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module
    spec.loader.exec_module(module)
    return module


ref = _load_reference("cable")
cosserat = _load_reference("cosserat")
ROUND_OFF = 1e-12
FD_RTOL = 1e-7

STATES = {  # name: (strain, section overrides); all clear of the kinks at 0 and delta
    "taut": (0.02, {}),
    "slack": (-0.03, {}),
    "inside ramp": (0.02, dict(delta=0.05)),
    "linear compressed": (-0.02, dict(axial="linear")),
}


def make_state(rng, strain, strain_rate=0.0, Le=0.1):
    """Positions and velocities with chord strain ``strain``, chord strain rate ``strain_rate``."""
    t = rng.normal(size=3)
    t /= np.linalg.norm(t)
    transverse = np.cross(t, rng.normal(size=3))
    x1, v1 = rng.normal(size=3), rng.normal(size=3)
    return x1, x1 + (1.0 + strain) * Le * t, v1, v1 + strain_rate * Le * t + transverse, Le


def derivative(fun, x, h):
    return (fun(x + h) - fun(x - h)) / (2 * h)


def random_rotation(rng):
    q = rng.normal(size=4)
    w, x, y, z = q / np.linalg.norm(q)
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                     [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                     [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])


def test_ramp_is_c1_with_a_c2_integral():
    """(CB5): r, r' and Rint are continuous at the kinks 0 and delta; Rint' = r and r' = r''."""
    delta = 0.1
    for kink in (0.0, delta):
        below, above = ref.ramp(kink - 1e-13, delta), ref.ramp(kink + 1e-13, delta)
        np.testing.assert_allclose(below[:2] + below[3:], above[:2] + above[3:], rtol=0, atol=1e-9)
    for e in (0.3 * delta, 0.7 * delta, 2 * delta, 0.05):
        r, dr, ddr, _ = ref.ramp(e, delta)
        for k, slope in ((3, r), (0, dr), (1, ddr)):
            fd = derivative(lambda s: ref.ramp(s, delta)[k], e, 1e-8)
            assert fd == pytest.approx(slope, rel=1e-6, abs=1e-6)
    assert ref.ramp(-0.1, delta) == (0.0, 0.0, 0.0, 0.0)


@pytest.mark.parametrize("name", STATES)
def test_internal_force_is_the_gradient_of_the_energy(name):
    strain, overrides = STATES[name]
    rng = np.random.default_rng(1)
    x1, x2, _, _, Le = make_state(rng, strain)
    section = ref.CableSection(EA=1e3, **overrides)
    f = ref.internal_force(x1, x2, Le, section)
    for _ in range(6):
        u = Le * rng.normal(size=6)
        along_u = lambda s: ref.energy(x1 + s * u[:3], x2 + s * u[3:], Le, section)  # noqa: E731
        dW = derivative(along_u, 0.0, 1e-6)
        assert abs(dW - f @ u) <= FD_RTOL * max(np.linalg.norm(f) * np.linalg.norm(u), 1e-30)
    if name == "slack":
        assert np.all(f == 0.0)


@pytest.mark.parametrize("name", STATES)
@pytest.mark.parametrize("strain_rate", [0.0, 3.0, -2.0])
def test_analytic_tangents_match_finite_differences(name, strain_rate):
    strain, overrides = STATES[name]
    x1, x2, v1, v2, Le = make_state(np.random.default_rng(2), strain, strain_rate)
    section = ref.CableSection(EA=1e3, tau=2e-3, **overrides)
    K_T = ref.tangent_stiffness(x1, x2, Le, section, v1, v2)
    C_T = ref.damping_matrix(x1, x2, Le, section, v1, v2)
    scale = max(np.abs(K_T).max(), 1.0)
    K_fd = ref.tangent_fd(x1, x2, Le, section, v1, v2)
    C_fd = ref.damping_fd(x1, x2, Le, section, v1, v2)
    np.testing.assert_allclose(K_fd, K_T, rtol=0, atol=FD_RTOL * scale)
    np.testing.assert_allclose(C_fd, C_T, rtol=0, atol=FD_RTOL * scale)


def test_tension_only_axial_force_never_pushes():
    """Random states incl. fast shortening: N >= 0; the clamp is exercised; linear would push."""
    rng = np.random.default_rng(3)
    tension_only = ref.CableSection(EA=1e3, tau=2e-3)
    linear = ref.CableSection(EA=1e3, tau=2e-3, axial="linear")
    clamped = pulled = 0
    for _ in range(300):
        x1, x2, v1, v2, Le = make_state(rng, rng.uniform(-0.02, 0.02), rng.uniform(-50.0, 50.0))
        f = ref.internal_force(x1, x2, Le, tension_only, v1, v2)
        _, e, t, e_rate = ref.kinematics(x1, x2, Le, v1, v2)
        N = f[3:] @ t
        assert N >= 0.0
        np.testing.assert_allclose(f, np.concatenate([-N * t, N * t]), rtol=0, atol=ROUND_OFF * 1e3)
        if e <= 0.0:
            assert N == 0.0
        elif ref.axial_force(e, e_rate, linear) < 0.0:
            assert N == 0.0
            clamped += 1
        else:
            pulled += 1
    assert clamped > 10 and pulled > 10


def test_rigid_motion_rotates_the_force_and_keeps_the_energy():
    rng = np.random.default_rng(4)
    section = ref.CableSection(EA=1e3, tau=2e-3)
    x1, x2, v1, v2, Le = make_state(rng, 0.02, 1.5)
    Q, shift = random_rotation(rng), 5.0 * rng.normal(size=3)
    y1, y2 = Q @ x1 + shift, Q @ x2 + shift
    W = ref.energy(x1, x2, Le, section)
    assert abs(ref.energy(y1, y2, Le, section) - W) <= ROUND_OFF * W
    f = ref.internal_force(x1, x2, Le, section, v1, v2)
    f_rot = ref.internal_force(y1, y2, Le, section, Q @ v1, Q @ v2)
    expected = np.concatenate([Q @ f[:3], Q @ f[3:]])
    np.testing.assert_allclose(f_rot, expected, rtol=0, atol=ROUND_OFF * np.abs(f).max())
    # a rigid velocity field (translation + spin) has no strain rate, so no viscous force
    c, w = rng.normal(size=3), 5.0 * rng.normal(size=3)
    f_spin = ref.internal_force(y1, y2, Le, section, c + np.cross(w, y1), c + np.cross(w, y2))
    f_static = ref.internal_force(y1, y2, Le, section)
    np.testing.assert_allclose(f_spin, f_static, rtol=0, atol=ROUND_OFF * np.abs(f_static).max())
    # stress-free under a large rigid motion: no force at all
    z1 = rng.normal(size=3)
    z2 = z1 + Le * Q @ np.array([0.6, 0.0, 0.8])
    f_free = ref.internal_force(z1, z2, Le, section, c + np.cross(w, z1), c + np.cross(w, z2))
    assert np.abs(f_free).max() <= ROUND_OFF * section.EA


def test_linear_law_is_the_lumped_spring():
    """(CB13): N = k (l - Le) + c dl/dt with k = EA/Le, c = tau EA/Le."""
    rng = np.random.default_rng(5)
    section = ref.CableSection(EA=800.0, tau=3e-3, axial="linear")
    for strain, rate in [(0.01, 2.0), (-0.02, -4.0), (0.005, -30.0)]:
        x1, x2, v1, v2, Le = make_state(rng, strain, rate)
        length = np.linalg.norm(x2 - x1)
        t = (x2 - x1) / length
        k, c = section.EA / Le, section.tau * section.EA / Le
        N = k * (length - Le) + c * t @ (v2 - v1)
        np.testing.assert_allclose(ref.internal_force(x1, x2, Le, section, v1, v2),
                                   np.concatenate([-N * t, N * t]), rtol=1e-12, atol=1e-12 * abs(N))


@pytest.mark.parametrize("axial", ["tension-only", "linear"])
@pytest.mark.parametrize("strain, rate", [(0.02, 1.0), (0.01, -20.0), (-0.01, 2.0)])
def test_cable_equals_aligned_cosserat_element(axial, strain, rate):
    """A straight Cosserat element with R1 = R2 and the chord along d1 carries the cable force."""
    rng = np.random.default_rng(6)
    q = rng.normal(size=4)
    q /= np.linalg.norm(q)
    d1, Le = cosserat.quat_to_matrix(q)[:, 0], 0.1
    x1, v1 = rng.normal(size=3), rng.normal(size=3)
    x2, v2 = x1 + (1.0 + strain) * Le * d1, v1 + rate * Le * d1
    rod = cosserat.Section(EA=1e3, GA2=4e2, GA3=4e2, GJ=1e-2, EI2=2e-2, EI3=2e-2, tau=2e-3,
                           axial=axial)
    f_rod = cosserat.internal_force(x1, q, x2, q, Le, np.array([1.0, 0, 0]), np.zeros(3), rod,
                                    np.concatenate([v1, np.zeros(3), v2, np.zeros(3)]))
    cable = ref.CableSection(EA=1e3, tau=2e-3, axial=axial)
    f_cable = ref.internal_force(x1, x2, Le, cable, v1, v2)
    atol = ROUND_OFF * max(np.abs(f_cable).max(), 1.0)
    np.testing.assert_allclose(f_rod[[0, 1, 2, 6, 7, 8]], f_cable, rtol=0, atol=atol)
    np.testing.assert_allclose(f_rod[[3, 4, 5, 9, 10, 11]], 0.0, atol=atol)


def test_lumped_mass():
    m = ref.lumped_node_mass(0.2, 3.0)
    assert 2 * m == pytest.approx(0.6)  # both ends together carry the element's mass
    f = ref.node_inertial_force(m, np.array([1.0, -2.0, 0.5]))
    np.testing.assert_allclose(f, [0.3, -0.6, 0.15], rtol=ROUND_OFF)


GOLDEN = json.loads((ELEMENTS / "cable" / "golden.json").read_text())


@pytest.mark.parametrize("case", GOLDEN["cases"], ids=lambda case: case["name"])
def test_golden_data_reproduces(case):
    inputs, expected = case["inputs"], case["outputs"]
    x1, x2, v1, v2 = (np.asarray(inputs[k]) for k in ("x1", "x2", "v1", "v2"))
    Le, section = inputs["Le"], ref.CableSection(**inputs["section"])
    _, e, _, e_rate = ref.kinematics(x1, x2, Le, v1, v2)
    computed = dict(
        strain=e, strain_rate=e_rate, axial_force=ref.axial_force(e, e_rate, section),
        energy=ref.energy(x1, x2, Le, section),
        internal_force=ref.internal_force(x1, x2, Le, section, v1, v2),
        tangent_stiffness=ref.tangent_stiffness(x1, x2, Le, section, v1, v2),
        damping_matrix=ref.damping_matrix(x1, x2, Le, section, v1, v2),
        tangent_fd=ref.tangent_fd(x1, x2, Le, section, v1, v2),
    )
    for key, value in computed.items():
        want = np.asarray(expected[key])
        rel = 1e-9 if key == "tangent_fd" else ROUND_OFF
        atol = rel * max(np.abs(want).max(), 1.0)
        np.testing.assert_allclose(value, want, rtol=0, atol=atol, err_msg=key)
