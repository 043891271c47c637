"""Contact inside the lumped model: the compiled kernel against the NumPy oracle, the consistent
tangent against finite differences, the explicit stability limit against the exact contact
frequency, and the travel limits of both integrators."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import trimesh

from rodnet.assembly import SparsityPattern
from rodnet.contact.forces import contact_state, nodal_force, nodal_tangents
from rodnet.integrate.explicit import integrate_explicit
from rodnet.kernels.contact_compiled import accumulate_contact, contact_scratch
from rodnet.models.system import ThreadSystem
from rodnet.run import prepare
from rodnet.scene import scene_from_toml
from rodnet.state import Configuration
from tests.contact.scenes import cord, run_ok

RNG = np.random.default_rng(5)


def four_bodies_scene(tmp_path: Path, diameter: float = 0.01, smoothing: float = 1e-3,
                      nodes: int = 400) -> str:
    """A long rod far from four bodies: a box, a cylinder, a sphere and a mesh (icosphere)."""
    mesh = tmp_path / "ball.stl"
    trimesh.creation.icosphere(subdivisions=2, radius=0.3).export(mesh)
    return f"""
[simulation]
integrator = "backward-euler"
[model]
type = "lumped"
axial = "linear"
{cord(diameter)}
[[rods]]
name = "r"
material = "cord"
points = [[-10.0, 0.0, 5.0], [10.0, 0.0, 5.0]]
elements = {nodes - 1}

[[bodies]]
name = "box"
shape = "box"
size = [0.6, 0.4, 0.3]
position = [0.0, 0.0, 0.0]
orientation_deg = [20.0, -35.0, 10.0]
fixed = true

[[bodies]]
name = "can"
shape = "cylinder"
size = [0.5, 0.5, 0.8]
position = [2.0, 0.0, 0.0]
orientation_deg = [0.0, 60.0, 0.0]
fixed = true

[[bodies]]
name = "ball"
shape = "sphere"
size = [0.6, 0.6, 0.6]
position = [4.0, 0.0, 0.0]
fixed = true

[[bodies]]
name = "mesh"
shape = "mesh"
file = "{mesh}"
position = [6.0, 0.0, 0.0]
orientation_deg = [0.0, 0.0, 45.0]
fixed = true

[contact]
stiffness = 2.0e3
damping = 3.0
friction = 0.4
smoothing = {smoothing}
slip_velocity = 0.05
points_per_segment = 3
"""


def near_surfaces(model, gap: tuple[float, float]) -> tuple[np.ndarray, np.ndarray]:
    """Node positions (N, 3) on a random walk near the four bodies' surfaces, with the signed
    distance of every node within ``gap``, and random velocities (N, 3)."""
    contact = model.contact.bodies
    n = model.structure.n_nodes
    x = np.empty((n, 3))
    for i in range(n):
        b = (i // 25) % contact.n_bodies
        shape, R, p = contact.shapes[b], contact.rotation[b], contact.position[b]
        # closest points of points inside the body lie on faces, away from the mirror planes
        # of a symmetric mesh, whose interior chords would tie between two closest triangles
        local = shape.query(RNG.uniform(0.8 * shape.bounds[0], 0.8 * shape.bounds[1])[None]).closest[0]
        normal = shape.query(local[None] * 1.001).normal[0]
        local = local + RNG.uniform(*gap) * normal
        x[i] = p + R @ local
    return x, RNG.normal(scale=0.2, size=(n, 3))


@pytest.fixture(scope="module")
def model(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("bodies")
    return prepare(scene_from_toml(four_bodies_scene(tmp))).system


def compiled(model, x, v, dt=0.0, with_moment=False):
    contact = model.contact
    force = np.zeros_like(x)
    scratch = contact_scratch(len(x), contact.n_bodies)
    scratch.active[:] = True
    scratch.clearance[:] = 0.0
    m = contact.start_motion()
    out = accumulate_contact(x, v, force, dt, contact.kernel_data, m.position, m.rotation,
                             m.velocity, m.omega, scratch)
    assert not scratch.taken.any()
    if with_moment:
        return force, scratch.body_force, scratch.body_moment, out
    return force, scratch.body_force, out


def numpy_contact(model):
    """The bodies of a system and their start pose, for the NumPy functions."""
    return model.contact.bodies, model.contact.start_motion()


def contact_matrix(model, blocks):
    """The contact tangent blocks (S, 6, 6) assembled on the free DOFs."""
    return SparsityPattern([model.contact.dofs], model.n_dof, model.free).matrix([blocks])


def test_compiled_contact_matches_the_numpy_oracle(model) -> None:
    x, v = near_surfaces(model, (-0.008, 0.012))
    force, body_force, (power, total, count, deepest, allowed) = compiled(model, x, v)
    expected = nodal_force(*numpy_contact(model), x, v)
    state = contact_state(*numpy_contact(model), x, v)
    assert 100 < count == state.count
    np.testing.assert_allclose(force, expected, rtol=1e-10, atol=1e-10 * np.abs(expected).max())
    np.testing.assert_allclose(body_force, state.body_force, rtol=1e-10, atol=1e-9)
    assert total == pytest.approx(state.total_force, rel=1e-10)
    assert deepest == pytest.approx(state.sunk, rel=1e-10) and deepest > 0
    assert power == pytest.approx(state.friction_power, rel=1e-10) and power > 0
    assert allowed == np.inf
    # every body takes part, and the reaction balances the nodal forces
    assert (np.abs(body_force).sum(axis=1) > 0).all()
    np.testing.assert_allclose(force.sum(axis=0), -body_force.sum(axis=0), atol=1e-9)


def test_contact_tangents_match_central_differences(tmp_path: Path) -> None:
    m = prepare(scene_from_toml(four_bodies_scene(tmp_path, nodes=80))).system
    x, v = near_surfaces(m, (0.0, 0.006))   # centrelines outside, within r + s of the surface
    vf = v.ravel()
    g, K, C = m.tangents(Configuration(x), vf, 0.0)
    assert nodal_tangents(*numpy_contact(m), x, v).force.any()
    h = 1e-7
    rows = RNG.choice(m.n_dof, 40, replace=False)
    for j in rows:
        e = np.zeros(m.n_dof)
        e[j] = h
        dx = (m.generalized_force(Configuration(x + e.reshape(-1, 3)), vf, 0.0)
              - m.generalized_force(Configuration(x - e.reshape(-1, 3)), vf, 0.0)) / (2 * h)
        dv = (m.generalized_force(Configuration(x), vf + e, 0.0)
              - m.generalized_force(Configuration(x), vf - e, 0.0)) / (2 * h)
        scale = np.abs(K.toarray()).max()
        np.testing.assert_allclose(K[:, j].toarray().ravel(), dx, atol=2e-5 * scale)
        np.testing.assert_allclose(C[:, j].toarray().ravel(), dv,
                                   atol=2e-5 * np.abs(C.toarray()).max())


CHAIN = """
[simulation]
duration = {duration}
integrator = "explicit"
adaptive = false
dt = {dt}
gravity = [0.0, 0.0, -9.81]
[model]
type = "lumped"
axial = "linear"
""" + cord(axial_stiffness=1.0) + """
[[rods]]
name = "r"
material = "cord"
points = [[-0.3, 0.0, 0.50102], [0.3, 0.0, 0.50102]]
elements = 12
[[bodies]]
name = "table"
shape = "box"
size = [1.0, 1.0, 1.0]
fixed = true
[contact]
stiffness = {k}
damping = 0.0
friction = 0.0
smoothing = 0.0
[output]
frame_interval = 0.01
vtk = false
"""


def test_stable_step_bounds_the_contact_frequency_of_a_chain_lying_on_a_box() -> None:
    """With every point pressed, the highest frequency of M^-1 K is the uniform bounce of the
    chain; the estimate must be below its limit 2/omega_max and not far below."""
    scene = scene_from_toml(CHAIN.format(duration=0.1, dt=1e-5, k=1e4))
    p = prepare(scene)
    m = p.system
    x = p.q0.x.copy()
    x[:, 2] = 0.5 + 0.001 - 1e-4   # all points pressed 0.1 mm
    t = nodal_tangents(*numpy_contact(m), x, np.zeros_like(x))
    K = contact_matrix(m, -t.d_position).toarray()
    free = m.free
    w2 = np.linalg.eigvals(K / m.dof_mass[free][:, None]).real.max()
    exact = 2.0 / np.sqrt(w2)
    estimate = m.contact.bodies.stable_step(m.contact.inv_mass)
    assert 0.6 * exact <= estimate <= exact


def test_explicit_friction_leaves_sliding_alone_and_stops_a_slow_slip() -> None:
    """(E2): friction acts on the slip the step would end with. A chain sliding at 1 m/s feels
    mu N (to the regularisation's 1e-8); one creeping at 1e-7 m/s with nothing else pulling it
    loses kinetic energy at every step and sticks."""
    p = prepare(scene_from_toml(CHAIN.format(duration=0.1, dt=1e-5, k=1e4).replace(
        "friction = 0.0", "friction = 0.5")))
    x = p.q0.x.copy()
    x[:, 2] = 0.5 + 0.001 - 1e-4
    sliding = np.tile([1.0, 0.0, 0.0], (len(x), 1))
    dt = 1e-5
    np.testing.assert_allclose(compiled(p.system, x, sliding, dt)[0],
                               compiled(p.system, x, sliding)[0], rtol=1e-7)
    creep = 1e-7 * sliding
    capped, plain = compiled(p.system, x, creep, dt)[0], compiled(p.system, x, creep)[0]
    np.testing.assert_allclose(capped[:, 2], plain[:, 2], rtol=1e-12)   # the normal force stays
    # steps of the contact alone (positions held): the slip's kinetic energy falls at every
    # step, and the chain sticks
    mass, v = p.model.mass, creep.copy()
    energies = [np.dot(mass, v[:, 0] ** 2)]
    for _ in range(20):
        v[:, 0] += dt * compiled(p.system, x, v, dt)[0][:, 0] / mass
        energies.append(np.dot(mass, v[:, 0] ** 2))
    assert np.all(np.diff(energies) <= 0.0)
    assert energies[1] < 0.3 * energies[0] and energies[-1] < 1e-12 * energies[0]


@pytest.mark.slow
def test_chain_pressed_on_a_box_is_stable_below_the_limit_and_not_above_the_exact_one() -> None:
    """The chain rests pressed into the box (gravity keeps every point in contact), so the
    contact springs act as linear springs: symplectic Euler is stable below the estimate and
    unstable above the exact limit 2 / omega_max."""
    scene = scene_from_toml(CHAIN.format(duration=0.1, dt=1e-5, k=1e4).replace(
        "gravity = [0.0, 0.0, -9.81]", "gravity = [0.0, 0.0, -200.0]"))
    p = prepare(scene)
    m = p.system
    depth = p.model.mass[1] * 200.0 / (2 * 1e4)    # an interior node on its own point and two halves
    x0 = p.q0.x.copy()
    x0[:, 2] = 0.5 + 0.001 - depth
    # the exact equilibrium: one Newton step, the pressed contact being linear in the depth
    g, K, _ = m.tangents(Configuration(x0), np.zeros(m.n_dof), 0.0)
    z = np.arange(2, m.n_dof, 3)
    x0[:, 2] -= np.linalg.solve(K.toarray()[np.ix_(z, z)], g[z])
    assert np.abs(m.generalized_force(Configuration(x0), np.zeros(m.n_dof), 0.0)[z]).max() < 1e-10
    x0[0, 2] -= 0.01 * depth                  # a small push that keeps every point pressed
    t = nodal_tangents(*numpy_contact(m), x0, np.zeros_like(x0))
    K = contact_matrix(m, -t.d_position).toarray()
    exact = 2.0 / np.sqrt(np.linalg.eigvals(K / m.dof_mass[m.free][:, None]).real.max())

    def swing(dt: float) -> float:
        times = np.arange(0, 2001, 100) * dt      # whole steps between frames: the step is dt
        z = []
        control = m.control._replace(dt=dt, near_dt=dt, min_dt=1e-6 * dt)
        system = ThreadSystem(m.model, m.contact, control)
        state = system.initial_state(Configuration(x0.copy()), np.zeros(m.n_dof))
        integrate_explicit(system, state, times, lambda t, s: z.append(s.q.x[:, 2].copy()))
        return float(np.abs(np.array(z) - x0[:, 2]).max())

    assert swing(0.95 * m.contact.combined_step(p.model.stable_step())) < 0.1 * depth
    assert swing(1.1 * exact) > 100 * depth


PLATE_SHOT = """
[simulation]
duration = 0.004
integrator = "{integrator}"
dt = 1.0e-3
gravity = [0.0, 0.0, 0.0]
[model]
type = "lumped"
axial = "linear"
""" + cord(diameter=1.0e-3, axial_stiffness=10.0) + """
[[rods]]
name = "r"
material = "cord"
points = [[0.0, 0.0, 0.0], [0.05, 0.0, 0.0]]
elements = 1
velocity = [0.0, 0.0, 10.0]
[[bodies]]
name = "plate"
shape = "box"
size = [0.5, 0.5, 0.002]
position = [0.0, 0.0, 0.006]
fixed = true
[contact]
stiffness = 1.0e5
damping = 1.0
friction = 0.0
[output]
frame_interval = 1.0e-3
vtk = false
"""


@pytest.mark.parametrize("integrator", ["explicit", "backward-euler"])
def test_travel_limit_stops_a_fast_rod_at_a_thin_plate(integrator: str) -> None:
    """At 10 m/s backward Euler's first step of 1 ms would carry the rod from 6 mm in front of
    the 2 mm plate to 3 mm behind it, where no contact force acts; the travel limit shortens the
    steps near the plate and keeps the rod in front (explicit: the step is limited as well)."""
    text = PLATE_SHOT.format(integrator=integrator)
    r = run_ok(text)
    z = r.arrays["positions"][:, :, 2]
    assert z.max() < 0.006 - 0.001                        # never reached the near face
    assert (r.arrays["velocities"][-1, :, 2] < 0).all()   # bounced back
    limit = prepare(scene_from_toml(text)).system.contact.bodies.travel_limit[0]
    assert r.summary["integrator"]["dt_min"] <= limit / 10.0 * 1.0001


def test_travel_limit_of_a_plate_turned_inside_its_mesh_file(tmp_path: Path) -> None:
    """The 2 mm plate written to its mesh file already turned by 45 degrees: the travel limit
    takes its thickness from the mesh's oriented bounding box, so it is the box plate's, and
    backward Euler's rod stays in front of it (with the file's axis-aligned box, 0.35 m thick,
    the rod ended 64 mm behind the plate, the run ok: outside check)."""
    plate = trimesh.creation.box(extents=[0.5, 0.5, 0.002])
    plate.apply_transform(trimesh.transformations.rotation_matrix(np.pi / 4, [0.0, 1.0, 0.0]))
    plate.export(tmp_path / "plate.stl")
    text = PLATE_SHOT.format(integrator="backward-euler").replace(
        'shape = "box"\nsize = [0.5, 0.5, 0.002]\nposition = [0.0, 0.0, 0.006]',
        f'shape = "mesh"\nfile = "{tmp_path / "plate.stl"}"\nposition = [0.025, 0.0, 0.06]')
    assert 'shape = "mesh"' in text
    r = run_ok(text.replace("duration = 0.004", "duration = 0.008"))   # the rod turns as it hits
    normal = np.array([np.sin(np.pi / 4), 0.0, np.cos(np.pi / 4)])   # the plate's
    height = (r.arrays["positions"] - [0.025, 0.0, 0.06]) @ normal
    assert height.max() < -0.001                           # never reached the near face
    boxed = PLATE_SHOT.format(integrator="backward-euler")
    limits = [prepare(scene_from_toml(t)).system.contact.bodies.travel_limit[0]
              for t in (text, boxed)]
    assert limits[0] == pytest.approx(limits[1], rel=1e-4)
