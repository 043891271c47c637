"""Contact of Cosserat rods with bending and torsion (implicit integrators) with fixed bodies: the
contact force on the translational DOFs with its consistent tangent inside the rod's elements, a
rod resting on a box at the penalty depth, a rod hanging over a box edge held by its bending
stiffness, and a net of pinned-knot rods thrown at a thin plate. On every frame no thread
centreline point may be inside a body."""

from __future__ import annotations

import numpy as np
import pytest

from rodnet.contact.forces import nodal_tangents
from rodnet.errors import SceneError
from rodnet.run import prepare
from rodnet.models.cosserat.model import CosseratModel
from rodnet.scene import scene_from_toml
from rodnet.state import Configuration as RodConfiguration
from tests.contact.scenes import cord, run_ok
from tests.contact.test_contact_runs import centreline_points, net_at_plate, smallest_distance

G = 9.81
RNG = np.random.default_rng(7)

ROD_ON_BOX = """
[simulation]
duration = {duration}
integrator = "{integrator}"
dt = {dt}
adaptive = {adaptive}
rho_inf = 0.0
gravity = [0.0, 0.0, -9.81]
[model]
type = "cosserat"
bending = true
torsion = true
axial = "linear"
""" + cord() + """
[[rods]]
name = "r"
material = "cord"
points = {points}
elements = 4
[[masses]]
node = "r:start"
mass = 0.1
[[bodies]]
name = "table"
shape = "box"
size = [1.0, 1.0, 1.0]
fixed = true
[contact]
stiffness = 1.0e5
damping = 60.0
friction = 0.3
[output]
frame_interval = 0.005
vtk = false
"""
STANDING = "[[0.0, 0.0, 0.505], [0.0, 0.0, 0.605]]"


def rod_text(integrator: str = "backward-euler", points: str = STANDING, duration: float = 1.0,
             adaptive: str = "true", dt: float = 1e-3) -> str:
    """A 0.1 m rod of four elements with bending and torsion, its 0.1 kg end 4 mm above a box."""
    return ROD_ON_BOX.format(integrator=integrator, points=points, duration=duration,
                             adaptive=adaptive, dt=dt)


def test_rod_model_with_bodies_is_the_contact_model() -> None:
    p = prepare(scene_from_toml(rod_text()))
    assert isinstance(p.model, CosseratModel) and p.system.contact is not None
    assert p.system.n_dof == 6 * 5          # positions and rotations: the rod model, not a cable


def test_contact_tangent_of_the_rod_model_matches_central_differences() -> None:
    """Nodes pushed into the box with random velocities: K and C of the whole model (elements
    plus contact) against central differences of g on positions and rotations."""
    p = prepare(scene_from_toml(rod_text(points="[[-0.05, 0.0, 0.5012], [0.05, 0.0, 0.5012]]")))
    m = p.system
    x = p.q0.x.copy()
    x[:, 2] = 0.5 + 1e-3 - RNG.uniform(0.0, 2e-4, len(x))
    x[:, :2] += RNG.normal(0.0, 1e-3, (len(x), 2))
    q = RodConfiguration(x, p.q0.quat)
    v = RNG.normal(0.0, 0.05, m.n_dof)
    assert np.count_nonzero(nodal_tangents(m.contact.bodies, m.contact.start_motion(), x,
                                           v[:3 * m.n_nodes].reshape(-1, 3)).d_position) > 0
    g, K, C = m.tangents(q, v, 0.0)
    K, C = K.toarray(), C.toarray()
    h = 1e-8
    for j in range(m.n_dof):
        e = np.zeros(m.n_dof)
        e[j] = h
        dq = (m.generalized_force(m.retract(q, e), v, 0.0)
              - m.generalized_force(m.retract(q, -e), v, 0.0)) / (2 * h)
        dv = (m.generalized_force(q, v + e, 0.0) - m.generalized_force(q, v - e, 0.0)) / (2 * h)
        np.testing.assert_allclose(K[:, j], dq, atol=1e-5 * np.abs(K).max())
        np.testing.assert_allclose(C[:, j], dv, atol=1e-5 * np.abs(C).max())


@pytest.mark.parametrize("integrator", ["backward-euler", "generalized-alpha", "explicit"])
def test_heavy_end_of_a_bending_rod_rests_at_the_penalty_depth(integrator: str) -> None:
    # the explicit step is that of the light rod nodes on the damped contact springs (1.5 us):
    # 0.25 s, about 70 contact periods of the heavy end after it lands
    text = rod_text(integrator, duration=0.25 if integrator == "explicit" else 1.0)
    r = run_ok(text)
    weight = (0.1 + 0.01 * 0.1) * G         # the whole rod's weight rests on its lower node
    depth = 0.5 + 1e-3 - r.arrays["positions"][-1, 0, 2]
    assert depth == pytest.approx(weight / 1e5, rel=0.01)
    assert -r.arrays["body_force"][-1, 0, 2] == pytest.approx(weight, rel=0.01)
    assert r.arrays["contact_count"][-1] == 1
    assert r.arrays["positions"][:, 0, 2].min() < 0.5 + 1e-3   # it fell onto the box
    assert smallest_distance(r, text) > 0.0


def rod_net_at_plate(integrator: str = "backward-euler") -> str:
    """The 5 x 5 net of ``test_contact_runs`` at 50 m/s into a 2 mm plate tilted by 30 degrees,
    its threads Cosserat rods with bending and torsion and pinned knots."""
    return net_at_plate().replace('integrator = "explicit"', f'integrator = "{integrator}"') \
        .replace('type = "lumped"', 'type = "cosserat"\nbending = true\ntorsion = true\n'
                 'knots = "pinned"')


@pytest.mark.parametrize("integrator", ["backward-euler", "explicit"])
def test_rod_net_at_50_m_s_does_not_pass_through_a_2_mm_plate(integrator: str) -> None:
    text = rod_net_at_plate(integrator)
    r = run_ok(text)
    contact = prepare(scene_from_toml(text)).system.contact.bodies
    local = (centreline_points(r) - contact.position[0]) @ contact.rotation[0]      # (F, S, 21, 3)
    over_plate = (np.abs(local[..., 0]) < 0.5) & (np.abs(local[..., 1]) < 0.5)
    assert (local[0, ..., 2] < -0.1).all()
    assert not (over_plate & (local[..., 2] >= 0.0)).any()
    assert smallest_distance(r, text) > 0.0
    # it did hit and bounce: every node approached at 50 cos 30 m/s and none still does
    approach = r.arrays["velocities"] @ contact.rotation[0][:, 2]
    np.testing.assert_allclose(approach[0], 50.0 * np.cos(np.radians(30.0)))
    assert approach[-1].max() < 0.05 * 50.0
    assert (local[-1, ..., 2] < 0.0).all()
    assert r.arrays["contact_force"].max() > 0.0
