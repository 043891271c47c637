"""The explicit loop's rotation update (rodnet.kernels.explicit, C47-C47a: the kick of the body
momentum, then the free rotation split into turns about the three body axes; a vectorised pass
by the series of cos and sin below 0.05 rad per axis and step, the nodes turned further redone
by cos and sin) against the same splitting written here with rotation matrices, on both sides
of the switch; and the splitting's invariants."""

from __future__ import annotations

import numba
import numpy as np

from rodnet.integrate.explicit import _bodies, scratch
from rodnet.kernels import explicit as kx
from rodnet.kernels import so3
from rodnet.run import prepare
from rodnet.scene import scene_from_toml
from tests.conftest import small_net_toml


def _pinned_rod_net(scaled: bool = True):  # type: ignore[no-untyped-def]
    """The explicit problem, step control and start state of the 5 x 5 net of Cosserat threads
    (two elements each, pinned knots); ``scaled`` False: the threads' own (anisotropic) rotary
    inertia."""
    scene = scene_from_toml(small_net_toml(n=2), ["model.type=cosserat", "model.knots=pinned",
                                                  "simulation.integrator=explicit",
                                                  f"simulation.rotary_inertia_scaling={str(scaled).lower()}"])
    p = prepare(scene)
    problem, control = p.system.explicit_problem()
    return problem, control, p.state


def _axis_turn(axis: int, angle: np.ndarray) -> np.ndarray:
    """(R, 3, 3) rotation matrices by ``angle`` (R,) about body axis ``axis``."""
    c, s = np.cos(angle), np.sin(angle)
    j, k = (axis + 1) % 3, (axis + 2) % 3
    out = np.zeros((len(angle), 3, 3))
    out[:, axis, axis] = 1.0
    out[:, j, j] = out[:, k, k] = c
    out[:, k, j], out[:, j, k] = s, -s
    return out


def _split_free_rotation(quat, P, inverse, h):  # type: ignore[no-untyped-def]
    """Reference (C47a): turns about body axes 0, 1 (h/2), 2 (h), 1, 0 (h/2), each by
    ``tau P_a / J_a``, the body momentum turned back by the same matrix."""
    for axis, tau in ((0, h / 2), (1, h / 2), (2, h), (1, h / 2), (0, h / 2)):
        angle = tau * P[:, axis] * inverse[:, axis]
        rotvec = np.zeros_like(P)
        rotvec[:, axis] = angle
        quat = so3.quat_multiply(quat, so3.quat_from_rotvec(rotvec))
        P = np.einsum("rji,rj->ri", _axis_turn(axis, angle), P)
    return quat / np.linalg.norm(quat, axis=1, keepdims=True), P


def test_rotation_update_is_the_split_free_rotation_on_both_sides_of_the_series() -> None:
    problem, control, st = _pinned_rod_net(scaled=False)
    rng = np.random.default_rng(3)
    x, quat, v = st.q.x.copy(), st.q.quat.copy(), st.velocities.copy()
    r = len(quat)   # sections stress-free: the kick is the spins' momentum and gravity's none
    axis = rng.normal(size=(r, 3))
    axis /= np.linalg.norm(axis, axis=1, keepdims=True)
    h = 1e-6
    angle = 10.0 ** rng.uniform(-4.0, -0.3, r)          # per step, from 1e-4 to 0.5 rad
    W = axis * (angle / h)[:, None]
    J, inverse = problem.rotations.inertia, problem.rotations.inv_inertia
    assert np.all(inverse > 0.0) and np.ptp(J, axis=1).max() > 0.1 * J.max()   # anisotropic
    s = scratch(problem)
    kx.forces(0.0, x, quat, v, W, problem, s)
    P = J * W + h * s.m_node                            # the kick
    expected, P1 = _split_free_rotation(quat.copy(), P, inverse, h)
    # one step of h: the base step 1 s is cut to land on t0 + h
    done = kx.march(x, quat, v, W, _bodies(st), 0.0, h, 1, 1.0, problem, control,
                    scratch(problem))
    assert done.status == 0 and done.steps == 1
    largest = h * np.linalg.norm(P, axis=1) * inverse.max(axis=1)
    assert np.any(largest < 0.05) and np.any(largest > 0.05)   # both passes
    # round-off grows with the angle (the damping's kick turns some nodes by tens of radians)
    error = np.abs(quat * np.sign(quat[:, :1]) - expected * np.sign(expected[:, :1])).max(axis=1)
    assert np.all(error <= 1e-13 * np.maximum(1.0, largest))
    assert error[largest < 0.05].max() <= 1e-14          # the series to round-off
    np.testing.assert_allclose(W, P1 * inverse, rtol=1e-11, atol=0.0)


def test_free_rotation_keeps_the_spatial_momentum_and_the_energy_bounded() -> None:
    """Nodes spinning about one body axis and tumbling about another, no moments: over 20,000
    steps of 0.3 rad the spatial angular momentum ``R J W`` stays to round-off and the kinetic
    energy within 1 %; the update of (C47) before the splitting (``W1 = W0 - h J^-1 W0 x J
    W0``) gained energy without bound on such a spin (a free rod, 77 % in 20 s)."""
    J = np.array([[1.0, 1.0, 2.0], [3.0, 2.0, 3.0], [1.0, 2.0, 3.0]])
    inverse = 1.0 / J
    W = np.array([[0.5, 0.0, 10.0], [8.0, 1.0, 0.5], [1.0, 5.0, 0.2]])
    quat = np.tile([1.0, 0.0, 0.0, 0.0], (3, 1))
    h = 0.03
    spatial0 = J * W
    energy0 = 0.5 * np.einsum("ri,ri->r", J * W, W)
    P = J * W
    for _ in range(20_000):
        quat, P = _split_free_rotation(quat, P, inverse, h)
    spatial = np.einsum("rij,rj->ri", so3.quat_to_matrix(quat), P)
    np.testing.assert_allclose(spatial, spatial0, rtol=0.0, atol=1e-9 * np.abs(spatial0).max())
    energy = 0.5 * np.einsum("ri,ri->r", P, P * inverse)
    np.testing.assert_allclose(energy, energy0, rtol=1e-2)
    # and the compiled pass takes the same steps: one node of the net, no moments
    Q, Wc, M = quat.copy(), P * inverse, np.zeros((3, 3))
    Q0, P0 = Q.copy(), P.copy()
    bad, far = kx.update_range(np.zeros((0, 3)), Q, np.zeros((0, 3)), Wc, np.zeros((0, 3)), M,
                               np.zeros((0, 3)), J, inverse, 1e-3)
    assert bad == 0 and far == 0
    expected, P1 = _split_free_rotation(Q0, P0, inverse, 1e-3)
    np.testing.assert_allclose(Q * np.sign(Q[:, :1]), expected * np.sign(expected[:, :1]),
                               atol=1e-14)
    np.testing.assert_allclose(Wc, P1 * inverse, rtol=1e-13)


def test_a_non_finite_spin_fails_the_step() -> None:
    problem, control, st = _pinned_rod_net()
    x, quat, v, W = st.q.x.copy(), st.q.quat.copy(), st.velocities.copy(), st.spin.copy()
    W[1] = np.nan
    done = kx.march(x, quat, v, W, _bodies(st), 0.0, 1e-6, 1, 1.0, problem, control,
                    scratch(problem))
    assert done.status == 1


def test_the_loops_step_the_same_in_any_number_of_blocks() -> None:
    """The loops over elements and nodes run over blocks of them (``StepControl.blocks``, one
    per thread in a run): whatever their number (7 divides neither the 5 x 5 net's elements nor
    its nodes) and on one thread or two, every element and node is stepped once with the same
    arithmetic, so the state is the same to the last bit, turns past the series of exp
    included."""
    problem, control, st = _pinned_rod_net()
    sizes = (problem.rods.rest_length.shape[0], st.q.x.shape[0], st.q.quat.shape[0])
    assert all(size % 7 != 0 for size in sizes)
    rng = np.random.default_rng(5)
    quat0 = so3.quat_multiply(st.q.quat, so3.quat_from_rotvec(rng.normal(size=(len(st.q.quat), 3))
                                                            * 0.3))
    W0 = rng.normal(scale=2e3, size=st.spin.shape)
    v0 = st.velocities + rng.normal(scale=5.0, size=st.velocities.shape)
    before = numba.get_num_threads()
    numba.set_num_threads(min(2, numba.config.NUMBA_NUM_THREADS))
    try:
        ends = []
        # march_parallel is the same loop with contact: not compiled here (about 15 s)
        for loop, blocks in ((kx.march, 1), (kx.march, 7), (kx.march_free, 7),
                             (kx.march_parallel_free, 2), (kx.march_parallel_free, 7)):
            x, quat, v, W = st.q.x.copy(), quat0.copy(), v0.copy(), W0.copy()
            done = loop(x, quat, v, W, _bodies(st), 0.0, 50 * control.dt, 1, control.dt, problem,
                        control._replace(blocks=blocks), scratch(problem))
            assert done.status == 0 and done.steps >= 50
            ends.append((done.steps, x, quat, v, W))
    finally:
        numba.set_num_threads(before)
    assert np.any(np.linalg.norm(W0, axis=1) * control.dt > 0.05)   # some turn past the series
    for steps, *arrays in ends[1:]:
        assert steps == ends[0][0]
        for got, expected in zip(arrays, ends[0][1:]):
            np.testing.assert_array_equal(got, expected)
    assert not np.array_equal(ends[0][1], st.q.x)
