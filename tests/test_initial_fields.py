"""Initial fields: a rod given a rigid angular velocity about a point starts in rigid rotation
(sections turning with it, no strain rate) and keeps its angular momentum in free flight; a
per-node velocity table replaces the velocities of the nodes it names."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from rodnet.errors import SceneError
from rodnet.run import prepare, run
from rodnet.scene import scene_from_toml

OMEGA = (0.0, 0.3, 4.0)      # rad/s
CENTER = (0.1, -0.2, 0.05)   # m

ROD = """
[simulation]
duration = {duration}
gravity = [0.0, 0.0, 0.0]
integrator = "{integrator}"
[model]
type = "{model}"
[[materials]]
name = "kevlar"
density = 1440.0
youngs_modulus = 7.0e10
poisson_ratio = 0.36
diameter = 1.0e-3
viscosity = 2.0e6
[[rods]]
name = "thread"
material = "kevlar"
points = [[0.0, 0.0, 0.0], [0.4, 0.3, 0.0], [0.8, 0.3, 0.2]]
elements = 8
velocity = [1.0, 0.0, 0.5]
angular_velocity = [0.0, 0.3, 4.0]
rotation_center = [0.1, -0.2, 0.05]
[[masses]]
node = "thread:end"
mass = 0.01
{extra}
[output]
vtk = false
frame_interval = 0.05
"""


def _scene(model: str = "cosserat", integrator: str = "bdf2", duration: float = 0.2,
           extra: str = ""):  # type: ignore[no-untyped-def]
    return scene_from_toml(ROD.format(model=model, integrator=integrator, duration=duration,
                                      extra=extra))


def test_rigid_rotation_starts_without_strain_rate() -> None:
    p = prepare(_scene())
    x, v = p.state.q.x, p.state.v
    n = len(x)
    expected = np.array([1.0, 0.0, 0.5]) + np.cross(OMEGA, x - np.array(CENTER))
    np.testing.assert_allclose(v[:3 * n].reshape(-1, 3), expected, rtol=1e-14, atol=1e-14)
    _, rates = p.system.strains(p.state.q, v)
    # a rigid motion changes no strain: shear, stretch, bending and twist rates all vanish
    assert np.abs(rates).max() < 1e-12 * np.linalg.norm(OMEGA)


def test_a_spun_rod_keeps_its_angular_momentum_in_free_flight(tmp_path: Path) -> None:
    """Lumped model, explicit (symplectic) stepping: central forces conserve the node masses'
    momentum and angular momentum exactly. A straight rod spun about its centre of mass,
    normal to it, turns rigidly at the angular velocity it was given."""
    text = ROD.format(model="lumped", integrator="explicit", duration=0.5, extra="")
    text = text.replace("[[0.0, 0.0, 0.0], [0.4, 0.3, 0.0], [0.8, 0.3, 0.2]]",
                        "[[-0.3, 0.0, 0.0], [0.5, 0.0, 0.0]]")
    text = text.replace("angular_velocity = [0.0, 0.3, 4.0]", "angular_velocity = [0.0, 1.5, 4.0]")
    text = text.replace("rotation_center = [0.1, -0.2, 0.05]\n", "")
    text = text.split("[[masses]]")[0] + "[output]" + text.split("[output]")[1]
    scene = scene_from_toml(text)
    p = prepare(scene)
    r = run(scene, tmp_path, progress=False)
    assert r.status == "ok", r.message
    m, x, v = p.mass, r.arrays["positions"], r.arrays["velocities"]
    P = np.einsum("n,fni->fi", m, v)
    L = np.einsum("n,fni->fi", m, np.cross(x, v))
    assert np.abs(P - P[0]).max() < 1e-12 * np.abs(P[0]).max()
    assert np.abs(L - L[0]).max() < 1e-12 * np.abs(L[0]).max()
    omega = np.array([0.0, 1.5, 4.0])
    chord0, chord1 = x[0, -1] - x[0, 0], x[-1, -1] - x[-1, 0]
    axis, angle = omega / np.linalg.norm(omega), np.linalg.norm(omega) * r.arrays["time"][-1]
    K = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    rotated = (np.eye(3) + np.sin(angle) * K + (1 - np.cos(angle)) * K @ K) @ chord0
    assert np.linalg.norm(chord1 - rotated) < 1e-6 * np.linalg.norm(chord0)


def test_a_velocity_table_sets_the_named_nodes() -> None:
    extra = '[initial]\nvelocities = [["thread:3", 0.5, -2.0, 7.0], ["thread:start", 0.0, 0.0, 1.0]]'
    p = prepare(_scene(extra=extra))
    v = p.state.v[:3 * len(p.state.q.x)].reshape(-1, 3)
    nodes = p.structure.selectors
    np.testing.assert_array_equal(v[nodes["thread:3"]], [0.5, -2.0, 7.0])
    np.testing.assert_array_equal(v[nodes["thread:start"]], [0.0, 0.0, 1.0])


@pytest.mark.parametrize("extra, key", [
    ('[initial]\nvelocities = [["thread:99", 0.0, 0.0, 1.0]]', "initial.velocities[0]"),
    ('[initial]\nvelocities = [["thread:1", 0.0, 1.0]]', "initial.velocities[0]"),
    ('[initial]\nvelocities = [["thread:1", 0.0, "a", 1.0]]', "initial.velocities[0]"),
])
def test_bad_initial_velocities_are_refused_by_key(extra: str, key: str) -> None:
    with pytest.raises(SceneError) as err:
        prepare(_scene(extra=extra))
    assert key in str(err.value)
