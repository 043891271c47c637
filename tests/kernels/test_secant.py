"""The midpoint rule's secant form of the segment force (spring FORMULATION.md, S14-S15): its
work over a step is the change of the stored energy (S6), plus a dissipation that is never
negative, and its tangent is the derivative of the force."""

from __future__ import annotations

import numpy as np
import pytest

from rodnet.kernels.cable import cable_secant_tangents
from rodnet.kernels.tension import axial_energy

KINK = 1e-3
E_COUNT = 400


def _segments(seed: int, spread: float) -> tuple[np.ndarray, ...]:
    """Start and midpoint ends of random segments of rest length 0.5 m whose strains lie
    around zero (slack, in the kink, taut) and change by up to ``spread`` over the step."""
    rng = np.random.default_rng(seed)
    L = np.full(E_COUNT, 0.5)
    x0_a = rng.normal(size=(E_COUNT, 3))
    direction = rng.normal(size=(E_COUNT, 3))
    direction /= np.linalg.norm(direction, axis=1)[:, None]
    e0 = rng.uniform(-3.0 * KINK, 3.0 * KINK, E_COUNT)
    x0_b = x0_a + (L * (1.0 + e0))[:, None] * direction
    x1_a = x0_a + spread * rng.normal(size=(E_COUNT, 3))
    x1_b = x0_b + spread * rng.normal(size=(E_COUNT, 3))
    return L, x0_a, x0_b, 0.5 * (x0_a + x1_a), 0.5 * (x0_b + x1_b), x1_a, x1_b


def _work_and_stored_change(seed: int, spread: float, EA: np.ndarray, etaA: np.ndarray,
                            tension_only: bool) -> tuple[np.ndarray, np.ndarray]:
    """The secant force's work over the step of :func:`_segments` and the change of the
    stored energy (S6) between its ends [J] (E,) (1 / h = 1e3 1/s)."""
    L, x0_a, x0_b, xm_a, xm_b, x1_a, x1_b = _segments(seed, spread)
    _, g_b, _, _ = cable_secant_tangents(xm_a, xm_b, x0_a, x0_b, L, EA, etaA, KINK,
                                         tension_only, 1e3)
    work = np.einsum("ij,ij->i", g_b, (x1_b - x0_b) - (x1_a - x0_a))
    stored = [axial_energy(np.linalg.norm(b - a, axis=1) / L - 1.0, EA, L, KINK, tension_only)
              for a, b in ((x0_a, x0_b), (x1_a, x1_b))]
    return work, stored[1] - stored[0]


@pytest.mark.parametrize("tension_only", [True, False])
@pytest.mark.parametrize("spread", [1e-3, 1e-6, 1e-11])
def test_the_work_over_the_step_is_the_change_of_stored_energy(tension_only: bool,
                                                               spread: float) -> None:
    EA = np.full(E_COUNT, 1e4)
    work, stored_change = _work_and_stored_change(1, spread, EA, np.zeros(E_COUNT), tension_only)
    scale = EA * 0.5 * (3.0 * KINK) ** 2
    np.testing.assert_allclose(work, stored_change, rtol=0, atol=1e-12 * scale.max())
    assert np.abs(work).max() > 0.0


@pytest.mark.parametrize("tension_only", [True, False])
def test_damping_over_the_step_only_dissipates(tension_only: bool) -> None:
    work, stored_change = _work_and_stored_change(2, 1e-3, np.full(E_COUNT, 1e4),
                                                  np.full(E_COUNT, 30.0), tension_only)
    dissipated = work - stored_change
    assert dissipated.min() >= -1e-12 * np.abs(work).max()
    assert dissipated.max() > 1e-3 * np.abs(work).max()


@pytest.mark.parametrize("tension_only", [True, False])
def test_the_tangent_is_the_derivative_of_the_force(tension_only: bool) -> None:
    L, x0_a, x0_b, xm_a, xm_b, _, _ = _segments(3, 1e-3)
    EA, etaA = np.full(E_COUNT, 1e4), np.full(E_COUNT, 30.0)
    args = (L, EA, etaA, KINK, tension_only, 1e3)
    _, _, K, C = cable_secant_tangents(xm_a, xm_b, x0_a, x0_b, *args)
    assert not C.any()
    step = 1e-8
    numeric = np.empty_like(K)
    for k in range(3):
        shift = np.zeros(3)
        shift[k] = step
        plus = cable_secant_tangents(xm_a, xm_b + shift, x0_a, x0_b, *args)[1]
        minus = cable_secant_tangents(xm_a, xm_b - shift, x0_a, x0_b, *args)[1]
        numeric[:, :, k] = (plus - minus) / (2.0 * step)
    # away from the kink's corners, where the central difference straddles a jump of slope
    c1 = 2.0 * (xm_b - xm_a) - (x0_b - x0_a)
    e1 = np.linalg.norm(c1, axis=1) / L - 1.0
    smooth = (np.abs(e1) > 1e-6) & (np.abs(e1 - KINK) > 1e-6)
    scale = np.abs(K).max()
    np.testing.assert_allclose(numeric[smooth], K[smooth], rtol=0, atol=2e-5 * scale)


def test_secant_strain_is_where_the_ramp_takes_its_secant() -> None:
    """``r(e*) = (R(e1) - R(e0)) / (e1 - e0)`` for pairs across the kink, inside it, slack and
    taut (the rod's midpoint stresses, cosserat C56), with ``e*`` between the two strains."""
    from rodnet.kernels.tension import axial_energy, ramp, secant_strain
    rng = np.random.default_rng(3)
    d = 1e-6
    start = rng.choice([-1e-5, -1e-7, 3e-7, 2e-6, 1e-4], 400) * rng.uniform(0.5, 1.5, 400)
    end = rng.choice([-1e-5, -1e-7, 3e-7, 2e-6, 1e-4], 400) * rng.uniform(0.5, 1.5, 400)
    e = secant_strain(start, end, d)
    one = np.ones_like(start)
    secant = (axial_energy(end, one, one, d, True) - axial_energy(start, one, one, d, True)) \
        / (end - start)
    assert np.allclose(ramp(e, d)[0], secant, rtol=1e-9, atol=1e-18)
    assert np.all((e >= np.minimum(start, end) - 1e-15) & (e <= np.maximum(start, end) + 1e-15))
