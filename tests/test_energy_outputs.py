"""The energy series of result.npz: ``potential_energy`` (gravity and dead forces) closes the
energy balance with ``kinetic_energy`` and ``elastic_energy``, checked against quantities the
result file gives independently (positions, the rod's mass) and against Clapeyron's theorem."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from rodnet.run import run
from rodnet.scene import scene_from_toml

LENGTH, ELEMENTS, DIAMETER, DENSITY, E = 0.5, 10, 2.0e-3, 1440.0, 7.0e10
G = 9.81

ROD = f"""
[simulation]
type = "{{kind}}"
{{simulation}}
[model]
type = "{{model}}"
axial = "linear"
[[materials]]
name = "kevlar"
density = {DENSITY}
youngs_modulus = {E}
poisson_ratio = 0.36
diameter = {DIAMETER}
[[rods]]
name = "rod"
material = "kevlar"
points = [[0.0, 0.0, 0.0], [{LENGTH}, 0.0, 0.0]]
elements = {ELEMENTS}
[[supports]]
node = "rod:start"
fix = "{{fix}}"
{{loads}}
[output]
frame_interval = 0.01
vtk = false
"""


def _run(tmp_path: Path, name: str, **keys: str):  # type: ignore[no-untyped-def]
    r = run(scene_from_toml(ROD.format(**keys)), tmp_path / name, progress=False)
    assert r.status == "ok", r.message
    return r.arrays


@pytest.mark.parametrize("model", ["cosserat", "lumped"])
def test_a_pendulum_keeps_kinetic_elastic_and_gravity_energy(tmp_path: Path, model: str) -> None:
    """A stiff rod pinned at one end falls from horizontal under gravity: its gravity energy
    is -M g z of its centroid (uniform elements lump half their mass on each end), and the
    midpoint rule at short steps keeps the sum of the three series while 0.06 J turns into
    motion."""
    a = _run(tmp_path, model, kind="dynamic", model=model, fix="pin", loads="",
             simulation=f"duration = 0.2\ngravity = [0.0, 0.0, {-G}]\nintegrator = \"midpoint\"\n"
                        "adaptive = false\ndt = 2.0e-4\nrtol = 1.0e-10")
    mass = DENSITY * np.pi * DIAMETER**2 / 4.0 * LENGTH
    x = a["positions"][:, :ELEMENTS + 1]         # the rod's position nodes
    centroid_z = 0.5 * (x[:, 1:, 2] + x[:, :-1, 2]).mean(axis=1)
    np.testing.assert_allclose(a["potential_energy"], mass * G * centroid_z,
                               rtol=1e-12, atol=1e-15)
    total = a["kinetic_energy"] + a["elastic_energy"] + a["potential_energy"]
    converted = a["kinetic_energy"].max()
    assert converted > 0.5 * mass * G * LENGTH / 2.0      # it has fallen most of the way
    assert np.abs(total - total[0]).max() < 1e-5 * converted, np.abs(total - total[0]).max()


@pytest.mark.parametrize("model", ["cosserat", "lumped"])
def test_a_static_tip_load_stores_half_the_work_it_loses(tmp_path: Path, model: str) -> None:
    """Clapeyron: in linear elasticity the strain energy is half the load's work, so the
    potential of a tip force, -P . x, less its value at rest, is -2 times the elastic energy at
    every load factor (a stretched bar, inside the linear range)."""
    force = 50.0
    a = _run(tmp_path, model, kind="static", model=model, fix="clamp",
             simulation="load_steps = 4",
             loads=f'[[loads]]\nnode = "rod:end"\nforce = [{force}, 0.0, 0.0]')
    load_factor = np.arange(1, 5) / 4.0
    elastic, potential = a["elastic_energy"], a["potential_energy"]   # one frame per load step
    stretch = a["positions"][:, ELEMENTS, 0] - LENGTH
    np.testing.assert_allclose(potential, -load_factor * force * (LENGTH + stretch), rtol=1e-12)
    np.testing.assert_allclose(potential + load_factor * force * LENGTH, -2.0 * elastic,
                               rtol=1e-6)
    EA = E * np.pi * DIAMETER**2 / 4.0
    np.testing.assert_allclose(elastic, (load_factor * force) ** 2 * LENGTH / (2.0 * EA),
                               rtol=1e-3)


def test_a_dead_moment_has_no_potential(tmp_path: Path) -> None:
    a = _run(tmp_path, "moment", kind="static", model="cosserat", fix="clamp",
             simulation="load_steps = 1",
             loads='[[loads]]\nnode = "rod:end"\nmoment = [0.0, 0.0, 1.0e-4]')
    assert np.isnan(a["potential_energy"]).all()
    assert np.isfinite(a["elastic_energy"]).all()


def test_the_penalty_springs_energy_closes_the_balance_of_a_bounce(tmp_path: Path) -> None:
    """A thread dropped flat onto a fixed box without contact damping or friction bounces: the
    energy in the penalty springs is what the other three series miss while it touches."""
    box = ('[[bodies]]\nname = "table"\nshape = "box"\nsize = [2.0, 2.0, 0.2]\n'
           'position = [0.25, 0.0, -0.2]\nfixed = true\n'
           '[contact]\nstiffness = 0.5\ndamping = 0.0\nfriction = 0.0')
    scene = ROD.format(kind="dynamic", model="lumped", fix="pin", loads=box,
                       simulation=f"duration = 0.3\ngravity = [0.0, 0.0, {-G}]\n"
                                  "integrator = \"midpoint\"\nadaptive = false\ndt = 1.0e-4\n"
                                  "rtol = 1.0e-10")
    scene = scene.replace('[[supports]]\nnode = "rod:start"\nfix = "pin"\n', "")
    r = run(scene_from_toml(scene), tmp_path / "bounce", progress=False)
    assert r.status == "ok", r.message
    a = r.arrays
    touching = a["contact_energy"] > 0.0
    assert touching.sum() >= 3 and not touching[0]
    total = a["kinetic_energy"] + a["elastic_energy"] + a["potential_energy"]
    moving = a["kinetic_energy"].max()
    assert np.abs(total + a["contact_energy"] - total[0]).max() < 1e-3 * moving
    assert np.abs(total - total[0]).max() > 0.1 * moving   # the springs hold a real part


@pytest.mark.parametrize("knots", ["rigid", "pinned"])
def test_element_rotation_nodes_map_the_rotation_node_arrays(tmp_path: Path, knots: str) -> None:
    """``element_rotation_nodes`` (E, 2) says which rows of ``rotation_node_quaternions`` an
    element's ends take: with rigid knots, one rotation node per node, those rows are the
    ``rotations`` of the element's end nodes (``segments``); with pinned knots every thread end
    at a knot has its own. (Without the map an outside check's curvatures recomputed from the
    rotation-node rows were off by 3.3 1/m: their order is not the nodes'.)"""
    from tests.conftest import small_net_toml

    text = small_net_toml(duration=0.02, integrator="bdf2", n=2)
    r = run(scene_from_toml(text, ["model.type=cosserat", f"model.knots={knots}"]), tmp_path,
            progress=False)
    assert r.status == "ok", r.message
    a = r.arrays
    ends, quats = a["element_rotation_nodes"], a["rotation_node_quaternions"]
    assert ends.shape == a["segments"].shape and ends.max() == quats.shape[1] - 1
    assert len(np.unique(ends)) == quats.shape[1]          # every rotation node is some end
    if knots == "rigid":
        assert np.abs(quats[:, ends] - a["rotations"][:, a["segments"]]).max() == 0.0
    else:   # a pinned knot's thread ends turn on their own: more rotation nodes than nodes
        assert quats.shape[1] > a["positions"].shape[1]
