"""Kirchhoff threads against physics: the bending frequency of a pinned-pinned beam (Euler-
Bernoulli), the cable they reduce to without bending, and the invariants of a launched net.

Expected values are analytic formulas, the lumped model, or conservation laws. Scenes go through
the public TOML path and :func:`rodnet.run.run`.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from rodnet.run import prepare, run
from rodnet.scene import scene_from_toml
from tests.conftest import small_net_toml
from tests.validation.test_dynamics import _half_period, _observed_order

BEAM = """
[simulation]
type = "dynamic"
duration = {duration}
integrator = "explicit"
explicit_safety = 0.5

[model]
type = "kirchhoff"
axial = "linear"

[[materials]]
name = "steel"
density = 7800.0
youngs_modulus = 2.0e11
diameter = 0.01

[[rods]]
name = "beam"
material = "steel"
points = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0]]
elements = {elements}
velocity = [0.0, 0.0, 1.0e-3]

[[supports]]
node = "beam:start"
fix = "pin"

[[supports]]
node = "beam:end"
fix = "pin"

[output]
frame_interval = {frame_interval}
vtk = false
picture = false
plot = false
"""


def test_pinned_beam_bending_frequency(tmp_path: Path) -> None:
    """A 1 m steel beam (d = 10 mm) on two pins, released straight with a uniform 1 mm/s
    transverse velocity. Its first-mode coordinate (the deflection projected on sin(pi x / L),
    which the sampled sines make exact for equal nodal masses) crosses zero every half period
    of omega_1 = (pi / L)^2 sqrt(EI / rho A) (Euler-Bernoulli). The amplitude, 8 um, is far
    below the radius, so the pins' stretching is negligible. The error falls at second order in
    the hinge spacing; the discrete chain's own value is -(pi h / L)^2 / 12 to leading order
    (-0.82 %, -0.21 %, -0.051 % for 10, 20, 40 elements)."""
    EI, rhoA = 2.0e11 * np.pi * 0.01**4 / 64, 7800.0 * np.pi * 0.01**2 / 4
    omega = np.pi**2 * np.sqrt(EI / rhoA)
    period = 2.0 * np.pi / omega
    errors = []
    for n in (10, 20, 40):
        result = run(scene_from_toml(BEAM.format(duration=2.2 * period, elements=n,
                                                 frame_interval=period / 400)),
                     tmp_path / str(n), progress=False)
        assert result.status == "ok", result.message
        positions = result.arrays["positions"]
        mode = np.sin(np.pi * positions[0, :, 0])
        q1 = positions[:, :, 2] @ mode
        measured = np.pi / _half_period(result.arrays["time"][1:], q1[1:])
        errors.append(measured / omega - 1.0)
    order = _observed_order([1 / 10, 1 / 20, 1 / 40], np.abs(errors))
    print(f"\npinned beam, first frequency error at 10, 20, 40 elements: "
          f"{[f'{e:+.3%}' for e in errors]}, observed order {order:.2f}")
    assert abs(errors[-1]) < 1e-3
    assert 1.8 < order < 2.2


def _net(overrides: list[str], duration: float = 0.3, n: int = 2):
    return scene_from_toml(small_net_toml(duration=duration, n=n), overrides)


def test_kirchhoff_threads_without_bending_are_the_cable(tmp_path: Path) -> None:
    """With bending off there is no hinge: the run is the lumped (cable) run, bit for bit."""
    a = run(_net(["model.type=kirchhoff", "model.knots=pinned", "model.bending=false"]),
            tmp_path / "k", progress=False)
    b = run(_net(["model.type=lumped"]), tmp_path / "l", progress=False)
    assert a.status == b.status == "ok"
    assert np.array_equal(a.arrays["positions"], b.arrays["positions"])


def test_kirchhoff_net_invariants(tmp_path: Path) -> None:
    """A 5 x 5 net of Kirchhoff threads (two elements per thread, solid Kevlar EI) launched in
    free space for 0.3 s, explicit: the centre of mass moves uniformly (1e-8 of the net size),
    the bending acts (the run differs from the cable run by 0.074 m), and the energy never rises
    between frames by more than 1e-6 of its start value (measured: it never rose), while the
    viscosity removes some of it (40.06 -> 38.16 J)."""
    scene = _net(["model.type=kirchhoff", "model.knots=pinned"])
    mass = prepare(scene).mass
    result = run(scene, tmp_path / "k", progress=False)
    cable = run(_net(["model.type=lumped"]), tmp_path / "l", progress=False)
    assert result.status == cable.status == "ok", result.message
    a = result.arrays
    com = np.einsum("fnk,n->fk", a["positions"], mass) / mass.sum()
    slope, offset = np.polyfit(a["time"], com, 1)
    drift = np.abs(com - np.outer(a["time"], slope) - offset).max()
    size = np.ptp(a["positions"][-1], axis=0).max()
    energy = a["kinetic_energy"] + a["elastic_energy"]
    bending = np.abs(a["positions"] - cable.arrays["positions"]).max()
    print(f"\nKirchhoff net: centre-of-mass deviation {drift:.2e} m, largest energy rise "
          f"{np.diff(energy).max() / energy[0]:.2e} E0, energy {energy[0]:.4f} -> "
          f"{energy[-1]:.4f} J, largest distance to the cable run {bending:.2e} m")
    assert drift <= 1e-8 * size
    assert np.diff(energy).max() <= 1e-6 * energy[0]
    assert energy[-1] < energy[0]
    assert bending > 1e-6 * size


@pytest.mark.parametrize("model", ["kirchhoff", "lumped"])
def test_a_moment_is_refused_naming_the_model(model: str) -> None:
    from rodnet.errors import SceneError
    scene = BEAM.format(duration=0.01, elements=4, frame_interval=0.01).replace(
        'type = "kirchhoff"', f'type = "{model}"') + \
        '[[loads]]\nnode = "beam:2"\nmoment = [0.0, 1.0, 0.0]\n'
    with pytest.raises(SceneError) as refused:
        prepare(scene_from_toml(scene))
    label = "Kirchhoff threads" if model == "kirchhoff" else "the lumped model"
    assert "loads[0].moment" in str(refused.value) and label in str(refused.value)
    assert "model.type = 'cosserat'" in str(refused.value)
