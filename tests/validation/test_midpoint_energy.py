"""The midpoint rule with the secant segment force (spring FORMULATION.md, S15) on lumped and
cable threads: energy-conserving through slack-taut snaps, and right for fast-turning stiff
threads, where forces taken at the midpoint configuration stretched them too far."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from rodnet.run import run
from rodnet.scene import scene_from_toml
from tests.conftest import small_net_toml


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
bending = false
torsion = false
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


def test_a_spinning_tether_pulls_what_its_rotation_needs(tmp_path: Path) -> None:
    """A 2 m tether (EA 1e5 N) with 1 kg at each end, spun at 10 rad/s and damped to a steady
    rotation: each element's tension is what the nodes outside it need to turn,
    ``sum m omega^2 r``, read from the result file. Forces at the midpoint configuration,
    whose chords are shorter than the ends', stretched it to +33 % at default steps."""
    for model in ("lumped", "cosserat"):
        r = run(scene_from_toml(SPIN.format(model=model)), tmp_path / model, progress=False)
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
            assert abs(tension[e] / needed - 1.0) < 2e-4, (model, e, tension[e], needed)
