"""Free rigid bodies in whole explicit runs: momentum of a net hitting a tumbling body, torque-free
tumbling, free flight as written to result.npz and VTK, and a mass on a fixed inclined plane
(elements/contact/FORMULATION.md section 8, (R1)-(R4); (F2), (F4))."""

from __future__ import annotations

import meshio
import numpy as np
import pytest

from rodnet.integrate.explicit import integrate_explicit
from rodnet.kernels import so3
from rodnet.errors import SceneError
from rodnet.run import RunResult, prepare
from rodnet.scene import scene_from_toml
from tests.contact.scenes import cord, run_ok

G = 9.81

NET_AND_BOX = """
[simulation]
duration = 0.12
integrator = "explicit"
[model]
type = "lumped"
[[materials]]
name = "kevlar"
density = 1440.0
youngs_modulus = 7.0e10
diameter = 1.0e-3
viscosity = 1.0e4
[net]
nodes_per_side = 5
mesh_length = 0.1
material = "kevlar"
packing = 1.0
corner_mass = 2.0e-3
corner_thread_length = 0.05
launch_speed = 3.0
launch_angle_deg = 20.0
[[bodies]]
name = "box"
shape = "box"
size = [0.3, 0.2, 0.1]
mass = 0.05
position = [0.04, -0.03, 0.2]
orientation_deg = [20.0, -10.0, 35.0]
velocity = [0.3, 0.2, -4.0]
angular_velocity_deg = [300.0, -500.0, 200.0]
[contact]
stiffness = 1.0e4
damping = 0.5
friction = 0.4
[output]
frame_interval = 1.0e-3
vtk = false
"""


def momenta(r: RunResult, text: str) -> tuple[np.ndarray, np.ndarray]:
    """Total linear momentum (F, 3) [kg m/s] and angular momentum about the world origin (F, 3)
    [kg m^2/s] of nodes plus bodies, from the result arrays alone (``node_mass``,
    ``body_mass``, ``body_inertia``: the masses the scene built)."""
    built = prepare(scene_from_toml(text))
    m, mass, inertia = r.arrays["node_mass"], r.arrays["body_mass"], r.arrays["body_inertia"]
    np.testing.assert_array_equal(m, built.mass)
    np.testing.assert_array_equal(mass, built.system.contact.bodies.mass)
    np.testing.assert_array_equal(inertia, built.system.contact.bodies.inertia)
    x, v = r.arrays["positions"], r.arrays["velocities"]
    p, u = r.arrays["body_positions"], r.arrays["body_velocities"]
    w, q = r.arrays["body_angular_velocities"], r.arrays["body_rotations"]
    linear = np.einsum("n,fni->fi", m, v) + np.einsum("b,fbi->fi", mass, u)
    angular = np.einsum("n,fni->fi", m, np.cross(x, v)) \
        + np.einsum("b,fbi->fi", mass, np.cross(p, u))
    for f in range(len(q)):
        for b in range(len(mass)):
            R = so3.quat_to_matrix(q[f, b])
            angular[f] += R @ inertia[b] @ R.T @ w[f, b]
    return linear, angular


def test_net_hitting_a_tumbling_box_conserves_linear_and_angular_momentum() -> None:
    r = run_ok(NET_AND_BOX)
    linear, angular = momenta(r, NET_AND_BOX)
    assert np.abs(linear - linear[0]).max() <= 1e-6 * np.linalg.norm(linear[0])
    assert np.abs(angular - angular[0]).max() <= 1e-6 * np.linalg.norm(angular[0])
    # contact did happen, on many points, and changed the box's motion a lot
    assert r.arrays["contact_force"].max() > 1.0 and r.arrays["contact_count"].max() >= 10
    u, w = r.arrays["body_velocities"][:, 0], r.arrays["body_angular_velocities"][:, 0]
    assert u[-1, 2] - u[0, 2] > 0.3          # slowed down by the net
    assert np.linalg.norm(w[-1] - w[0]) > 0.05 * np.linalg.norm(w[0])
    # the moment is not zero: angular momentum moved between the box's spin and the rest
    spin = np.abs(np.diff(r.arrays["body_moment"][:, 0], axis=0)).max()
    assert spin > 0.0
    # and the saved contact force balances the nodes' momentum change only with the body's
    nodes = np.einsum("n,fni->fi", prepare(scene_from_toml(NET_AND_BOX)).mass,
                      r.arrays["velocities"])
    assert np.abs(nodes - nodes[0]).max() > 0.1 * np.linalg.norm(linear[0])


ROD_NET_AND_BOX = NET_AND_BOX.replace('type = "lumped"', 'type = "cosserat"\nknots = "pinned"')


def test_rod_net_hitting_a_tumbling_box_conserves_linear_and_angular_momentum() -> None:
    """Cosserat threads with bending and torsion (explicit, scaled rotary inertia): the nodes'
    moments of momentum plus the rotations' spins ``R J W`` plus the box's."""
    p = prepare(scene_from_toml(ROD_NET_AND_BOX))
    model, c = p.model, p.system.contact.bodies
    n = model.n_nodes
    frames = []

    def keep(t: float, state) -> None:
        q, v, m = state.q, state.v, state.bodies
        frames.append((q.x.copy(), q.quat.copy(), v[:3 * n].reshape(-1, 3).copy(),
                       v[3 * n:].reshape(-1, 3).copy(), m.position.copy(), m.velocity.copy(),
                       m.momentum.copy()))

    integrate_explicit(p.system, p.state, p.times, keep)
    x, quat, u, W, P, U, L = (np.array(a) for a in zip(*frames))
    linear = np.einsum("n,fni->fi", model.node_mass, u) + np.einsum("b,fbi->fi", c.mass, U)
    R = so3.quat_to_matrix(quat.reshape(-1, 4)).reshape(*quat.shape[:2], 3, 3)
    angular = (np.einsum("n,fni->fi", model.node_mass, np.cross(x, u))
               + np.einsum("frij,frj->fi", R, model.rotary_inertia * W)
               + np.einsum("b,fbi->fi", c.mass, np.cross(P, U)) + L.sum(axis=1))
    assert np.abs(linear - linear[0]).max() <= 1e-6 * np.linalg.norm(linear[0])
    assert np.abs(angular - angular[0]).max() <= 1e-6 * np.linalg.norm(angular[0])
    assert U[-1, 0, 2] - U[0, 0, 2] > 0.3          # the net did slow the box down
    assert p.built.rotary_inertia_scale > 1.0 and p.system.control.near_dt < p.dt


TUMBLER = """
[simulation]
duration = {duration}
integrator = "explicit"
[model]
type = "lumped"
""" + cord() + """
[[rods]]
name = "r"
material = "cord"
points = [[20.0, 0.0, 0.0], [20.1, 0.0, 0.0]]
elements = 1
[[bodies]]
name = "b"
shape = "{shape}"
size = {size}
mass = 3.0
position = [0.5, -0.2, 1.0]
orientation_deg = [30.0, 40.0, -20.0]
velocity = [0.2, -0.1, 0.3]
angular_velocity_deg = {omega}
[output]
frame_interval = 0.01
vtk = {vtk}
"""


def tumbler(shape: str = "box", size: str = "[0.6, 0.4, 0.2]",
            omega: str = "[40.0, 200.0, 20.0]", duration: float = 3.0, vtk: str = "false") -> str:
    return TUMBLER.format(shape=shape, size=size, omega=omega, duration=duration, vtk=vtk)


def body_frame_motion(r: RunResult, text: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """World angular momentum about the centre of mass (F, 3), rotational kinetic energy (F,)
    and rotations (F, 3, 3) of body 0."""
    J = prepare(scene_from_toml(text)).system.contact.bodies.inertia[0]
    q, w = r.arrays["body_rotations"][:, 0], r.arrays["body_angular_velocities"][:, 0]
    R = np.array([so3.quat_to_matrix(qi) for qi in q])
    L = np.einsum("fij,jk,flk,fl->fi", R, J, R, w)
    return L, 0.5 * np.einsum("fi,fi->f", L, w), R


def test_torque_free_tumbling_keeps_angular_momentum_and_bounded_energy() -> None:
    """A box spun near its unstable middle axis flips over and over: the world angular momentum
    stays, the energy does not drift."""
    text = tumbler()
    r = run_ok(text)
    L, energy, R = body_frame_motion(r, text)
    np.testing.assert_allclose(L, np.broadcast_to(L[0], L.shape), rtol=0, atol=1e-12 * np.linalg.norm(L[0]))
    assert np.ptp(energy) <= 1e-5 * energy[0]
    # it really tumbles: the spin about the middle body axis reverses (Dzhanibekov flip)
    spin = np.einsum("fji,fj->fi", R, r.arrays["body_angular_velocities"][:, 0])
    assert spin[0, 1] > 3.0 and spin[-1, 1] < -3.0
    assert r.arrays["contact_force"].max() == 0.0


def test_symmetric_body_precesses_about_its_angular_momentum_at_L_over_I_transverse() -> None:
    """Torque-free axisymmetric top: the symmetry axis turns about the fixed L at |L| / I_t."""
    text = tumbler("cylinder", "[0.4, 0.4, 1.0]", "[90.0, -60.0, 600.0]")
    r = run_ok(text)
    L, _, R = body_frame_motion(r, text)
    J = prepare(scene_from_toml(text)).system.contact.bodies.inertia[0]
    transverse = J[0, 0]
    axis = L[0] / np.linalg.norm(L[0])
    t = r.arrays["time"]
    rate = np.linalg.norm(L[0]) / transverse
    expected = np.array([so3.quat_to_matrix(so3.quat_from_rotvec(rate * ti * axis)) @ R[0][:, 2]
                         for ti in t])
    assert rate * t[-1] > 2.0 * np.pi   # more than one turn
    np.testing.assert_allclose(R[:, :, 2], expected, atol=1e-6)


def test_free_flight_is_written_to_result_and_vtk(tmp_path) -> None:
    """Gravity, a velocity and a spin about a principal axis: the centre of mass follows
    p0 + v0 t + g t^2 / 2 (to the symplectic Euler term g h t / 2), the rotation exp(omega t) R0
    (to the phase error of (R3))."""
    text = tumbler("sphere", "[0.3, 0.3, 0.3]", "[0.0, 0.0, 120.0]", duration=0.5, vtk="true")
    text = text.replace("[simulation]", "[simulation]\ngravity = [0.0, -1.0, -9.81]")
    r = run_ok(text, directory=str(tmp_path))
    t = r.arrays["time"]
    g, v0, p0 = np.array([0.0, -1.0, -9.81]), np.array([0.2, -0.1, 0.3]), np.array([0.5, -0.2, 1.0])
    p = r.arrays["body_positions"][:, 0]
    h = r.summary["integrator"]["dt"]
    np.testing.assert_allclose(p, p0 + np.outer(t, v0) + 0.5 * np.outer(t**2, g),
                               atol=0.5 * np.linalg.norm(g) * h * t[-1] + 1e-9)
    np.testing.assert_allclose(r.arrays["body_velocities"][:, 0], v0 + np.outer(t, g), atol=1e-9)
    bodies = prepare(scene_from_toml(text)).system.contact.bodies
    R0, w = bodies.rotation[0], bodies.omega[0]
    np.testing.assert_allclose(w, R0 @ np.radians([0.0, 0.0, 120.0]), atol=1e-12)
    np.testing.assert_allclose(r.arrays["body_angular_velocities"][:, 0],
                               np.broadcast_to(w, (len(t), 3)), atol=1e-12)
    # (R3) about a principal axis turns by asin(h |w|) per step, not h |w|: a phase error of
    # (h |w|)^2 / 6 of the angle
    phase = np.linalg.norm(w) * t[-1] * (h * np.linalg.norm(w)) ** 2 / 6.0
    for f in (0, len(t) // 2, len(t) - 1):
        R = so3.quat_to_matrix(r.arrays["body_rotations"][f, 0])
        np.testing.assert_allclose(R, so3.quat_to_matrix(so3.quat_from_rotvec(w * t[f])) @ R0,
                                   atol=1e-9 + 1.01 * phase)
        surface = meshio.read(tmp_path / "vtk" / f"body_0_{f:05d}.vtu").points
        first = meshio.read(tmp_path / "vtk" / "body_0_00000.vtu").points
        np.testing.assert_allclose(surface, p[f] + (first - p0) @ (R @ R0.T).T, atol=1e-9)


INCLINE = """
[simulation]
duration = {duration}
integrator = "explicit"
gravity = [0.0, 0.0, -9.81]
[model]
type = "lumped"
axial = "linear"
""" + cord(axial_stiffness=1.0e4) + """
[[rods]]
name = "r"
material = "cord"
points = [{a}, {b}]
elements = 1
[[masses]]
node = "r:start"
mass = 0.1
[[masses]]
node = "r:end"
mass = 0.1
[[bodies]]
name = "slope"
shape = "box"
size = [4.0, 1.0, 0.2]
orientation_deg = [0.0, {angle_deg}, 0.0]
fixed = true
[contact]
stiffness = 1.0e5
damping = 60.0
friction = {mu}
slip_velocity = 1.0e-3
[output]
frame_interval = 0.01
vtk = false
"""
MU = 0.3


def incline(angle: float, duration: float
            ) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
    """A 0.1 m rod with 0.1 kg at each end lying along the fall line of a box tilted by
    ``angle`` [rad] about y, 1 um above it. Returns time (F,), downhill position and velocity
    of the rod's middle (F,), and the explicit step [s]."""
    c, s = np.cos(angle), np.sin(angle)
    downhill, normal = np.array([c, 0.0, -s]), np.array([s, 0.0, c])
    lift = (0.1 + 1.0e-3 + 1.0e-6) * normal
    a, b = lift - 0.05 * downhill, lift + 0.05 * downhill
    text = INCLINE.format(duration=duration, a=a.tolist(), b=b.tolist(), angle_deg=np.degrees(angle),
                          mu=MU)
    r = run_ok(text)
    middle_x = r.arrays["positions"].mean(axis=1)
    middle_v = r.arrays["velocities"].mean(axis=1)
    assert r.arrays["contact_count"][-1] == 3   # both ends and the middle point
    return (r.arrays["time"], middle_x @ downhill, middle_v @ downhill,
            r.summary["integrator"]["dt"])


def test_mass_on_an_inclined_plane_slides_with_g_sin_minus_mu_cos() -> None:
    angle = np.arctan(1.5 * MU)
    t, s, u, _ = incline(angle, 0.5)
    i1, i2 = np.searchsorted(t, 0.2), len(t) - 1
    measured = (u[i2] - u[i1]) / (t[i2] - t[i1])
    assert measured == pytest.approx(G * (np.sin(angle) - MU * np.cos(angle)), rel=0.01)


def test_mass_on_an_inclined_plane_below_the_friction_angle_sticks() -> None:
    """'Stick' of regularised friction is a creep at the speed (F4), here about 1 mm/s, against
    the 0.4 m/s it would reach in 0.5 s without friction. Explicit friction (E2) acts on the slip
    the step would end with, which the downhill pull of the step raises: the rod creeps slower
    than (F4) says, by up to one step's pull h g sin(angle) (measured 0.69 against 1.33 mm/s),
    and steadily."""
    angle = np.arctan(0.8 * MU)
    t, s, u, h = incline(angle, 0.5)
    ratio = np.tan(angle) / MU
    creep = 1.0e-3 * ratio / np.sqrt(1.0 - ratio**2)
    assert creep - h * G * np.sin(angle) < u[-1] < creep
    assert u[-1] == pytest.approx(u[len(u) // 2], rel=1e-6)
    assert s[-1] - s[0] < 1.0e-3


def floor_and_box(integrator: str, body: bool = True) -> str:
    """A 1 kg box (0.2 x 0.2 x 0.1 m) sliding at 2 m/s along two pinned 10 mm lumped rods (every
    node held: only the box can move) under gravity, friction 0.3."""
    supports = "".join(f'[[supports]]\nnode = "{rod}:{k}"\nfix = "pin"\n'
                       for rod in ("left", "right") for k in range(11))
    box = """
[[bodies]]
name = "box"
shape = "box"
size = [0.2, 0.2, 0.1]
mass = 1.0
position = [0.3, 0.0, 0.0551]
velocity = [2.0, 0.0, 0.0]
""" if body else ""
    return f"""
[simulation]
duration = 0.2
integrator = "{integrator}"
gravity = [0.0, 0.0, -9.81]
[model]
type = "lumped"
[[materials]]
name = "floor"
density = 1000.0
youngs_modulus = 1.0e9
diameter = 0.01
[[rods]]
name = "left"
material = "floor"
points = [[0.0, -0.05, 0.0], [1.0, -0.05, 0.0]]
elements = 10
[[rods]]
name = "right"
material = "floor"
points = [[0.0, 0.05, 0.0], [1.0, 0.05, 0.0]]
elements = 10
{supports}{box}
[contact]
stiffness = 1.0e5
damping = 100.0
friction = 0.3
[output]
frame_interval = 0.01
vtk = false
"""


@pytest.mark.parametrize("integrator", ["explicit", "bdf2"])
def test_a_box_slides_on_threads_held_at_every_node(integrator: str) -> None:
    """A structure held at every node runs when a free body can move (the box decelerates at
    mu g); without the body it is refused, its long list of supports cut short."""
    r = run_ok(floor_and_box(integrator))
    t, u = r.arrays["time"], r.arrays["body_velocities"][:, 0, 0]
    i1, i2 = np.searchsorted(t, 0.05), np.searchsorted(t, 0.2)
    assert (u[i1] - u[i2]) / (t[i2] - t[i1]) == pytest.approx(0.3 * G, rel=0.02)
    with pytest.raises(SceneError, match=r"nothing can move") as refused:
        prepare(scene_from_toml(floor_and_box(integrator, body=False)))
    assert "'left:7', ... (22 items)]: every node is supported" in str(refused.value)
