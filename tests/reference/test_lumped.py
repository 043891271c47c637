"""The lumped reference model: force law, compiled kernel, analytic oscillator, net invariants."""

from __future__ import annotations

import numpy as np
import pytest

from rodnet.errors import SimulationFailed
from rodnet.integrate.frames import frame_times
from rodnet.kernels.tension import axial_force
from rodnet.run import prepare, run
from rodnet.scene import scene_from_toml
from rodnet.state import Configuration
from tests.conftest import small_net_toml
from tests.systems import compiled_forces, run_explicit

SPRING = """
[simulation]
duration = {duration}
integrator = "{integrator}"
adaptive = false
dt = {dt}
rtol = 1e-9
[model]
type = "lumped"
axial = "{axial}"
kink_strain = 0.0
[[materials]]
name = "wire"
density = 1000.0
youngs_modulus = 1.0e9
diameter = 1.0e-3
viscosity = {viscosity}
[[rods]]
name = "spring"
material = "wire"
points = [[0, 0, 0], [1, 0, 0]]
elements = 1
[[supports]]
node = "spring:start"
fix = "pin"
[[masses]]
node = "spring:end"
mass = 1.0
velocity = [{v0}, 0.0, 0.0]
[output]
frame_interval = 0.001
vtk = false
"""


def spring(duration=0.2, integrator="explicit", dt=1e-5, axial="linear", viscosity=0.0, v0=0.1):
    return scene_from_toml(SPRING.format(duration=duration, integrator=integrator, dt=dt,
                                         axial=axial, viscosity=viscosity, v0=v0))


def test_compiled_forces_equal_numpy_forces() -> None:
    rng = np.random.default_rng(1)
    for axial in ("tension-only", "linear"):
        p = prepare(scene_from_toml(small_net_toml(n=2), [f"model.axial={axial}",
                                                          "simulation.gravity=[0, 0, -9.81]"]))
        x = p.structure.rest_positions * rng.uniform(0.98, 1.02, p.q0.x.shape)
        v = rng.normal(size=x.shape)
        f = compiled_forces(p.system, x, v, 0.3)
        np.testing.assert_allclose(f, p.model.force(x, v, 0.3), rtol=1e-12, atol=1e-9)


def _segment_pairs(rest_length, stretch, rng):
    """Positions (2S, 3) of S separate two-node segments, node 2i to 2i + 1, stretched by
    ``stretch`` (S,) along random directions, with random velocities (2S, 3)."""
    d = rng.normal(size=(len(stretch), 3))
    d /= np.linalg.norm(d, axis=1)[:, None]
    a = rng.normal(size=(len(stretch), 3))
    x = np.stack([a, a + (rest_length * stretch)[:, None] * d], axis=1).reshape(-1, 3)
    return x, rng.normal(size=x.shape), np.arange(2 * len(stretch)).reshape(-1, 2)


def test_slack_segments_skipped_exactly() -> None:
    """Segments within a few rounding errors of their rest length, the kink and beyond: the
    compiled forces (which pass over segments shorter than (1 - SLACK_MARGIN) of their rest
    length unmeasured) equal a direct evaluation of the law at every segment."""
    from rodnet.kernels.segments import SLACK_MARGIN, segment_forces

    rng = np.random.default_rng(4)
    eps = np.finfo(float).eps
    stretch = 1.0 + np.concatenate([np.arange(-40, 41) * eps, [-2 * SLACK_MARGIN, -SLACK_MARGIN,
                                    -0.5 * SLACK_MARGIN, 0.5e-6, 2e-6, 1e-3, -1e-3, -0.5]])
    rest = rng.uniform(0.1, 3.0, len(stretch))
    x, v, pairs = _segment_pairs(rest, stretch, rng)
    EA, etaA = np.full(len(rest), 1e4), np.full(len(rest), 10.0)
    for kink in (0.0, 1e-6):
        f = np.zeros_like(x)
        peak = segment_forces(x, v, f, pairs, rest, EA, etaA, kink, True)
        d = x[1::2] - x[0::2]
        length = np.sqrt(np.einsum("ij,ij->i", d, d))
        t = d / length[:, None]
        rate = np.einsum("ij,ij->i", v[1::2] - v[0::2], t) / rest
        n = axial_force(length / rest - 1.0, rate, EA, etaA, kink, True)
        np.testing.assert_allclose(f[0::2], n[:, None] * t, rtol=1e-13, atol=0.0)
        np.testing.assert_allclose(f[1::2], -n[:, None] * t, rtol=1e-13, atol=0.0)
        assert peak == pytest.approx(n.max(), rel=1e-13)
        assert (n > 0).sum() >= 4 and (n == 0).sum() >= 40   # both branches exercised


def test_frame_tension_and_energy_equal_the_law() -> None:
    """The compiled pass of a saved frame gives axial_force and axial_energy (S3)-(S6) of every
    segment: slack, inside the kink, taut, and the linear law."""
    from rodnet.kernels.segments import segment_states
    from rodnet.kernels.tension import axial_energy

    rng = np.random.default_rng(5)
    stretch = np.concatenate([rng.uniform(0.9, 1.1, 40), 1.0 + rng.uniform(0.0, 2e-6, 10)])
    rest = rng.uniform(0.1, 3.0, len(stretch))
    x, v, pairs = _segment_pairs(rest, stretch, rng)
    EA, etaA = rng.uniform(1e3, 1e5, len(rest)), rng.uniform(0.0, 50.0, len(rest))
    d = x[1::2] - x[0::2]
    length = np.linalg.norm(d, axis=1)
    e = length / rest - 1.0
    rate = np.einsum("ij,ij->i", v[1::2] - v[0::2], d / length[:, None]) / rest
    for kink, tension_only in ((0.0, True), (1e-6, True), (1e-6, False)):
        tension = np.empty(len(rest))
        energy = segment_states(x, v, pairs, rest, EA, etaA, kink, tension_only, tension)
        np.testing.assert_allclose(tension, axial_force(e, rate, EA, etaA, kink, tension_only),
                                   rtol=1e-12, atol=1e-12)
        expected = axial_energy(e, EA, rest, kink, tension_only).sum()
        assert energy == pytest.approx(expected, rel=1e-12)
        assert (tension > 0).any() and (tension == 0).any() == tension_only


def test_tension_only_law_never_pushes() -> None:
    e = np.array([-0.1, 0.0, 1e-3, 1e-3, 2e-3])
    rate = np.array([0.0, 5.0, 0.0, -100.0, 1.0])
    n = axial_force(e, rate, np.full(5, 100.0), np.full(5, 1.0), 0.0, True)
    np.testing.assert_allclose(n, [0.0, 0.0, 0.1, 0.0, 1.2])  # slack, kink, taut, fast shortening
    lin = axial_force(e, rate, np.full(5, 100.0), np.full(5, 1.0), 0.0, False)
    assert lin[0] < 0 and lin[3] < 0  # the linear law does push


def test_undamped_spring_mass_period_and_amplitude() -> None:
    """Linear spring k = EA/l0 with a 1 kg end mass: x(t) = (v0/w) sin(w t), w^2 = k/m."""
    scene = spring(duration=0.2, dt=2e-6)
    r = run(scene, _tmp(), progress=False)
    k = 1.0e9 * np.pi / 4 * 1e-6 / 1.0
    m = 1.0 + 0.5 * 1000.0 * np.pi / 4 * 1e-6
    w = np.sqrt(k / m)
    t = r.arrays["time"]
    u = r.arrays["positions"][:, 1, 0] - 1.0
    np.testing.assert_allclose(u, 0.1 / w * np.sin(w * t), atol=2e-3 * 0.1 / w)


def test_kelvin_voigt_logarithmic_decrement() -> None:
    """Damped oscillator: amplitude ratio over one period exp(-2 pi zeta / sqrt(1 - zeta^2))."""
    viscosity = 4.0e6
    r = run(spring(duration=0.1, dt=1e-6, viscosity=viscosity, integrator="rk45"), _tmp(), progress=False)
    k = 1.0e9 * np.pi / 4 * 1e-6
    c = viscosity * np.pi / 4 * 1e-6
    m = 1.0 + 0.5 * 1000.0 * np.pi / 4 * 1e-6
    zeta = c / (2 * np.sqrt(k * m))
    u = r.arrays["positions"][:, 1, 0] - 1.0
    peaks = [u[i] for i in range(1, len(u) - 1) if u[i] > u[i - 1] and u[i] > u[i + 1]]
    ratio = np.exp(-2 * np.pi * zeta / np.sqrt(1 - zeta**2))
    assert 0.3 < ratio < 0.95  # strong enough damping for the ratio to mean something
    np.testing.assert_allclose(np.array(peaks[1:3]) / np.array(peaks[0:2]), ratio, rtol=2e-2)


def test_stable_step_separates_stable_from_unstable() -> None:
    p = prepare(scene_from_toml(small_net_toml(duration=0.3)))
    limit = p.model.stable_step()
    times = frame_times(0.3, 0.01)
    run_explicit(p.system, p.q0, p.v0, times, 0.95 * limit)
    with pytest.raises(SimulationFailed, match="diverged"):
        run_explicit(p.system, p.q0, p.v0, times, 2.5 * limit)


@pytest.fixture(scope="module")
def deployment():
    scene = scene_from_toml(small_net_toml(duration=1.0))
    return prepare(scene), run(scene, _tmp(), progress=False)


def test_centre_of_mass_moves_uniformly(deployment) -> None:
    p, r = deployment
    m = p.model.mass
    com = np.einsum("fnk,n->fk", r.arrays["positions"], m) / m.sum()
    v_com = (m @ p.v0.reshape(-1, 3)) / m.sum()
    expected = com[0] + r.arrays["time"][:, None] * v_com
    travelled = np.linalg.norm(expected[-1] - expected[0])
    assert np.abs(com - expected).max() <= 1e-9 * travelled


def test_energy_never_increases_and_tension_never_negative(deployment) -> None:
    p, r = deployment
    energy = np.array([sum(p.model.energy(Configuration(x), v, t).values()) for t, x, v in
                       zip(r.arrays["time"], r.arrays["positions"], r.arrays["velocities"])])
    assert np.diff(energy).max() <= 1e-9 * energy[0]
    assert energy[-1] < 0.95 * energy[0]  # the threads did dissipate
    assert r.arrays["tension"].min() >= 0.0 and r.arrays["tension"].max() > 10.0


def test_explicit_agrees_with_rk45_on_a_small_net(deployment) -> None:
    """Up to the maximum mouth area. After it, the light corner masses of this small net snap back
    and the motion is so sensitive that RK45 at rtol 1e-6 and 1e-8 differ by 1 % of the area; the
    reference deployment (validation/benchmarks) is compared over its whole 3 s."""
    _, explicit = deployment
    rk = run(scene_from_toml(small_net_toml(duration=1.0, integrator="rk45")), _tmp(), progress=False)
    area = explicit.arrays["mouth_area"]
    until = slice(0, int(np.argmax(area)) + 1)
    assert np.abs(area[until] - rk.arrays["mouth_area"][until]).max() < 2e-3 * area.max()
    dist = explicit.arrays["distance"]
    assert np.abs(dist[until] - rk.arrays["distance"][until]).max() < 1e-2 * dist[until][-1]
    assert abs(explicit.summary["metrics"]["time_of_max_mouth_area"]
               - rk.summary["metrics"]["time_of_max_mouth_area"]) <= 0.01


def test_rk45_does_not_depend_on_the_origin() -> None:
    """A stiff pendulum (the spring's mass released under gravity) with its pin at the origin
    and 50 m from it along every axis: RK45's unknowns are displacements, so its relative
    tolerance sees the same numbers and the swings agree to round-off (with the positions as
    unknowns they differed by 4.8e-8 m, the tolerance relative to the 87 m of the far run)."""
    toml = SPRING.format(duration=0.3, integrator="rk45", dt=1e-5, axial="linear",
                         viscosity=0.0, v0=0.0).replace(
        "rtol = 1e-9", "rtol = 1e-6\ngravity = [0.0, 0.0, -9.81]")
    near = run(scene_from_toml(toml), _tmp(), progress=False)
    far = run(scene_from_toml(toml.replace("points = [[0, 0, 0], [1, 0, 0]]",
                                           "points = [[50, 50, 50], [51, 50, 50]]")),
              _tmp(), progress=False)
    assert near.arrays["positions"][-1, 1, 2] < -0.4          # it swung
    assert near.summary["steps"] == far.summary["steps"]
    moved = far.arrays["positions"] - near.arrays["positions"] - 50.0
    assert np.abs(moved).max() < 1e-12
    assert np.abs(far.arrays["velocities"] - near.arrays["velocities"]).max() < 1e-12


SPINNING_DUMBBELL = """
[simulation]
duration = 0.2
gravity = [0.0, 0.0, 0.0]
integrator = "rk45"
rtol = 1e-6
[model]
type = "lumped"
axial = "linear"
[[materials]]
name = "kevlar"
density = 1440.0
youngs_modulus = 7.0e10
diameter = 0.001
viscosity = 2.0e5
[[rods]]
name = "thread"
material = "kevlar"
points = [[0.0, 0, 0], [1.0, 0, 0]]
elements = 1
[[masses]]
node = "thread:start"
mass = 0.05
[[masses]]
node = "thread:end"
mass = 0.05
[initial]
velocities = [["thread:start", {u}, -5.0, 0.0], ["thread:end", {w}, 5.0, 0.0]]
[output]
frame_interval = 0.01
vtk = false
picture = false
plot = false
"""
"""Two masses on one stiff element spinning at 10 rad/s and ringing axially (outside check)."""


def test_rk45_does_not_depend_on_the_frames_velocity() -> None:
    """The dumbbell at rest and boosted by 1,000 m/s: RK45's unknowns are relative to a frame
    moving with the scene's initial mean velocity, so the same steps and relative motion (with
    the velocities as unknowns the boosted run took 997 steps instead of 1,212, 7.8 times the
    error, and its largest tension came out 1.74 % high)."""
    rest = run(scene_from_toml(SPINNING_DUMBBELL.format(u=-0.02, w=0.02)), _tmp(), progress=False)
    boosted = run(scene_from_toml(SPINNING_DUMBBELL.format(u=999.98, w=1000.02)), _tmp(),
                  progress=False)
    assert rest.summary["steps"] == boosted.summary["steps"]
    t = rest.arrays["time"]
    shift = 1000.0 * t[:, None] * np.array([1.0, 0.0, 0.0])
    moved = boosted.arrays["positions"] - rest.arrays["positions"] - shift[:, None, :]
    assert np.abs(moved).max() < 1e-9
    assert rest.arrays["tension"].max() == pytest.approx(boosted.arrays["tension"].max(),
                                                         rel=1e-9)


def _tmp():
    import tempfile

    return tempfile.mkdtemp(prefix="rodnet-test-")


@pytest.mark.parametrize("axial", ["tension-only", "linear"])
def test_fused_node_loop_equals_the_general_loop(axial) -> None:
    """march_nodes (the loop of the lumped model without bodies) and the general march give
    the same positions, velocities and largest tension to the last bit, with gravity and a
    ramped dead load."""
    from rodnet.integrate.explicit import scratch
    from rodnet.kernels import explicit as kx

    text = small_net_toml(n=2) + ('\n[[loads]]\nnode = "net:knot:12"\nforce = [3.0, -2.0, 40.0]'
                                  '\nramp = 0.02\n')
    p = prepare(scene_from_toml(text, [f"model.axial={axial}", "model.type=lumped",
                                       "simulation.gravity=[0, 0, -9.81]"]))
    problem, control = p.system.explicit_problem()
    assert kx.node_forces_only(problem, control) and len(problem.loads.nodes) == 1
    z = np.zeros
    bodies = kx.Bodies(z((0, 3)), z((0, 3)), z((0, 4)), z((0, 3, 3)), z((0, 3)), z((0, 3)))
    x = [p.state.q.x.copy() for _ in range(2)]
    v = [p.state.velocities.copy() for _ in range(2)]
    work = [scratch(problem) for _ in range(2)]
    peaks = [0.0, 0.0]
    for frame in range(5):
        t0, t1 = 0.01 * frame, 0.01 * (frame + 1)
        n = int(np.ceil(0.01 / control.dt))
        a = kx.march(x[0], z((0, 4)), v[0], z((0, 3)), bodies, t0, t1, n, (t1 - t0) / n,
                     problem, control, work[0])
        b = kx.march_nodes(x[1], v[1], t0, t1, n, (t1 - t0) / n, problem, work[1].f_node,
                           work[1].load_rate)
        assert a == b
        peaks = [max(peaks[0], a.peak), max(peaks[1], b.peak)]
    assert np.array_equal(x[0], x[1]) and np.array_equal(v[0], v[1]) and peaks[0] > 0.0
    assert np.abs(x[0] - p.state.q.x).max() > 0.01   # the net moved
