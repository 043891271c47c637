"""Contact laws: smoothing, derivatives against central differences, friction in stick and slip,
the full point force and its tangents (elements/contact/FORMULATION.md §2-§4)."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from rodnet.contact.geometry import Box, Cylinder, Sphere, query_world
from rodnet.contact.laws import (ContactLaw, contact_force, elastic_friction, normal_energy,
                                 normal_force, regularized_friction, smoothed_ramp)
from rodnet.contact.mesh import TriangleMesh
from rodnet.errors import SceneError

RNG = np.random.default_rng(7)


def central(func, x: np.ndarray, step: float) -> np.ndarray:
    return (func(x + step) - func(x - step)) / (2 * step)


def test_ramp_is_c1_with_a_linear_branch_through_the_origin() -> None:
    s = 1e-3
    at = np.array([-s, s])
    for side in (-1, 1):
        r, slope, _ = smoothed_ramp(at + side * 1e-12, s)
        np.testing.assert_allclose(r, [0.0, s], atol=1e-11)
        np.testing.assert_allclose(slope, [0.0, 1.0], atol=1e-8)
    delta = np.array([2 * s, 5.0])
    np.testing.assert_array_equal(smoothed_ramp(delta, s)[0], delta)
    assert smoothed_ramp(np.array([-np.inf]), s)[0][0] == 0.0
    # energy is the integral of k rho; rho' and rho'' are the derivatives of rho
    delta = RNG.uniform(-2 * s, 3 * s, 200)
    delta = delta[np.min(np.abs(np.abs(delta) - s)[:, None], axis=1) > 1e-6]
    k = 5.0
    np.testing.assert_allclose(central(lambda d: normal_energy(d, k, s), delta, 1e-8),
                               k * smoothed_ramp(delta, s)[0], rtol=1e-6, atol=1e-12)
    np.testing.assert_allclose(central(lambda d: smoothed_ramp(d, s)[0], delta, 1e-8),
                               smoothed_ramp(delta, s)[1], atol=1e-6)
    np.testing.assert_allclose(central(lambda d: smoothed_ramp(d, s)[1], delta, 1e-8),
                               smoothed_ramp(delta, s)[2], rtol=1e-5)


def test_normal_force_partials_match_central_differences() -> None:
    k, c, s = 2.0e4, 30.0, 1e-4
    delta = RNG.uniform(-2 * s, 10 * s, 400)
    rate = RNG.uniform(-0.2, 0.2, 400)
    nf = normal_force(delta, rate, k, c, s)
    rho, slope, _ = smoothed_ramp(delta, s)
    keep = np.abs(k * rho + c * slope * rate) > 1e-3  # away from the clamp at N = 0
    keep &= np.abs(np.abs(delta) - s) > 1e-7
    fd_delta = central(lambda d: normal_force(d, rate, k, c, s).force, delta, 1e-9)
    fd_rate = central(lambda r: normal_force(delta, r, k, c, s).force, rate, 1e-7)
    np.testing.assert_allclose(nf.d_penetration[keep], fd_delta[keep], rtol=1e-5, atol=1e-6)
    np.testing.assert_allclose(nf.d_rate[keep], fd_rate[keep], rtol=1e-5, atol=1e-6)


def test_normal_force_never_pulls_and_damps_only_in_contact() -> None:
    k, c, s = 1e4, 100.0, 1e-4
    # separating fast while penetrated: clamped at zero
    assert normal_force(np.array([1e-3]), np.array([-10.0]), k, c, s).force[0] == 0.0
    # out of contact: no damping force whatever the approach speed
    out = normal_force(np.array([-2 * s]), np.array([5.0]), k, c, s)
    assert out.force[0] == 0.0 and out.d_rate[0] == 0.0
    # deep in contact: linear spring plus dashpot
    deep = normal_force(np.array([1e-2]), np.array([0.1]), k, c, s)
    assert deep.force[0] == pytest.approx(k * 1e-2 + c * 0.1)


def test_regularized_friction_derivatives_limit_and_creep() -> None:
    mu, eps = 0.4, 1e-3
    v = RNG.normal(scale=3e-3, size=(100, 3))
    normal = RNG.uniform(0.5, 2.0, 100)
    fr = regularized_friction(v, normal, mu, eps)
    assert np.all(np.linalg.norm(fr.force, axis=1) < mu * normal)
    fd = np.stack([central(lambda dv: regularized_friction(v + dv * e, normal, mu, eps).force, 0.0, 1e-8)
                   for e in np.eye(3)], axis=-1)
    np.testing.assert_allclose(fr.d_tangential, fd, rtol=1e-5, atol=1e-6)
    fd_n = central(lambda dn: regularized_friction(v, normal + dn, mu, eps).force, 0.0, 1e-6)
    np.testing.assert_allclose(fr.d_normal, fd_n, atol=1e-8)
    # slip: |f| -> mu N, opposing the velocity
    fast = regularized_friction(np.array([[0.0, 2.0, 0.0]]), np.array([1.0]), mu, eps)
    np.testing.assert_allclose(fast.force, [[0.0, -mu, 0.0]], rtol=1e-6)
    # creep under a sub-critical load (F4): the force balances the load exactly there
    ratio = 0.8
    creep = eps * ratio / np.sqrt(1 - ratio**2)
    held = regularized_friction(np.array([[creep, 0.0, 0.0]]), np.array([1.0]), mu, eps)
    assert -held.force[0, 0] == pytest.approx(ratio * mu)


def test_elastic_friction_sticks_then_slips_with_consistent_derivatives() -> None:
    mu, kt = 0.3, 1e4
    normal = np.full(200, 2.0)
    slip = RNG.normal(scale=mu * 2.0 / kt, size=(200, 3))
    slip[:, 2] = 0.0
    x = RNG.normal(size=(200, 3))
    fr = elastic_friction(slip, normal, mu, kt, x)
    stick = fr.sticking
    assert 20 < stick.sum() < 180
    np.testing.assert_allclose(fr.force[stick], -kt * slip[stick])
    np.testing.assert_allclose(np.linalg.norm(fr.force[~stick], axis=1), mu * normal[~stick])
    keep = np.abs(kt * np.linalg.norm(slip, axis=1) - mu * normal) > 1e-3
    fd = np.stack([central(lambda d: elastic_friction(slip + d * e, normal, mu, kt, x).force, 0.0, 1e-9)
                   for e in np.eye(3)], axis=-1)
    np.testing.assert_allclose(fr.d_tangential[keep], fd[keep], rtol=1e-5, atol=1e-4)
    fd_n = central(lambda d: elastic_friction(slip, normal + d, mu, kt, x).force, 0.0, 1e-6)
    np.testing.assert_allclose(fr.d_normal[keep], fd_n[keep], atol=1e-7)
    # after the return mapping the spring sits exactly on the cone and pulls the same way
    again = elastic_friction(x - fr.anchor, normal, mu, kt, x)
    np.testing.assert_allclose(again.force, fr.force, atol=1e-12)


def rotation_about(axis: np.ndarray, angle: float) -> np.ndarray:
    axis = axis / np.linalg.norm(axis)
    k = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    return np.eye(3) + np.sin(angle) * k + (1 - np.cos(angle)) * k @ k


def bodies():
    m = trimesh.creation.icosphere(subdivisions=1, radius=0.5)
    return [Box((0.5, 0.4, 0.3)), Cylinder(0.4, 0.8, axis=0), Sphere(0.5), TriangleMesh(m.vertices, m.faces)]


@pytest.mark.parametrize("body", bodies(), ids=["box", "cylinder", "sphere", "mesh"])
@pytest.mark.parametrize("friction_law", ["regularized", "elastic", "lagged"])
def test_contact_force_tangents_match_central_differences(body, friction_law: str) -> None:
    law = ContactLaw(stiffness=1e3, damping=5.0, friction=0.4, smoothing=2e-3, slip_velocity=0.05,
                     tangential_stiffness=500.0)
    position, rotation = np.array([0.1, -0.2, 0.3]), rotation_about(np.array([1.0, 2.0, 3.0]), 0.6)
    radius = 0.01
    # points just above and slightly inside the surface, including near edges and corners
    local = RNG.normal(size=(300, 3))
    local = body.query(local).closest
    local += RNG.normal(scale=0.01, size=local.shape)
    x = position + local @ rotation.T
    v = RNG.normal(scale=0.05, size=x.shape)
    anchor = x + RNG.normal(scale=2e-3, size=x.shape) if friction_law == "elastic" else None
    lagged = RNG.uniform(0.5, 2.0, len(x)) if friction_law == "lagged" else None

    def force(xx, vv):
        q = query_world(body, xx, position, rotation)
        return contact_force(q, vv, radius, law, anchor=anchor, lagged_normal_force=lagged).force

    pf = contact_force(query_world(body, x, position, rotation), v, radius, law, anchor, lagged)
    assert (pf.normal_force > 0).sum() > 50
    h = 1e-7
    fd_x = np.stack([(force(x + h * e, v) - force(x - h * e, v)) / (2 * h) for e in np.eye(3)], axis=-1)
    fd_v = np.stack([(force(x, v + h * e) - force(x, v - h * e)) / (2 * h) for e in np.eye(3)], axis=-1)
    size_x = np.maximum(np.abs(pf.d_position).max(axis=(1, 2)), 1.0)
    size_v = np.maximum(np.abs(pf.d_velocity).max(axis=(1, 2)), 1.0)
    err_x = np.abs(fd_x - pf.d_position).max(axis=(1, 2)) / size_x
    err_v = np.abs(fd_v - pf.d_velocity).max(axis=(1, 2)) / size_v
    # a point within a step of a kink (clamp, stick/slip switch, mesh feature border) may differ
    assert np.mean(err_x < 1e-5) > 0.99 and np.mean(err_v < 1e-5) > 0.99


def test_contact_law_validation_names_the_key() -> None:
    with pytest.raises(SceneError, match="stiffness"):
        ContactLaw(stiffness=0.0)
    with pytest.raises(SceneError, match="friction"):
        ContactLaw(stiffness=1.0, friction=-0.1)
    with pytest.raises(SceneError, match="slip_velocity"):
        ContactLaw(stiffness=1.0, slip_velocity=0.0)
    assert ContactLaw(stiffness=3.0).spring_stiffness == 3.0


def test_points_beyond_the_mesh_cut_off_get_no_force_and_finite_tangents() -> None:
    m = trimesh.creation.icosphere(subdivisions=1, radius=0.5)
    mesh = TriangleMesh(m.vertices, m.faces)
    x = np.array([[0.0, 0.0, 2.0], [0.0, 0.0, 0.5]])
    q = mesh.query(x, max_distance=0.1)
    law = ContactLaw(stiffness=1e3, damping=1.0, friction=0.5, smoothing=1e-3)
    for anchor in (None, x.copy()):
        pf = contact_force(q, np.ones_like(x), 0.01, law, anchor=anchor)
        assert np.all(pf.force[0] == 0.0) and pf.normal_force[1] > 0.0
        assert np.isfinite(pf.d_position).all() and np.isfinite(pf.d_velocity).all()
        if anchor is not None:
            np.testing.assert_allclose(pf.anchor[0], x[0])
