"""The explicit loop's rod element forces against the model's forces, on random states of a net.

The explicit loop (:func:`rodnet.kernels.cosserat_compiled.rod_forces`) reads every element
straight from the node arrays and takes the half rotation and the coefficients ``beta``,
``gamma`` from the relative quaternion by the half-angle formulas; the model's
:meth:`~rodnet.models.cosserat.model.CosseratModel.forces` gathers the element states, takes the
element forces from the reference path (:func:`rodnet.kernels.cosserat_compiled.internal_force`:
exponential, ``tan``) and assembles them. Both must give the same node forces and moments to
1e-12 of the largest element force and moment, with pinned knots and with rigid knots (end offsets).

Random states: every rotation node turned by a random rotation of up to 2.2 rad from the start
(the elements' relative rotations then cover the series and the closed forms of the coefficients
and the double cover past pi, away from its singularity at 2 pi); some nodes turned by less than
1e-8 rad (the series logarithm where both ends of an element are); every quaternion's sign flipped
must change nothing; the knots moved by up to 5 cm (slack and taut elements), random
velocities and spins (damping).
"""

from __future__ import annotations

import numpy as np
import pytest

from rodnet.integrate.explicit import scratch
from rodnet.kernels import so3
from rodnet.kernels.explicit import forces
from rodnet.run import prepare
from rodnet.scene import scene_from_toml
from rodnet.state import Configuration
from tests.conftest import small_net_toml

RTOL = 1e-12


def random_state(model, q0: Configuration, rng: np.random.Generator):
    """Positions (N, 3), quaternions (R, 4), velocities (N, 3), spins (R, 3)."""
    n, r = model.n_nodes, model.n_rot
    axis = rng.normal(size=(r, 3))
    axis /= np.linalg.norm(axis, axis=1, keepdims=True)
    angle = rng.uniform(0.0, 2.2, r)
    tiny = rng.random(r) < 0.2
    angle[tiny] = 10.0 ** rng.uniform(-12.0, -8.0, tiny.sum())
    quat = so3.quat_multiply(q0.quat, so3.quat_from_rotvec(angle[:, None] * axis))
    x = q0.x + rng.uniform(-0.05, 0.05, (n, 3))
    return x, quat, rng.normal(size=(n, 3)), rng.normal(scale=20.0, size=(r, 3))


@pytest.mark.parametrize("knots", ["pinned", "rigid"])
def test_explicit_rod_forces_match_the_model(knots: str) -> None:
    scene = scene_from_toml(small_net_toml(n=2), ["model.type=cosserat", f"model.knots={knots}"])
    p = prepare(scene)
    model = p.model
    assert (model.end_offset is not None) == (knots == "rigid")
    problem, _ = p.system.explicit_problem()
    work = scratch(problem)
    rng = np.random.default_rng(7)
    angles = []
    for _ in range(5):
        x, quat, v, W = random_state(model, p.q0, rng)
        peak, phi_max = forces(0.0, x, quat, v, W, problem, work)
        q = Configuration(x, quat)
        v_flat = np.concatenate([v.ravel(), W.ravel()])
        g, _, _ = model.forces(q, v_flat, 0.0, 1.0, False)
        gyro, _ = model._gyroscopic(v_flat)
        n3 = 3 * model.n_nodes
        f_ref = -g[:n3].reshape(-1, 3)
        m_ref = -(g[n3:].reshape(-1, 3) - gyro)
        # to 1e-12 of the largest element force and moment (the moments are about 1e-5 of the
        # forces times the element length: each gets its own scale)
        force_scale = np.abs(work.force[:, [0, 1, 2, 6, 7, 8]]).max()
        moment_scale = np.abs(work.force[:, [3, 4, 5, 9, 10, 11]]).max()
        np.testing.assert_allclose(work.f_node, f_ref, rtol=0.0, atol=RTOL * force_scale)
        np.testing.assert_allclose(work.m_node, m_ref, rtol=0.0, atol=RTOL * moment_scale)
        flipped = scratch(problem)
        assert forces(0.0, x, -quat, v, W, problem, flipped) == (peak, phi_max)
        np.testing.assert_array_equal(flipped.f_node, work.f_node)
        np.testing.assert_array_equal(flipped.m_node, work.m_node)
        # what the step control and the summary take: the largest rotation and axial force
        rotation = model.element_rotation(q)
        assert phi_max == pytest.approx(rotation.max(), rel=RTOL)
        assert peak == pytest.approx(max(0.0, model.axial_force(q, v_flat).max()), rel=RTOL)
        angles.append(rotation)
    angles = np.concatenate(angles)
    # the states reach every branch of the coefficients and the double cover
    assert np.any(angles < 0.5) and np.any((angles > 0.5) & (angles < np.pi))
    assert np.any(angles > np.pi)
