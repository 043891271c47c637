"""Line loads: a force per length on a rod or on every net thread is the consistent nodal load
of the elements, and a cantilever under it deflects as beam theory says."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from rodnet.errors import SceneError
from rodnet.run import run
from rodnet.scene import scene_from_toml

Q = -1.0e-4     # N/m: a tip deflection of 3.6 mm, the linear range of the beam
LENGTH, ELEMENTS, DIAMETER, E = 1.0, 20, 1.0e-3, 7.0e10

BEAM = f"""
[simulation]
type = "static"
gravity = [0.0, 0.0, 0.0]
load_steps = 2
[model]
type = "cosserat"
axial = "linear"
[[materials]]
name = "kevlar"
density = 1440.0
youngs_modulus = {E}
poisson_ratio = 0.36
diameter = {DIAMETER}
[[rods]]
name = "beam"
material = "kevlar"
points = [[0.0, 0.0, 0.0], [{LENGTH}, 0.0, 0.0]]
elements = {ELEMENTS}
[[supports]]
node = "beam:start"
fix = "clamp"
{{loads}}
[output]
vtk = false
"""


def _tip(tmp_path: Path, loads: str, name: str) -> np.ndarray:
    r = run(scene_from_toml(BEAM.format(loads=loads)), tmp_path / name, progress=False)
    assert r.status == "ok", r.message
    return r.arrays["positions"][-1]


def test_a_line_load_is_the_nodal_loads_of_its_elements_and_bends_as_beam_theory(
        tmp_path: Path) -> None:
    line = _tip(tmp_path, f'[[line_loads]]\non = "beam"\nforce_per_length = [0.0, 0.0, {Q}]',
                "line")
    share = Q * LENGTH / ELEMENTS
    nodal = "\n".join(f'[[loads]]\nnode = "beam:{k}"\nforce = [0.0, 0.0, '
                      f'{share / 2 if k == ELEMENTS else share}]' for k in range(1, ELEMENTS + 1))
    by_hand = _tip(tmp_path, nodal, "nodal")
    np.testing.assert_allclose(line, by_hand, rtol=0, atol=1e-12 * LENGTH)
    EI = E * np.pi * DIAMETER**4 / 64.0
    expected = Q * LENGTH**4 / (8.0 * EI)          # Euler-Bernoulli cantilever, uniform load
    assert abs(line[-1, 2] - expected) < 0.01 * abs(expected), (line[-1, 2], expected)


def test_a_line_load_on_the_net_adds_up_to_its_threads_length(tmp_path: Path) -> None:
    from rodnet.models.loads import dead_loads
    from rodnet.topology import build_structure
    from tests.conftest import small_net_toml

    text = small_net_toml().replace("[output]", '[[line_loads]]\non = "net"\n'
                                    'force_per_length = [0.0, 1.5, -3.0]\n[output]')
    scene = scene_from_toml(text)
    structure = build_structure(scene)
    loads = dead_loads(scene, structure, np.zeros(structure.n_nodes))
    total = structure.rest_length.sum()
    np.testing.assert_allclose(loads.force.sum(axis=0), np.array([0.0, 1.5, -3.0]) * total,
                               rtol=1e-12)


@pytest.mark.parametrize("body, key", [
    ('on = "nothing"\nforce_per_length = [0.0, 0.0, 1.0]', "line_loads[0].on"),
    ('on = "beam"\nforce_per_length = [0.0, 0.0]', "line_loads[0].force_per_length"),
    ('on = "beam"\nforce_per_length = [0.0, 0.0, 1.0]\nstop = 1.0', "line_loads[0].stop"),
])
def test_bad_line_loads_are_refused_by_key(body: str, key: str) -> None:
    with pytest.raises(SceneError) as err:
        scene_from_toml(BEAM.format(loads="[[line_loads]]\n" + body))
    assert key in str(err.value)


def test_a_line_load_on_a_rod_in_a_net_only_scene_says_what_it_may_name() -> None:
    """A net-only scene has no rod to name: the message says "net", not "a rod []" (outside
    check)."""
    from tests.conftest import small_net_toml

    text = small_net_toml().replace("[output]", '[[line_loads]]\non = "beam"\n'
                                    'force_per_length = [0.0, 0.0, 1.0]\n[output]')
    with pytest.raises(SceneError) as err:
        scene_from_toml(text)
    message = str(err.value)
    assert "line_loads[0].on" in message and "'beam'" in message
    assert 'must be "net"' in message and "[]" not in message
