"""Whole runs with fixed bodies: a mass resting on a box at the penalty depth, a net shot at a thin
plate, a thread dragged across a box with Coulomb friction, explicit against implicit, cable
threads, and the result files. On every frame no thread centreline point may be inside a body."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from rodnet.models.lumped import LumpedModel
from rodnet.run import RunResult, prepare
from rodnet.scene import scene_from_toml
from tests.contact.scenes import cord, run_ok

G = 9.81

DROP = """
[simulation]
duration = {duration}
integrator = "{integrator}"
dt = {dt}
adaptive = {adaptive}
gravity = [0.0, 0.0, -9.81]
[model]
type = "{model}"
bending = false
torsion = false
axial = "linear"
""" + cord() + """
[[rods]]
name = "r"
material = "cord"
points = [[0.0, 0.0, 0.505], [0.0, 0.0, 0.605]]
elements = 1
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
vtk = {vtk}
"""


def drop_text(integrator: str = "explicit", model: str = "lumped", adaptive: str = "true",
              vtk: str = "false", duration: float = 1.0, dt: float = 1e-4) -> str:
    """A 0.1 m rod standing on its 0.1 kg lower end, 4 mm above a box."""
    return DROP.format(integrator=integrator, model=model, adaptive=adaptive, vtk=vtk,
                       duration=duration, dt=dt)


def drop(integrator: str = "explicit", model: str = "lumped", adaptive: str = "true",
         vtk: str = "false", directory: str | None = None, duration: float = 1.0,
         dt: float = 1e-4) -> RunResult:
    return run_ok(drop_text(integrator, model, adaptive, vtk, duration, dt), directory=directory)


def centreline_points(r: RunResult, samples: int = 20) -> np.ndarray:
    """``samples + 1`` evenly spaced points on every segment, on every frame: (F, S, samples + 1,
    3) [m], from the start node to the end node."""
    x, seg = r.arrays["positions"], r.arrays["segments"]
    xi = np.linspace(0.0, 1.0, samples + 1)[None, None, :, None]
    return (1 - xi) * x[:, seg[:, 0], None] + xi * x[:, seg[:, 1], None]


def smallest_distance(r: RunResult, scene_text: str, samples: int = 20) -> float:
    """The smallest signed distance [m] of any of ``samples`` points per segment to any body,
    over every frame (positive: every centreline point outside every body)."""
    contact = prepare(scene_from_toml(scene_text)).system.contact.bodies
    points = centreline_points(r, samples).reshape(-1, 3)
    smallest = np.inf
    for b, shape in enumerate(contact.shapes):
        local = (points - contact.position[b]) @ contact.rotation[b]
        smallest = min(smallest, float(shape.query(local).distance.min()))
    return smallest


@pytest.mark.parametrize("integrator", ["explicit", "backward-euler", "generalized-alpha"])
def test_heavy_end_of_a_rod_rests_at_the_penalty_depth(integrator: str) -> None:
    r = drop(integrator)
    mass = 0.1 + 0.01 * 0.1            # the whole rod's weight rests on its lower node
    depth = 0.5 + 1e-3 - r.arrays["positions"][-1, 0, 2]
    assert depth == pytest.approx(mass * G / 1e5, rel=0.01)
    assert r.arrays["contact_count"][-1] == 1
    assert -r.arrays["body_force"][-1, 0, 2] == pytest.approx(mass * G, rel=0.01)
    assert smallest_distance(r, drop_text(integrator)) > 0.0


def test_explicit_and_implicit_bounces_agree() -> None:
    explicit = drop("explicit", duration=0.2)
    implicit = drop("generalized-alpha", adaptive="false", duration=0.2, dt=2e-4)
    z_e, z_i = explicit.arrays["positions"][:, 0, 2], implicit.arrays["positions"][:, 0, 2]
    fall = 0.505 - z_e.min()
    assert fall > 0.004 and z_e.max() > 0.5013               # it hit the box and bounced
    assert np.abs(z_e - z_i).max() < 0.02 * fall


def test_cable_threads_take_the_same_contact() -> None:
    cable, lumped = drop("backward-euler", model="cosserat"), drop("backward-euler")
    cable_system = prepare(scene_from_toml(drop_text("backward-euler", "cosserat"))).system
    assert isinstance(cable_system.model, LumpedModel) and cable_system.contact is not None
    np.testing.assert_allclose(cable.arrays["positions"], lumped.arrays["positions"], atol=1e-12)


def test_results_hold_bodies_and_contact_series(tmp_path: Path) -> None:
    r = drop(vtk="true", directory=str(tmp_path))
    data = np.load(tmp_path / "result.npz")
    frames = len(data["time"])
    assert data["body_positions"].shape == (frames, 1, 3) and (data["body_positions"] == 0).all()
    assert data["body_rotations"].shape == (frames, 1, 4)
    np.testing.assert_array_equal(data["body_rotations"][:, 0], [[1.0, 0, 0, 0]] * frames)
    for key in ("contact_force", "contact_count", "friction_work"):
        assert data[key].shape == (frames,)
    assert data["body_force"].shape == (frames, 1, 3) and list(data["body_names"]) == ["table"]
    assert data["contact_count"][0] == 0 and data["contact_count"][-1] == 1
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert summary["bodies"] == {"table": 0}
    assert len(summary["contact"]["force"]) == len(summary["contact"]["time"]) == frames
    metrics = summary["metrics"]
    assert metrics["max_contact_force_at_frames"] == pytest.approx(data["contact_force"].max())
    assert metrics["max_contact_force"] >= metrics["max_contact_force_at_frames"]  # every step
    assert summary["scene"]["bodies"][0]["shape"] == "box"
    bodies = sorted((tmp_path / "vtk").glob("body_0_*.vtu"))
    assert len(bodies) == frames
    assert 'part="1"' in (tmp_path / "result.pvd").read_text()
    pv = pytest.importorskip("pyvista")
    reader = pv.get_reader(str(tmp_path / "result.pvd"))
    reader.set_active_time_point(frames - 1)
    blocks = reader.read()
    assert blocks.n_blocks == 2 and blocks[1].n_cells == 12
    np.testing.assert_allclose(blocks[1].bounds, [-0.5, 0.5, -0.5, 0.5, -0.5, 0.5])


def net_at_plate(speed: float = 50.0) -> str:
    """A flat 5 x 5 net flying at ``speed`` along +z into a 2 mm plate tilted by 30 degrees."""
    knots = "".join(f'[[masses]]\nnode = "net:knot:{i}"\nmass = 1.0e-3\n'
                    f"velocity = [0.0, 0.0, {speed}]\n" for i in range(25))
    return f"""
[simulation]
duration = 0.015
integrator = "explicit"
gravity = [0.0, 0.0, 0.0]
[model]
type = "lumped"
elements_per_thread = 1
[[materials]]
name = "kevlar"
density = 1440.0
youngs_modulus = 7.0e10
diameter = 1.0e-3
viscosity = 2.0e6
[net]
nodes_per_side = 5
mesh_length = 0.1
material = "kevlar"
packing = 1.0
corner_mass = 1.0e-3
corner_thread_length = 0.1
launch_speed = {speed}
launch_angle_deg = 0.0
{knots}
[[bodies]]
name = "plate"
shape = "box"
size = [1.0, 1.0, 0.002]
position = [0.0, 0.0, 0.35]
orientation_deg = [30.0, 0.0, 0.0]
fixed = true
[contact]
stiffness = 2.0e7
damping = 30.0
friction = 0.3
points_per_segment = 4
[output]
frame_interval = 1.0e-4
vtk = false
"""


def test_net_at_50_m_s_does_not_pass_through_a_2_mm_plate() -> None:
    text = net_at_plate()
    r = run_ok(text)
    contact = prepare(scene_from_toml(text)).system.contact.bodies
    local = (centreline_points(r) - contact.position[0]) @ contact.rotation[0]      # (F, S, 21, 3)
    over_plate = (np.abs(local[..., 0]) < 0.5) & (np.abs(local[..., 1]) < 0.5)
    # the net comes from the plate's local -z side; on every frame no point over the plate may
    # be at or beyond its mid-plane
    assert (local[0, ..., 2] < -0.1).all()
    assert not (over_plate & (local[..., 2] >= 0.0)).any()
    assert smallest_distance(r, text) > 0.0
    # it did hit: every node approached at 50 cos 30 m/s and none still does; the impact lasts
    # some 30 us, shorter than a frame interval, so frames rarely show it
    approach = r.arrays["velocities"] @ contact.rotation[0][:, 2]
    np.testing.assert_allclose(approach[0], 50.0 * np.cos(np.radians(30.0)))
    assert approach[-1].max() < 0.05 * 50.0 and approach[-1].mean() < -5.0
    assert (local[-1, ..., 2] < 0.0).all()


DRAG = """
[simulation]
duration = 0.4
integrator = "{integrator}"
dt = 1.0e-3
gravity = [0.0, 0.0, -9.81]
[model]
type = "lumped"
""" + cord() + """
[[rods]]
name = "r"
material = "cord"
points = [[-0.2, 0.0, 0.50101], [0.2, 0.0, 0.50101]]
elements = 8
[[loads]]
node = "r:end"
force = [{pull}, 0.0, 0.0]
ramp = 0.01
[[bodies]]
name = "block"
shape = "box"
size = [2.0, 1.0, 1.0]
fixed = true
[contact]
stiffness = 1.0e4
damping = 1.0
friction = 0.4
slip_velocity = 1.0e-3
[output]
frame_interval = 0.01
vtk = false
"""
MU, WEIGHT = 0.4, 0.4 * 0.01 * G


def drag(integrator: str, overrides: tuple[str, ...] = ()) -> tuple[RunResult, str]:
    """A 0.4 m thread on a box pulled at its end by twice its sliding friction."""
    text = DRAG.format(integrator=integrator, pull=2.0 * MU * WEIGHT)
    return run_ok(text, overrides), text


@pytest.mark.parametrize("integrator,overrides", [
    ("explicit", ()), ("backward-euler", ()),
    # rho_inf = 0: generalized-alpha at steps far beyond the contact period of the light thread
    # nodes keeps the penalty oscillation alive at the default 0.7 (docs/contact.md); steps of at
    # most 0.5 ms: the friction work, end-of-step power times the step, is exact for backward
    # Euler (its displacement is h v_end) but first order for generalized-alpha (2.3 % high at
    # the 10 ms steps the adaptive control takes here, 0.13 % at 0.5 ms)
    ("generalized-alpha", ("simulation.rho_inf=0.0", "simulation.dt=5e-4",
                           "simulation.dt_max=5e-4"))])
def test_thread_dragged_across_a_box_feels_mu_times_the_normal_force(
        integrator: str, overrides: tuple[str, ...]) -> None:
    r, text = drag(integrator, overrides)
    v = r.arrays["velocities"][:, :, 0]
    sliding = v.min(axis=1) > 0.05
    assert sliding.sum() > 10
    force = r.arrays["body_force"][sliding, 0]
    np.testing.assert_allclose(force[:, 0] / -force[:, 2], MU, rtol=0.01)
    np.testing.assert_allclose(-force[:, 2], WEIGHT, rtol=0.01)
    # the thread accelerates at (F - mu N) / m = mu g
    t, u = r.arrays["time"][sliding], v[sliding].mean(axis=1)
    assert np.polyfit(t, u, 1)[0] == pytest.approx(MU * G, rel=0.01)
    # friction work: the integral of mu N v
    work = r.arrays["friction_work"]
    assert work[-1] == pytest.approx(MU * WEIGHT * (r.arrays["positions"][-1, :, 0].mean()
                                                    - r.arrays["positions"][0, :, 0].mean()), rel=0.02)
    assert smallest_distance(r, text) > 0.0


def test_dragged_thread_explicit_and_implicit_agree() -> None:
    # backward Euler is first order: at most the scene's 1 ms steps (the adaptive control would
    # take 10 ms, 2.6 % apart)
    (e, _), (i, _) = drag("explicit"), drag("backward-euler", ("simulation.dt_max=1e-3",))
    x_e, x_i = e.arrays["positions"][:, -1, 0], i.arrays["positions"][:, -1, 0]
    assert np.abs(x_e - x_i).max() < 0.01 * (x_e[-1] - x_e[0])


def test_explicit_step_counts_contact_springs_only_near_a_body() -> None:
    """(E5): the threads' own stable step while the box is out of reach, the step with the
    contact springs near it; a run with the box far away takes the steps of a run without it
    (but for the first step, taken at the shorter step before the first evaluation, and one
    more where the frame interval's rest is divided again), also when the far box is free and
    spins (its bounding sphere stays where it is). Before, the first frame interval was taken
    at the shorter step (a 1e-6 kg plate 100 m away: 7,246 steps instead of 10, outside check)
    and a spinning body far away forced it again and again (7,418 steps instead of 2,001)."""
    text = drop_text()
    p = prepare(scene_from_toml(text))
    safety = 0.5
    near_dt = p.system.control.near_dt
    assert p.dt == pytest.approx(safety * p.model.stable_step(), rel=1e-12)
    assert near_dt == pytest.approx(safety * p.system.contact.combined_step(p.model.stable_step()),
                                    rel=1e-12)
    assert near_dt < 0.5 * p.dt        # the 1e5 N/m penalty on a 0.1 kg mass dominates
    near = run_ok(text)
    far = run_ok(text.replace("fixed = true", "fixed = true\nposition = [0.0, 0.0, -20.0]"))
    spinning = run_ok(text.replace("fixed = true", "density = 1000.0\nposition = [0.0, 0.0, "
                                   "-20.0]\nangular_velocity_deg = [0.0, 3600.0, 0.0]"))
    alone = run_ok(text[:text.index("[[bodies]]")] + text[text.index("[output]"):])
    for other in (far, spinning):
        assert alone.summary["steps"] <= other.summary["steps"] <= alone.summary["steps"] + 2
    assert near.summary["steps"] > 1.5 * alone.summary["steps"]
    np.testing.assert_allclose(far.arrays["positions"][-1], alone.arrays["positions"][-1],
                               atol=1e-3)


FORCE_UNIT_DROP = """
[simulation]
duration = 0.13
gravity = [0.0, 0.0, -9.81]
adaptive = false
dt = 2e-4
[model]
type = "cosserat"
bending = false
torsion = false
[[materials]]
name = "kevlar"
density = {density}
youngs_modulus = {modulus}
diameter = 0.002
viscosity = {viscosity}
[[rods]]
name = "thread"
material = "kevlar"
points = [[-0.5, 0, 0.05], [0.5, 0, 0.05]]
elements = 10
[[masses]]
node = "thread:start"
mass = {mass}
[[masses]]
node = "thread:end"
mass = {mass}
[[bodies]]
name = "block"
shape = "box"
size = [2.0, 2.0, 0.2]
position = [0.0, 0.0, -0.1]
fixed = true
[contact]
stiffness = {stiffness}
damping = {damping}
friction = 0.3
[output]
frame_interval = 0.01
vtk = false
picture = false
plot = false
"""
"""A cable thread with end masses dropped 5 cm onto a box, BDF2 at fixed steps through the
landing (outside check); every mass, modulus and contact coefficient times ``unit``."""


def test_a_landing_is_solved_the_same_in_any_unit_of_force(tmp_path: Path) -> None:
    """Forces 1e5 times smaller (every mass, modulus, viscosity and contact coefficient) divide
    the discrete equations by 1e5 and change nothing else: the same steps, Newton iterations
    and motion. The line search's slope on ``|r|^2 / 2`` along a convexified correction had the
    units of force, not force squared, and this run failed at the landing ("no step along the
    Newton correction reduces the residual 1.81e-05 N") while the original converged."""
    runs = []
    for unit in (1.0, 1e-5):
        text = FORCE_UNIT_DROP.format(density=1440.0 * unit, modulus=7e10 * unit,
                                      viscosity=2e5 * unit, mass=0.1 * unit,
                                      stiffness=1e5 * unit, damping=50.0 * unit)
        runs.append(run_ok(text, directory=str(tmp_path / f"unit{unit:g}")))
    (a, b) = runs
    assert a.summary["steps"] == b.summary["steps"] == 650
    assert a.summary["newton_iterations"] == b.summary["newton_iterations"]
    assert a.arrays["positions"][:, :, 2].min() < 0.001      # landed: within a radius (1 mm)
    np.testing.assert_allclose(b.arrays["positions"], a.arrays["positions"], rtol=0.0, atol=1e-9)


THIN_THREAD_ON_A_BOX = """
[simulation]
duration = 0.0005
gravity = [0.0, 0.0, -9810.0]
[model]
type = "lumped"
[[materials]]
name = "kevlar"
density = 1440.0
youngs_modulus = 7.0e10
diameter = 2e-6
viscosity = 200.0
[[rods]]
name = "thread"
material = "kevlar"
points = [[-0.0005, 0, 5e-5], [0.0005, 0, 5e-5]]
elements = 10
[[masses]]
node = "thread:start"
mass = 1e-10
[[masses]]
node = "thread:end"
mass = 1e-10
[[bodies]]
name = "block"
shape = "box"
size = [0.002, 0.002, 0.0002]
position = [0.0, 0.0, -0.0001]
fixed = true
[contact]
stiffness = 100.0
damping = 5e-5
[output]
frame_interval = 1e-5
vtk = false
picture = false
plot = false
"""
"""A 1 mm thread of 2 um with 1e-10 kg end masses dropped 49 um onto a box (outside check: the
scene of a 1 m thread with 0.1 kg masses scaled by 1e-3, gravity by 1e3)."""


def test_a_thin_thread_rests_on_a_body_at_the_penalty_depth() -> None:
    """The end masses come to rest ``m g / k`` (9.81e-9 m) deep in the box, as the scaled-up
    twin does: the default smoothing is at most 1 % of the thread's radius. A fixed 1e-6 m (half
    the thread's diameter) held them 0.80 um above the box, the blend's force
    ``k (delta + s)^2 / (4 s)`` carrying their weight at ``delta = -0.80 um``."""
    r = run_ok(THIN_THREAD_ON_A_BOX)
    ends = [r.summary["nodes"]["thread:start"], r.summary["nodes"]["thread:end"]]
    gap = r.arrays["positions"][-1, ends, 2] - 1e-6           # surface above the box's top
    np.testing.assert_allclose(gap, -1e-10 * 9810.0 / 100.0, rtol=0.02)


def test_a_thread_sunk_into_a_body_is_reported_and_warned_of() -> None:
    """The deepest thread surface in a body, in thread radii, at every frame
    (``contact_depth``) and its largest (``max_contact_depth``); beyond one radius (the
    centreline inside the body) the run warns. With the default stiffness the thin thread's
    masses rest ``m g / k`` deep (0.0098 radii); at 0.1 N/m ``m g / k`` is 9.81 radii."""
    soft = run_ok(THIN_THREAD_ON_A_BOX.replace("stiffness = 100.0", "stiffness = 0.1")
                  .replace("damping = 5e-5", "damping = 3e-6")
                  .replace("duration = 0.0005", "duration = 0.0008"))
    depth = soft.arrays["contact_depth"]
    assert depth[-1] == pytest.approx(1e-10 * 9810.0 / 0.1 / 1e-6, rel=0.05)
    assert soft.summary["metrics"]["max_contact_depth_at_frames"] == pytest.approx(depth.max())
    assert soft.summary["metrics"]["max_contact_depth"] >= depth.max()   # over every step
    assert any("sank" in w and "contact.stiffness = 0.1" in w for w in soft.summary["warnings"])
    firm = run_ok(THIN_THREAD_ON_A_BOX)
    assert firm.summary["metrics"]["max_contact_depth_at_frames"] < 0.2   # 0.05
    # between frames the landing at 0.98 m/s goes deeper, about v sqrt(m / k) = 0.98 radii
    # undamped (m = 1e-10 kg on one point), less with the contact damping (zeta about 0.25)
    assert 0.4 < firm.summary["metrics"]["max_contact_depth"] < 1.0
    assert not any("sank" in w for w in firm.summary["warnings"])
