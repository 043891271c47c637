"""The explicit plan solves each kind of element once (rodnet.models.cosserat.explicit): the
grouping of alike elements and the bounds it gives, against every element solved on its own."""

from __future__ import annotations

import dataclasses

import numpy as np

from rodnet.models.cosserat import explicit as ce
from rodnet.run import prepare
from tests.validation.test_explicit_rods import net


def test_rows_that_differ_only_in_sign_bits_are_different_kinds() -> None:
    """Two sign flips cancel in a plain sum of bits times odd multipliers: the grouping must
    still tell such rows apart, and keep equal rows together."""
    rng = np.random.default_rng(1)
    a = rng.standard_normal((40, 14))
    a[5] = a[3]
    a[7] = a[3]
    a[9] = a[3]
    a[9, [2, 3]] *= -1.0                    # the sign bits of two columns
    a[11] = 0.0
    a[12] = -0.0                            # equal as floats, not bit for bit
    kinds, kind = ce._distinct_rows(a)
    np.testing.assert_array_equal(kinds[kind], a)
    assert kind[5] == kind[3] == kind[7]
    assert kind[9] != kind[3]
    assert kind[11] != kind[12]
    assert len(kinds) == 40 - 2


def test_bounds_of_kinds_equal_every_element_solved_alone() -> None:
    """A small net whose elements are of a few kinds, one element's stiffness changed: the
    element stiffness and the largest eigenvalues are those of every element on its own, bit
    for bit, at rest and bent."""
    model = prepare(net(knots="rigid")).model
    stiffness = model.stiffness.copy()
    stiffness[3] *= 1.5
    model = dataclasses.replace(model, stiffness=stiffness)
    bound = ce.ElementBound(model)
    raised = model.rotary_inertia * (1.0 + np.arange(model.n_rot))[:, None]
    inv_sqrt = bound.inverse_sqrt_mass(raised)
    for angle in (0.0, 1.0):
        kinds, kind = ce._stiffness_kinds(model, angle)
        assert 1 < len(kinds) < len(kind)
        alone = []
        for e in range(len(kind)):
            one = dataclasses.replace(model, rest_length=model.rest_length[e:e + 1],
                                      reference_strain=model.reference_strain[e:e + 1],
                                      stiffness=model.stiffness[e:e + 1], tau=model.tau[e:e + 1])
            x, q = ce.stress_free_element_states(one, angle)
            _, K, _ = ce.internal_force_and_tangents_numpy(one.rest_length, one.reference_strain,
                                                           one.stiffness, one.tau, x, q,
                                                           np.zeros((1, 12)), False,
                                                           one.kink_strain)
            alone.append(0.5 * (K[0] + K[0].T))
        alone = np.array(alone)
        np.testing.assert_array_equal(ce.element_stiffness(model, angle), alone)
        A = inv_sqrt[:, :, None] * alone * inv_sqrt[:, None, :]
        expected = np.array([np.linalg.eigvalsh(A[e])[-1] for e in range(len(A))])
        np.testing.assert_array_equal(bound.largest((kinds, kind), inv_sqrt), expected)
        np.testing.assert_array_equal(bound.largest(alone, inv_sqrt), expected)
        sub = ce.TRANSLATION
        expected_t = np.array([np.linalg.eigvalsh(A[e][np.ix_(sub, sub)])[-1]
                               for e in range(len(A))])
        np.testing.assert_array_equal(bound.largest((kinds, kind), inv_sqrt, sub), expected_t)
