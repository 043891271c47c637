"""Linear beam reference (scikit-fem) against closed-form beam and bar results.

Tolerances are relative and set by the discretisation at the element count used: Hermite
(Euler-Bernoulli), P2 x P2 (Timoshenko) and P2 bar frequencies and buckling loads converge as
h^4, so 64 elements give better than 1e-6 on the first three modes; static deflections of these
elements are exact at the nodes and are checked to round-off (1e-9).
"""

import numpy as np
import pytest

from rodnet.reference.beam_skfem import (axial_frequencies, buckling_load, natural_frequencies,
                                         static_deflection)

# cantilever: 1.5 m polyamide thread, d = 1 mm
L, EI, RHO_A = 1.5, 1.2272e-4, 9.0321e-4
# stubby steel beam: 1 m long, 0.1 m x 0.1 m square section, nu = 0.3, shear coefficient 5/6
STEEL_E, STEEL_RHO, SIDE = 2.0e11, 7850.0, 0.1
S_EI = STEEL_E * SIDE**4 / 12
S_GA = 5.0 / 6.0 * STEEL_E / 2.6 * SIDE**2
S_RHO_A, S_RHO_I = STEEL_RHO * SIDE**2, STEEL_RHO * SIDE**4 / 12

FREQ_RTOL = 1e-6
STATIC_RTOL = 1e-9


def beam_frequency(beta_l, length=L, ei=EI, rho_a=RHO_A):
    """f = (beta L)^2 / (2 pi L^2) sqrt(EI / rhoA) [Hz]."""
    return np.asarray(beta_l) ** 2 / (2 * np.pi * length**2) * np.sqrt(ei / rho_a)


def test_cantilever_frequencies():
    f = natural_frequencies(L, EI, RHO_A, n_modes=3, supports=("clamp", "free"), n_elements=64)
    exact = beam_frequency([1.875104069, 4.694091133, 7.854757438])
    np.testing.assert_allclose(f, exact, rtol=FREQ_RTOL)


def test_simply_supported_frequencies():
    f = natural_frequencies(L, EI, RHO_A, n_modes=3, supports=("pin", "pin"), n_elements=64)
    n = np.arange(1, 4)
    exact = n**2 * np.pi / (2 * L**2) * np.sqrt(EI / RHO_A)
    np.testing.assert_allclose(f, exact, rtol=FREQ_RTOL)


def test_free_free_frequencies_start_with_two_rigid_modes():
    f = natural_frequencies(L, EI, RHO_A, n_modes=5, supports=("free", "free"), n_elements=64)
    elastic = beam_frequency([4.730040745, 7.853204624, 10.99560784])
    np.testing.assert_allclose(f[2:], elastic, rtol=FREQ_RTOL)
    # omega^2 of a rigid mode is zero to round-off, so f is zero only to its square root
    assert np.all(f[:2] < 1e-4 * elastic[0])


@pytest.mark.parametrize("supports, factor", [(("pin", "pin"), 1.0), (("clamp", "free"), 0.25),
                                              (("clamp", "clamp"), 4.0)])
def test_euler_buckling_loads(supports, factor):
    p = buckling_load(L, EI, supports=supports, n_elements=64)
    assert p == pytest.approx(factor * np.pi**2 * EI / L**2, rel=FREQ_RTOL)


def test_cantilever_tip_force_deflection():
    force = 2e-4
    w, tip = static_deflection(L, EI, ("clamp", "free"), tip_force=force, n_elements=16)
    s = np.linspace(0, L, 17)
    np.testing.assert_allclose(w, force * s**2 * (3 * L - s) / (6 * EI), rtol=STATIC_RTOL, atol=0)
    assert tip == pytest.approx(force * L**3 / (3 * EI), rel=STATIC_RTOL)


def test_cantilever_distributed_load_deflection():
    q = 1e-4
    w, tip = static_deflection(L, EI, ("clamp", "free"), distributed_load=q, n_elements=16)
    s = np.linspace(0, L, 17)
    exact = q * s**2 * (6 * L**2 - 4 * L * s + s**2) / (24 * EI)
    np.testing.assert_allclose(w, exact, rtol=STATIC_RTOL, atol=0)
    assert tip == pytest.approx(q * L**4 / (8 * EI), rel=STATIC_RTOL)


def test_simply_supported_midspan_deflection():
    q = 1e-4
    w, tip = static_deflection(L, EI, ("pin", "pin"), distributed_load=q, n_elements=16)
    assert w[8] == pytest.approx(5 * q * L**4 / (384 * EI), rel=STATIC_RTOL)
    assert abs(tip) < 1e-12 * w[8]


@pytest.mark.parametrize("supports, quarter_waves", [(("clamp", "free"), [1, 3, 5]),
                                                     (("clamp", "pin"), [2, 4, 6]),
                                                     (("free", "free"), [0, 2, 4])])
def test_axial_frequencies_p2(supports, quarter_waves):
    ea = 1e3
    c = np.sqrt(ea / RHO_A)
    f = axial_frequencies(L, ea, RHO_A, supports=supports, n_modes=3, n_elements=64)
    exact = np.array(quarter_waves) * c / (4 * L)
    np.testing.assert_allclose(f, exact, rtol=FREQ_RTOL, atol=FREQ_RTOL * exact[-1])


def test_axial_frequencies_p1_converge_at_second_order():
    ea = 1e3
    exact = np.sqrt(ea / RHO_A) / (4 * L)
    errors = [axial_frequencies(L, ea, RHO_A, n_modes=1, n_elements=n, order=1)[0] / exact - 1
              for n in (32, 64)]
    assert 0 < errors[1] < 1e-4
    assert np.log2(errors[0] / errors[1]) == pytest.approx(2.0, abs=0.01)


def test_timoshenko_simply_supported_matches_closed_form():
    # w = W sin(k s), theta = T cos(k s): det of the 2x2 system is a quadratic in omega^2
    k = np.arange(1, 4) * np.pi
    a = S_RHO_A * S_RHO_I
    b = -(S_RHO_A * (S_EI * k**2 + S_GA) + S_RHO_I * S_GA * k**2)
    c = S_GA * S_EI * k**4
    exact = np.sqrt((-b - np.sqrt(b**2 - 4 * a * c)) / (2 * a)) / (2 * np.pi)
    f = natural_frequencies(1.0, S_EI, S_RHO_A, n_modes=3, supports=("pin", "pin"), GA=S_GA,
                            rhoI=S_RHO_I, n_elements=128, model="timoshenko")
    np.testing.assert_allclose(f, exact, rtol=1e-7)


def test_timoshenko_tends_to_euler_bernoulli_for_slender_beams():
    f_eb = natural_frequencies(1.0, 1.0, 1.0, n_elements=64)
    shear_parameter = [1e-3, 1e-4, 1e-5]  # EI / (GA L^2)
    gaps = np.array([natural_frequencies(1.0, 1.0, 1.0, GA=1.0 / e, n_elements=64,
                                         model="timoshenko") / f_eb - 1 for e in shear_parameter])
    assert np.all(gaps < 0)
    # the shear correction is first order in EI / (GA L^2)
    np.testing.assert_allclose(gaps[2] / gaps[1], 0.1, rtol=0.01)
    assert np.all(np.abs(gaps[-1]) < 5e-4)


def test_timoshenko_is_lower_for_stubby_beams():
    f_eb = natural_frequencies(1.0, S_EI, S_RHO_A, n_elements=64)
    f_t = natural_frequencies(1.0, S_EI, S_RHO_A, GA=S_GA, rhoI=S_RHO_I, n_elements=64,
                              model="timoshenko")
    ratio = f_t / f_eb
    assert ratio[0] < 0.995 and np.all(np.diff(ratio) < 0)


def test_timoshenko_buckling_is_engesser_load():
    p_euler = np.pi**2 * S_EI
    p = buckling_load(1.0, S_EI, ("pin", "pin"), GA=S_GA, n_elements=64)
    assert p == pytest.approx(p_euler / (1 + p_euler / S_GA), rel=FREQ_RTOL)


def test_timoshenko_cantilever_tip_deflection_includes_shear():
    force, q = 1e3, 2e3
    _, tip = static_deflection(1.0, S_EI, tip_force=force, distributed_load=q, GA=S_GA,
                               n_elements=16)
    exact = force / (3 * S_EI) + force / S_GA + q / (8 * S_EI) + q / (2 * S_GA)
    assert tip == pytest.approx(exact, rel=STATIC_RTOL)


def test_invalid_input_is_rejected():
    with pytest.raises(ValueError, match="supports"):
        natural_frequencies(L, EI, RHO_A, supports=("clamp", "roller"))
    with pytest.raises(ValueError, match="rigid-body"):
        buckling_load(L, EI, supports=("pin", "free"))
    with pytest.raises(ValueError, match="GA"):
        natural_frequencies(L, EI, RHO_A, model="timoshenko")
    with pytest.raises(ValueError, match="EI"):
        static_deflection(L, -EI, tip_force=1.0)
