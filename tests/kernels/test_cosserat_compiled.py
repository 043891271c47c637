"""The compiled Cosserat kernels against the NumPy path, element by element.

Random states mix, per element, every branch of the two paths: relative rotations of exactly zero,
below 1e-8 (series logarithm), on both sides of the series switches of the coefficients, up to
within 1e-6 of pi and, with the second quaternion's sign flipped, past pi on the double cover
(C11); both quaternions of an element may change sign together (nothing changes then); axial strains slack, inside the tension-only
ramp and taut, and axial strain rates that make the Kelvin-Voigt total negative (clamp).

The two paths take atan2 and tan from different libraries (NumPy's loops, libm), so their
kinematics agree to a few ulp, not bit for bit. Everything is compared at 1e-12 relative per
element. Inside the ramp the tangents carry the axial modulus ``EA e / kink``, which turns the
last bit of ``e`` into ``~EA ulp / kink``: with the 1e-2 ramp of the main cases that stays near
1e-13 of the tangent. Force, energy and resultants are also checked with the default 1e-6 ramp
and the sharp kink; there the damped force gets the same allowance, ``dN_0/de`` times the last
bits of ``e``.
"""

import numpy as np
import pytest

from rodnet.kernels import cosserat, cosserat_tangent, cosserat_tangent_compiled, so3
from rodnet.kernels.cosserat_strain import kinematics, reduce_velocity, strain_rates_from_kinematics

TENSION_ONLY, LINEAR = True, False
KINK = 1e-2
RTOL = 1e-12


def random_quats(rng, n):
    return so3.quat_normalize(rng.normal(size=(n, 4)))


def unit_vectors(rng, n):
    v = rng.normal(size=(n, 3))
    return v / np.linalg.norm(v, axis=1, keepdims=True)


def relative_angles(rng, n):
    """Angles of the relative rotation, cycling through the branches of log, beta and gamma."""
    kinds = [
        np.zeros(n),                                    # psi = 0 exactly
        10.0 ** rng.uniform(-14.0, -8.0, n),            # |psi| < 1e-8
        rng.uniform(1e-3, 0.5, n),                      # series coefficients
        rng.uniform(0.5, 3.0, n),                       # closed forms
        np.pi - 10.0 ** rng.uniform(-6.0, -2.0, n),     # near pi
    ]
    return np.choose(np.arange(n) % len(kinds), kinds)


def axial_strains(rng, n):
    """Slack, inside the ramp ``0 < e < KINK``, taut, and material axis against the chord
    (``e < -1``, (C51)) beyond and inside the mirrored ramp, cycling."""
    kinds = [rng.uniform(-0.2, -1e-2, n), KINK * rng.uniform(0.05, 0.95, n),
             rng.uniform(2 * KINK, 0.3, n), rng.uniform(-1.4, -1.0 - 2 * KINK, n),
             -1.0 - KINK * rng.uniform(0.05, 0.95, n)]
    return np.choose(np.arange(n) % 5, kinds)


def set_chord(x, q, rest_length, reference_strain, gamma):
    """Move node 2 so that the element has exactly the strains ``gamma`` (n, 3)."""
    R_m = kinematics(x, q)[1]
    x = x.copy()
    x[:, 1] = x[:, 0] + np.einsum("nij,nj->ni", R_m,
                                  rest_length[:, None] * (reference_strain[:, :3] + gamma))
    return x


def random_state(rng, n, tau):
    """Model ``(rest_length, reference_strain, stiffness, tau)`` and state ``(x, q, velocity)``."""
    rest_length = rng.uniform(0.5, 1.5, n)
    # curved stress-free geometry
    q1 = random_quats(rng, n)
    kappa0 = unit_vectors(rng, n) * rng.uniform(0.0, 1.0, (n, 1))
    q0 = np.stack([q1, so3.retract(q1, kappa0)], axis=1)
    x1 = rng.normal(size=(n, 3))
    chord = np.array([1.0, 0.0, 0.0]) + 0.1 * rng.normal(size=(n, 3))
    x0 = np.stack([x1, x1 + rest_length[:, None] * chord], axis=1)
    reference_strain = cosserat.reference_strains(rest_length, x0, q0)
    # deformed state; an element's quaternions may change sign together, and a second quaternion
    # with the other sign turns the element by 2 pi - angle (between 3.3 and 6 rad here)
    q1 = random_quats(rng, n)
    angles = relative_angles(rng, n)
    q2 = so3.retract(q1, unit_vectors(rng, n) * angles[:, None])
    past_pi = (angles > 0.3) & (angles < 3.0) & (rng.random(n) < 0.3)
    q2[past_pi] *= -1.0
    q = np.stack([q1, q2], axis=1) * rng.choice([-1.0, 1.0], size=(n, 1, 1))
    gamma = np.column_stack([axial_strains(rng, n), 0.1 * rng.normal(size=(n, 2))])
    x = set_chord(x0 + rng.normal(size=x0.shape), q, rest_length, reference_strain, gamma)
    stiffness = rng.uniform(0.5, 2.0, (n, 6)) * np.array([10.0, 4.0, 4.0, 1.0, 1.5, 1.5])
    # every fourth element shortens fast enough that the Kelvin-Voigt total would push (clamp)
    velocity = rng.normal(size=(n, 12))
    psi, R_m, g = kinematics(x, q)
    rate = strain_rates_from_kinematics(psi, R_m, g, reduce_velocity(velocity), rest_length)[:, 0]
    target = np.where(np.arange(n) % 4 == 0, -rng.uniform(2.0, 20.0, n), rate)
    velocity[:, 6:9] += R_m[:, :, 0] * (rest_length * (target - rate))[:, None]
    return (rest_length, reference_strain, stiffness, np.full(n, tau)), (x, q, velocity)


def assert_close(actual, expected, rtol=RTOL, atol=0.0):
    """Per element: ``max |actual - expected| <= rtol max |expected| + atol``; atol () or (n,)."""
    assert actual.shape == expected.shape
    assert np.all(np.isfinite(actual))
    axes = tuple(range(1, expected.ndim))
    error = np.abs(actual - expected).max(axis=axes, initial=0.0)
    bound = rtol * np.abs(expected).max(axis=axes, initial=0.0) + atol
    assert np.all(error <= bound), f"error up to {np.max(error / bound):.3g} times the bound"


CASES = [(law, tau) for law in (LINEAR, TENSION_ONLY) for tau in (0.0, 0.05)]
CASE_IDS = [f"{'tension-only' if law else 'linear'}, tau={tau}" for law, tau in CASES]


@pytest.fixture(scope="module", params=CASES, ids=CASE_IDS)
def case(request):
    tension_only, tau = request.param
    model, state = random_state(np.random.default_rng(11), 600, tau)
    return model, state, (tension_only, KINK)


def test_states_cover_the_branches(case):
    model, (x, q, velocity), (tension_only, kink) = case
    rest_length, reference_strain, stiffness, tau = model
    angle = np.linalg.norm(kinematics(x, q)[0], axis=1)
    assert np.any(angle == 0.0) and np.any((angle > 0.0) & (angle < 1e-8))
    assert np.any((angle > 0.01) & (angle < 0.5)) and np.any((angle > 0.5) & (angle < 3.0))
    assert np.any((angle > np.pi - 1e-5) & (angle < np.pi))
    # w of conj(q1) q2 is negative: the relative rotation has passed pi
    w = q[:, 0, 0] * q[:, 1, 0] + np.sum(q[:, 0, 1:] * q[:, 1, 1:], axis=1)
    assert np.any(w < 0.0) and np.all((angle > np.pi) == (w < 0.0))
    assert np.any(angle > 5.0)
    psi, R_m, g = kinematics(x, q)
    strain = cosserat.strains(rest_length, reference_strain, x, q)
    e = strain[:, 0]
    assert np.any(e < 0.0) and np.any((e > 0.0) & (e < kink)) and np.any(e > kink)
    assert np.any(e < -1.0 - kink) and np.any((e < -1.0) & (e > -1.0 - kink))
    if tension_only and tau[0] > 0.0:
        rate = strain_rates_from_kinematics(psi, R_m, g, reduce_velocity(velocity), rest_length)
        N = cosserat.stress_resultants_numpy(stiffness, tau, strain, rate, tension_only, kink)[:, 0]
        clamped = (e > 0.0) & (N == 0.0)
        assert np.any(clamped & (e < kink)) and np.any(clamped & (e > kink))
        assert np.any((e > 0.0) & (e < kink) & (N > 0.0))


def test_internal_force_matches_numpy(case):
    model, state, law = case
    assert_close(cosserat.internal_force(*model, *state, *law),
                 cosserat.internal_force_numpy(*model, *state, *law))


def test_internal_force_and_tangents_match_numpy(case):
    model, state, law = case
    compiled = cosserat.internal_force_and_tangents(*model, *state, *law)
    reference = cosserat.internal_force_and_tangents_numpy(*model, *state, *law)
    for actual, expected in zip(compiled[:2], reference[:2]):
        assert_close(actual, expected)
    if model[3][0] == 0.0:
        np.testing.assert_array_equal(compiled[2], 0.0)
        np.testing.assert_array_equal(reference[2], 0.0)
    else:
        assert_close(compiled[2], reference[2])
    # the two compiled entry points share the force loop
    np.testing.assert_array_equal(compiled[0], cosserat.internal_force(*model, *state, *law))


def test_strain_energy_matches_numpy(case):
    (rest_length, reference_strain, stiffness, _), (x, q, _), law = case
    args = (rest_length, reference_strain, stiffness, x, q, *law)
    energy = cosserat.strain_energy(*args)
    assert_close(energy[:, None], cosserat.strain_energy_numpy(*args)[:, None])


@pytest.mark.parametrize("tau", [0.0, 0.05])
@pytest.mark.parametrize("kink", [0.0, 1e-6, 1e-3])
@pytest.mark.parametrize("tension_only", [LINEAR, TENSION_ONLY])
def test_force_energy_and_resultants_match_numpy_for_other_ramps(tension_only, kink, tau):
    rng = np.random.default_rng(12)
    model, (x, q, velocity) = random_state(rng, 300, tau)
    strain = cosserat.strains(model[0], model[1], x, q)
    if kink > 0.0:  # move the ramp elements into this ramp
        ramp = (strain[:, 0] > 0.0) & (strain[:, 0] < KINK)
        gamma = strain[:, :3].copy()
        gamma[ramp, 0] *= kink / KINK
        x = set_chord(x, q, model[0], model[1], gamma)
    rest_length, reference_strain, stiffness, tau = model
    strain = cosserat.strains(rest_length, reference_strain, x, q)
    assert np.any((strain[:, 0] > 0.0) & (strain[:, 0] < kink)) or kink == 0.0
    rate = rng.normal(size=strain.shape)
    law = (tension_only, kink)
    assert_close(cosserat.stress_resultants(stiffness, tau, strain, rate, *law),
                 cosserat.stress_resultants_numpy(stiffness, tau, strain, rate, *law))
    energy_args = (rest_length, reference_strain, stiffness, x, q, *law)
    assert_close(cosserat.strain_energy(*energy_args)[:, None],
                 cosserat.strain_energy_numpy(*energy_args)[:, None])
    # dN_0/de holds tau EA de/dt / kink inside the ramp: the last bits of e, in which the two paths
    # differ, reach the (damped) force through it, both directly and through h = N x g
    psi, R_m, g = kinematics(x, q)
    rates = strain_rates_from_kinematics(psi, R_m, g, reduce_velocity(velocity), rest_length)
    modulus = cosserat.stress_resultants_and_moduli(stiffness, tau, strain, rates, *law)[1][:, 0]
    last_bits = 8.0 * np.finfo(float).eps * (np.abs(g[:, 0]) / rest_length
                                              + np.abs(reference_strain[:, 0]))
    assert_close(cosserat.internal_force(*model, x, q, velocity, *law),
                 cosserat.internal_force_numpy(*model, x, q, velocity, *law),
                 atol=np.abs(modulus) * last_bits * (1.0 + np.linalg.norm(g, axis=1)))


def test_compiled_tangent_assembly_from_given_kinematics_matches_numpy():
    model, (x, q, velocity) = random_state(np.random.default_rng(13), 60, 0.05)
    rest_length, reference_strain, stiffness, tau = model
    psi, R_m, g = kinematics(x, q)
    velocity9 = reduce_velocity(velocity)
    strain = cosserat.strains(rest_length, reference_strain, x, q)
    rate = strain_rates_from_kinematics(psi, R_m, g, velocity9, rest_length)
    response = cosserat.stress_resultants_and_moduli(stiffness, tau, strain, rate, TENSION_ONLY,
                                                     KINK)
    args = (psi, R_m, g, *response, velocity9, rest_length)
    for actual, expected in zip(cosserat_tangent_compiled.tangents(*args),
                                cosserat_tangent.tangents(*args)):
        assert_close(actual, expected)


def test_inputs_are_converted_and_shapes_checked():
    model, (x, q, velocity) = random_state(np.random.default_rng(14), 10, 0.05)
    law = (np.bool_(True), KINK)
    expected = cosserat.internal_force_numpy(*model, x, q, velocity, *law)
    # Fortran order, a strided view and a Python list all give the same force
    x_f = np.asfortranarray(x)
    q_strided = np.concatenate([q, q], axis=2)[:, :, :4]
    velocity_list = velocity.tolist()
    assert_close(cosserat.internal_force(*model, x_f, q_strided, velocity_list, *law), expected)
    with pytest.raises(ValueError, match="shapes"):
        cosserat.internal_force(*model, x[:-1], q, velocity, *law)
    with pytest.raises(ValueError, match="shapes"):
        cosserat.internal_force_and_tangents(*model, x, q, velocity[:, :9], *law)
    with pytest.raises(ValueError, match="shapes"):
        cosserat.strain_energy(model[0], model[1], model[2][:, :3], x, q, *law)


def test_no_elements():
    model, (x, q, velocity) = random_state(np.random.default_rng(15), 4, 0.05)
    empty = [a[:0] for a in (*model, x, q, velocity)]
    assert cosserat.internal_force(*empty, TENSION_ONLY, KINK).shape == (0, 12)
    f, K, C = cosserat.internal_force_and_tangents(*empty, TENSION_ONLY, KINK)
    assert f.shape == (0, 12) and K.shape == C.shape == (0, 12, 12)
    assert cosserat.strain_energy(*empty[:3], *empty[4:6], TENSION_ONLY, KINK).shape == (0,)


def test_one_thread_and_parallel_kernels_agree_to_the_bit(case):
    """On one thread the force and tangent kernels run the serial element passes without a
    parallel region; with a step's strain rates and the mixed step's strain shift (the implicit
    path's arguments) they must give the parallel kernels' arrays exactly."""
    import numba

    from rodnet.kernels import cosserat_compiled, threads

    if threads.available() < 2:
        pytest.skip("one core: no parallel kernels to compare with")
    model, state, law = case
    rng = np.random.default_rng(5)
    n = len(model[0])
    step = (rng.normal(scale=0.01, size=(n, 6)), 250.0)
    shift = rng.normal(scale=1e-3, size=(n, 6))
    before = numba.get_num_threads()
    out = {}
    try:
        for count in (1, threads.available()):
            numba.set_num_threads(count)
            out[count] = (cosserat_compiled.internal_force(*model, *state, *law, step),
                          *cosserat_compiled.internal_force_and_tangents(*model, *state, *law,
                                                                          step, shift))
    finally:
        numba.set_num_threads(before)
    for serial, parallel in zip(out[1], out[threads.available()]):
        np.testing.assert_array_equal(serial, parallel)
