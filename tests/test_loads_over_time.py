"""Loads over time: a pulse between ``start`` and ``stop`` gives the impulse ``F (stop -
start)``, a table of factors the integral of its factor, with every integrator (the steppers
land on the times where a load switches); bad settings are refused by key."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from rodnet.errors import SceneError
from rodnet.kernels.schedule import factors, load_schedule
from rodnet.run import prepare, run
from rodnet.scene import scene_from_toml

FORCE = (3.0, -1.0, 2.0)

SCENE = """
[simulation]
duration = 0.4
gravity = [0.0, 0.0, 0.0]
integrator = "{integrator}"
dt = 1.0e-3
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
points = [[0.0, 0.0, 0.0], [0.5, 0.0, 0.0]]
elements = 4
[[masses]]
node = "thread:end"
mass = 0.2
[[loads]]
node = "thread:end"
force = [3.0, -1.0, 2.0]
{timing}
[output]
vtk = false
frame_interval = 0.05
"""


def _momentum_change(tmp_path: Path, integrator: str, model: str, timing: str) -> np.ndarray:
    scene = scene_from_toml(SCENE.format(integrator=integrator, model=model, timing=timing))
    r = run(scene, tmp_path, progress=False)
    assert r.status == "ok", r.message
    a = r.arrays
    p = np.einsum("n,fni->fi", prepare(scene).mass, a["velocities"])
    assert np.allclose(a["time"], np.linspace(0.0, 0.4, 9))   # only the frames are saved
    return p[-1] - p[0]


@pytest.mark.parametrize("integrator, model", [("explicit", "lumped"), ("bdf2", "cosserat"),
                                               ("backward-euler", "cosserat"),
                                               ("generalized-alpha", "cosserat"),
                                               ("explicit", "cosserat"), ("rk45", "lumped")])
def test_a_pulse_gives_the_impulse_force_times_duration(tmp_path: Path, integrator: str,
                                                        model: str) -> None:
    # start and stop fall between frames and off the steps of dt
    change = _momentum_change(tmp_path, integrator, model, "start = 0.0713\nstop = 0.2291")
    expected = np.array(FORCE) * (0.2291 - 0.0713)
    np.testing.assert_allclose(change, expected, rtol=1e-9, atol=1e-12)


@pytest.mark.parametrize("integrator, model", [("bdf2", "cosserat"), ("rk45", "lumped")])
def test_a_table_of_jumps_gives_the_integral_of_its_factor(tmp_path: Path, integrator: str,
                                                           model: str) -> None:
    table = "table = [[0.0, 1.0], [0.1, 1.0], [0.1, -0.5], [0.25, -0.5], [0.25, 0.0]]"
    change = _momentum_change(tmp_path, integrator, model, table)
    np.testing.assert_allclose(change, np.array(FORCE) * (0.1 - 0.5 * 0.15), rtol=1e-9,
                               atol=1e-12)


def test_factor_of_ramp_table_and_window() -> None:
    s = load_schedule([0.2, 0.0, 0.0], [None, [(0.0, 0.0), (0.1, 2.0), (0.1, 1.0)], None],
                      [0.0, 0.0, 0.05], [None, None, 0.15])
    at = {t: factors(s, t) for t in (0.0, 0.05, 0.1, 0.15, 0.3)}
    np.testing.assert_allclose([at[t][0] for t in at], [0.0, 0.25, 0.5, 0.75, 1.0])   # ramp
    np.testing.assert_allclose([at[t][1] for t in at], [0.0, 1.0, 1.0, 1.0, 1.0])     # jump
    assert factors(s, 0.0999)[1] == pytest.approx(1.998)
    np.testing.assert_allclose([at[t][2] for t in at], [0.0, 1.0, 1.0, 0.0, 0.0])     # window


@pytest.mark.parametrize("timing, key", [("start = 0.3\nstop = 0.2", "loads[0].stop"),
                                         ("start = -1.0", "loads[0].start"),
                                         ("ramp = 0.1\ntable = [[0.0, 1.0]]", "loads[0].ramp"),
                                         ("table = [[0.2, 1.0], [0.1, 0.0]]", "loads[0].table"),
                                         ("table = [[0.2, 1.0, 3.0]]", "loads[0].table"),
                                         ("table = []", "loads[0].table")])
def test_bad_timing_is_refused_by_key(timing: str, key: str) -> None:
    with pytest.raises(SceneError) as err:
        scene_from_toml(SCENE.format(integrator="bdf2", model="cosserat", timing=timing))
    assert key in str(err.value)


@pytest.mark.parametrize("timing, key", [("stop = 0.2", "loads[0].stop"),
                                         ("ramp = 2.0", "loads[0].ramp")])
def test_a_static_run_refuses_times(timing: str, key: str) -> None:
    # a ramp was silently ignored by static runs (load_steps raise the loads)
    text = SCENE.format(integrator="bdf2", model="cosserat", timing=timing)
    text = text.replace('integrator = "bdf2"', 'type = "static"')
    with pytest.raises(SceneError) as err:
        scene_from_toml(text)
    assert key in str(err.value) and "static" in str(err.value)


FALL = SCENE.replace('gravity = [0.0, 0.0, 0.0]', 'gravity = [0.0, -3.0, -9.81]\n{gravity}') \
    .replace("[[loads]]\nnode = \"thread:end\"\nforce = [3.0, -1.0, 2.0]\n{timing}\n", "")


@pytest.mark.parametrize("gravity, integral, integrator, rtol", [
    ("gravity_table = [[0.0, 0.0], [0.1, 0.0], [0.1, 1.0], [0.3, 1.0], [0.3, 0.5]]",
     0.2 + 0.5 * 0.1, "bdf2", 1e-9),
    ("gravity_table = [[0.0, 0.0], [0.1, 0.0], [0.1, 1.0], [0.3, 1.0], [0.3, 0.5]]",
     0.2 + 0.5 * 0.1, "explicit", 1e-9),
    ("gravity_ramp = 0.2", 0.4 - 0.1, "explicit", 1e-3),
])
def test_gravity_with_a_time_factor_gives_the_fall_of_its_integral(
        tmp_path: Path, gravity: str, integral: float, integrator: str, rtol: float) -> None:
    scene = scene_from_toml(FALL.format(integrator=integrator, model="cosserat",
                                        gravity=gravity))
    r = run(scene, tmp_path, progress=False)
    assert r.status == "ok", r.message
    m = prepare(scene).mass
    p = np.einsum("n,fni->fi", m, r.arrays["velocities"])
    np.testing.assert_allclose(p[-1] - p[0], m.sum() * np.array([0.0, -3.0, -9.81]) * integral,
                               rtol=rtol, atol=1e-12)


@pytest.mark.parametrize("change, key", [
    ('integrator = "bdf2"', "simulation.gravity_ramp"),     # static
    ("", "simulation.gravity_ramp"),                           # a body
    ('integrator = "bdf2"\ngravity_table = [[0.0, 1.0]]', "simulation.gravity_ramp"),
])
def test_bad_gravity_timing_is_refused_by_key(change: str, key: str) -> None:
    text = FALL.format(integrator="bdf2", model="cosserat", gravity="gravity_ramp = 0.1")
    if change.startswith('integrator = "bdf2"\ngravity_table'):
        text = text.replace('integrator = "bdf2"', change)
    elif change:
        text = text.replace('integrator = "bdf2"', 'type = "static"')
    else:
        text = text.replace("[output]", '[[bodies]]\nname = "box"\nshape = "box"\n'
                            'size = [1.0, 1.0, 1.0]\nmass = 10.0\nposition = [0.0, 0.0, -5.0]\n'
                            "[output]")
    with pytest.raises(SceneError) as err:
        scene_from_toml(text)
    assert key in str(err.value)
