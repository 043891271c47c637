"""The midpoint rule with the secant segment force (spring FORMULATION.md, S15) on lumped and
cable threads: energy-conserving through slack-taut snaps, and right for fast-turning stiff
threads, where forces taken at the midpoint configuration stretched them too far."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from rodnet.run import run
from rodnet.scene import scene_from_toml
from tests.conftest import small_net_toml
from tests.test_run import PENDULUM


def _net(tmp_path: Path, name: str, integrator: str, extra: str = "") -> dict:
    toml = small_net_toml(duration=0.3, integrator=integrator, viscosity=0.0)
    toml = toml.replace("[simulation]\n", "[simulation]\n" + extra, 1)
    r = run(scene_from_toml(toml), tmp_path / name, progress=False)
    assert r.status == "ok", r.message
    return r.arrays


def test_an_undamped_net_keeps_its_energy_through_its_snaps(tmp_path: Path) -> None:
    """A 5 x 5 lumped net thrown open, no damping: its threads go slack and snap taut. With
    forces at the midpoint configuration the energy rose 5-fold by 0.09 s at default steps (the
    guard stopped the run); with the secant force it holds to the Newton tolerance, and the
    largest mouth area agrees with an explicit run at a tenth of its default step."""
    mid = _net(tmp_path, "midpoint", "midpoint")
    energy = mid["kinetic_energy"] + mid["elastic_energy"]
    assert np.abs(energy - energy[0]).max() < 1e-7 * energy[0]
    assert mid["tension"].max() > 50.0             # it did snap taut
    reference = _net(tmp_path, "explicit", "explicit", "explicit_safety = 0.05\n")
    area, expected = mid["mouth_area"].max(), reference["mouth_area"].max()
    assert abs(area / expected - 1.0) < 1e-3, (area, expected)


SPIN = """
[simulation]
duration = 2.0
gravity = [0.0, 0.0, 0.0]
integrator = "midpoint"
[model]
type = "{model}"
bending = {rod}
torsion = {rod}
[[materials]]
name = "tether"
density = 1000.0
youngs_modulus = 1.0e11
diameter = 1.0e-3
axial_stiffness = 1.0e5
mass_per_length = 0.1
viscosity = 3.0e7
[[rods]]
name = "t"
material = "tether"
points = [[-1.0, 0.0, 0.0], [1.0, 0.0, 0.0]]
elements = 10
angular_velocity = [0.0, 0.0, 10.0]
[[masses]]
node = "t:start"
mass = 1.0
[[masses]]
node = "t:end"
mass = 1.0
[output]
frame_interval = 0.01
vtk = false
"""


@pytest.mark.parametrize("model, rod", [("lumped", "false"), ("cosserat", "false"),
                                        ("cosserat", "true")])
def test_a_spinning_tether_pulls_what_its_rotation_needs(tmp_path: Path, model: str,
                                                        rod: str) -> None:
    """A 2 m tether (EA 1e5 N) with 1 kg at each end, spun at 10 rad/s and damped to a steady
    rotation: each element's tension is what the nodes outside it need to turn,
    ``sum m omega^2 r``, read from the result file; for cable threads and for Cosserat rods
    with bending and torsion. Forces at the midpoint configuration, whose chords are shorter
    than the ends', stretched cable threads to +33 % at default steps, and the rods to +7.5 %
    (their damping reading the shortening as a strain rate: C56). The rods' default steps are
    longer (up to 5.7 ms): there the midpoint rule's own error of a circular motion,
    ``(omega h)^2 / 8`` = 4e-4 of the force, shows (2.4e-5 at a fixed 0.25 ms, as BDF2's)."""
    tolerance = 6e-4 if rod == "true" else 2e-4
    r = run(scene_from_toml(SPIN.format(model=model, rod=rod)), tmp_path, progress=False)
    assert r.status == "ok", r.message
    a = r.arrays
    x, v, m = a["positions"][-1], a["velocities"][-1], a["node_mass"]
    radius = np.linalg.norm(x[:, :2], axis=1)
    omega = np.linalg.norm(np.cross(x, v), axis=1)[radius > 0.1] / radius[radius > 0.1] ** 2
    assert np.ptp(omega) < 1e-3 * omega.mean()      # a steady, rigid rotation
    segments, tension = a["segments"], a["tension"][-1]
    side = np.sign(x[:, 0])
    for e, (i, j) in enumerate(segments):
        outer = i if radius[i] > radius[j] else j
        beyond = (side == side[outer]) & (radius >= radius[outer] - 1e-12)
        needed = float(np.sum(m[beyond] * omega.mean() ** 2 * radius[beyond]))
        assert abs(tension[e] / needed - 1.0) < tolerance, (model, e, tension[e], needed)



def test_a_stiff_rod_pendulum_keeps_its_energy_at_steps_that_skip_its_axial_modes(
        tmp_path: Path) -> None:
    """A steel rod of 0.2 m x 20 mm on a pin (4 Cosserat elements), released horizontal: at a
    fixed 4 ms no axial or shear mode is resolved (the axial period is about 0.1 ms). With the
    stresses of the step's mean strains (C56) the energy, gravity's potential included, stays
    within 1e-6 of the largest kinetic energy and the axial force near what the swing needs
    (about 1.5 m g at the bottom); with those of the midpoint configuration the energy grew
    without bound (axial force 1e6 N) until the energy guard stopped the run at 0.056 s."""
    r = run(scene_from_toml(PENDULUM.format(dt=0.004, integrator="midpoint")), tmp_path,
            progress=False)
    assert r.status == "ok", r.message
    a = r.arrays
    energy = a["kinetic_energy"] + a["elastic_energy"] + a["potential_energy"]
    assert np.abs(energy - energy[0]).max() < 1e-6 * a["kinetic_energy"].max()
    weight = 7800.0 * np.pi * 0.01**2 * 0.2 * 9.81
    assert a["positions"][:, -1, 2].min() < -0.19                # it swings through the bottom
    assert a["tension"].max() < 3.0 * weight
