"""The explicit loop's rotation update (rodnet.kernels.explicit: a vectorised pass by the series
of exp below 0.05 rad per step, the nodes turned further redone by cos and sin) against the
exponential map of so3, for rotations per step on both sides of the switch."""

from __future__ import annotations

import numba
import numpy as np

from rodnet.integrate.explicit import _bodies, scratch
from rodnet.kernels import explicit as kx
from rodnet.kernels import so3
from rodnet.run import prepare
from rodnet.scene import scene_from_toml
from tests.conftest import small_net_toml


def _pinned_rod_net():  # type: ignore[no-untyped-def]
    """The explicit problem, step control and start state of the 5 x 5 net of Cosserat threads
    (two elements each, pinned knots)."""
    scene = scene_from_toml(small_net_toml(n=2), ["model.type=cosserat", "model.knots=pinned",
                                                  "simulation.integrator=explicit"])
    p = prepare(scene)
    problem, control = p.system.explicit_problem()
    return problem, control, p.state


def test_rotation_update_is_the_exponential_map_on_both_sides_of_the_series() -> None:
    problem, control, st = _pinned_rod_net()
    rng = np.random.default_rng(3)
    x, quat, v = st.q.x.copy(), st.q.quat.copy(), st.velocities.copy()
    r = len(quat)
    quat = so3.quat_multiply(quat, so3.quat_from_rotvec(rng.normal(size=(r, 3)) * 0.3))
    axis = rng.normal(size=(r, 3))
    axis /= np.linalg.norm(axis, axis=1, keepdims=True)
    h = 1e-6
    angle = 10.0 ** rng.uniform(-4.0, -0.3, r)          # per step, from 1e-4 to 0.5 rad
    W = axis * (angle / h)[:, None]
    before = quat.copy()
    # one step of h: the base step 1 s is cut to land on t0 + h
    done = kx.march(x, quat, v, W, _bodies(st), 0.0, h, 1, 1.0, problem, control,
                    scratch(problem))
    assert done.status == 0 and done.steps == 1
    turned = h * W                                      # the updated spins, as the loop used them
    expected = so3.quat_multiply(before, so3.quat_from_rotvec(turned))
    expected /= np.linalg.norm(expected, axis=1, keepdims=True)
    per_step = np.linalg.norm(turned, axis=1)
    assert np.any(per_step < 0.05) and np.any(per_step > 0.05)
    np.testing.assert_allclose(quat, expected, rtol=0.0, atol=1e-14)


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
