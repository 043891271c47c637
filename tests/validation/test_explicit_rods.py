"""Explicit Cosserat rods (FORMULATION.md §9b): stability bound, physics against independent
references (Euler-Bernoulli frequencies, the implicit integrators, the lumped net), invariants,
and the scaled rotary inertia's convergence."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from rodnet.errors import SceneError
from rodnet.integrate.explicit import integrate_explicit
from rodnet.models.system import ThreadSystem
from rodnet.kernels.tension import REVERSED_STIFFNESS
from rodnet.run import prepare, run
from rodnet.scene import scene_from_toml
from tests.conftest import small_net_toml
from tests.contact.scenes import cord

CANTILEVER = """
[simulation]
duration = {duration}
integrator = "{integrator}"
adaptive = {adaptive}
dt = {dt}
explicit_safety = {safety}
gravity = {gravity}
[model]
type = "cosserat"
axial = "linear"
[[materials]]
name = "steel"
density = 7800.0
youngs_modulus = 2.0e11
poisson_ratio = 0.3
diameter = 0.01
viscosity = {viscosity}
[[rods]]
name = "beam"
material = "steel"
points = [[0, 0, 0], [1, 0, 0]]
elements = {elements}
[[supports]]
node = "beam:start"
fix = "clamp"
{loads}
[output]
frame_interval = {frame}
vtk = false
picture = false
plot = false
"""


def cantilever(duration: float = 0.3, integrator: str = "explicit", adaptive: str = "true",
               dt: float = 1e-3, safety: float = 0.5, gravity: str = "[0.0, 0.0, 0.0]",
               viscosity: float = 0.0, elements: int = 10, loads: str = "",
               frame: float = 5e-4, overrides: tuple[str, ...] = ()) -> object:
    return scene_from_toml(CANTILEVER.format(
        duration=duration, integrator=integrator, adaptive=adaptive, dt=dt, safety=safety,
        gravity=gravity, viscosity=viscosity, elements=elements, loads=loads, frame=frame),
        overrides)


def net(n: int = 2, knots: str = "pinned", duration: float = 0.3, packing: float | None = None,
        integrator: str = "explicit", extra: tuple[str, ...] = ()) -> object:
    overrides = ["model.type=cosserat", f"model.knots={knots}", f"simulation.integrator={integrator}",
                 *extra]
    if packing is not None:
        overrides.append(f"net.packing={packing}")
    return scene_from_toml(small_net_toml(duration=duration, n=n), overrides)


def test_element_bound_is_below_the_true_limit_and_close_to_it() -> None:
    """(C48) against the largest eigenvalue of the assembled flat net (packing 1: the start is
    the stress-free state), with the scaled rotary inertia the run uses."""
    p = prepare(net(packing=1.0))
    model, plan = p.model, p.built
    linear = ThreadSystem(dataclasses.replace(model, tension_only=False))
    _, K, _ = linear.tangents(p.q0, np.zeros(model.n_dof), 0.0)
    scale = sp.diags(1.0 / np.sqrt(model.dof_mass))
    lam = spla.eigsh((scale @ (0.5 * (K + K.T)) @ scale).tocsc(), k=1, which="LA",
                     return_eigenvectors=False)[0]
    omega = np.sqrt(lam)
    zeta = 0.5 * model.tau.max() * omega
    true_limit = 2.0 * (np.sqrt(1.0 + zeta**2) - zeta) / omega
    assert plan.stable_step <= true_limit
    assert plan.stable_step > 0.85 * true_limit        # measured: 0.925
    assert p.dt == pytest.approx(0.5 * plan.stable_step)


def test_cantilever_frequency_against_euler_bernoulli(tmp_path: Path) -> None:
    """First bending mode of a clamped steel rod (1 m, 10 mm) released from a small tip
    velocity: period from the zero crossings against 2 pi / (1.8751^2 sqrt(EI / (rho A L^4)));
    the rotary inertia is scaled by a large factor yet moves the period by well under 1 %."""
    scene = cantilever(duration=0.42, elements=20)
    p = prepare(scene)
    assert p.built.rotary_inertia_scale > 10.0       # measured: 21
    # initial velocity: the static deflection shape of a tip load, 1 mm/s at the tip
    v0 = np.array(p.v0)
    x = p.q0.x[:, 0]
    shape = x**2 * (3.0 - x) / 2.0
    v0[2:3 * len(x):3] = 1e-3 * shape
    times, tips = [], []
    integrate_explicit(p.system, p.system.initial_state(p.q0.copy(), v0), p.times,
                       lambda t, s: (times.append(t), tips.append(s.q.x[-1, 2])))
    z = np.array(tips)
    t = np.array(times)
    up = np.flatnonzero((z[:-1] < 0.0) & (z[1:] >= 0.0))
    crossings = t[up] - z[up] * (t[up + 1] - t[up]) / (z[up + 1] - z[up])
    period = float(np.mean(np.diff(crossings)))
    d, L, E, rho = 0.01, 1.0, 2.0e11, 7800.0
    EI, rhoA = E * np.pi * d**4 / 64.0, rho * np.pi * d**2 / 4.0
    expected = 2.0 * np.pi / (1.8751041**2 * np.sqrt(EI / (rhoA * L**4)))
    # 20 lumped-mass elements without shear correction: the discrete rod is a little softer
    assert period == pytest.approx(expected, rel=0.01)


@pytest.mark.slow
def test_loaded_cantilever_follows_the_implicit_solution(tmp_path: Path) -> None:
    """Tip force and a global-axis tip moment ramped in, gravity and damping: the explicit run
    (supports, dead loads, moments in the body frame, weight) against generalized-alpha at a
    small fixed step, tip path over 0.2 s."""
    loads = """
[[loads]]
node = "beam:end"
force = [0.0, 30.0, -20.0]
moment = [5.0, 0.0, 3.0]
ramp = 0.05
"""
    common = dict(duration=0.2, gravity="[0.0, 0.0, -9.81]", viscosity=2e6, elements=10,
                  loads=loads, frame=0.01)
    tips = {}
    for name, kwargs in {"explicit": dict(integrator="explicit"),
                         "implicit": dict(integrator="generalized-alpha", adaptive="false",
                                          dt=2e-5)}.items():
        result = run(cantilever(**common, **kwargs), tmp_path / name, progress=False)
        assert result.status == "ok", result.message
        tips[name] = result.arrays["positions"][:, -1]
    motion = np.abs(tips["implicit"] - tips["implicit"][0]).max()
    assert motion > 0.05
    assert np.abs(tips["explicit"] - tips["implicit"]).max() < 0.01 * motion


def test_free_net_conserves_linear_momentum_and_loses_energy(tmp_path: Path) -> None:
    result = run(net(duration=0.3), tmp_path, progress=False)
    assert result.status == "ok"
    a = result.arrays
    mass = prepare(net(duration=0.3)).mass
    momentum = np.einsum("n,fnk->fk", mass, a["velocities"])
    assert np.abs(momentum - momentum[0]).max() < 1e-10 * np.abs(momentum[0]).max()
    energy = a["kinetic_energy"] + a["elastic_energy"]
    assert energy[-1] < energy[0]
    assert np.max(np.diff(energy)) < 1e-3 * energy[0]
    assert np.all(a["tension"] >= 0.0)


@pytest.mark.slow
@pytest.mark.parametrize("knots", ["pinned", "rigid"])
def test_net_against_the_implicit_rods_and_the_lumped_net(knots: str, tmp_path: Path) -> None:
    """Largest mouth area of the 5 x 5 net over 0.6 s (it peaks inside): explicit rods against
    generalized-alpha on the same rods (error-controlled: 1e-5 m on the root-mean-square of the
    nodes' local errors) and against the lumped net."""
    areas = {}
    for name, scene in {
        "explicit": net(knots=knots, duration=0.6),
        "implicit": net(knots=knots, duration=0.6, integrator="generalized-alpha",
                        extra=("simulation.error_tolerance=1e-5",)),
        "lumped": scene_from_toml(small_net_toml(duration=0.6, n=2)),
    }.items():
        r = run(scene, tmp_path / name, progress=False)
        assert r.status == "ok", r.message
        areas[name] = r.summary["metrics"]["max_mouth_area"]
    assert areas["explicit"] == pytest.approx(areas["implicit"], rel=3e-3)
    assert areas["explicit"] == pytest.approx(areas["lumped"], rel=3e-3)


def test_scaling_falls_with_the_step_and_starts_with_the_unscaled_momentum() -> None:
    """(C49): a smaller safety means a smaller step and less added inertia; the start angular
    velocities carry the unscaled model's angular momentum."""
    coarse, fine = prepare(net(extra=("simulation.explicit_safety=0.5",))), \
        prepare(net(extra=("simulation.explicit_safety=0.25",)))
    assert fine.dt < coarse.dt
    assert fine.built.rotary_inertia_scale < 0.6 * coarse.built.rotary_inertia_scale
    unscaled = prepare(net(integrator="generalized-alpha"))
    n3 = 3 * unscaled.model.n_nodes
    own = unscaled.model.rotary_inertia.ravel()
    np.testing.assert_allclose(coarse.model.rotary_inertia.ravel() * coarse.v0[n3:],
                               own * unscaled.v0[n3:], rtol=1e-12, atol=1e-300)
    np.testing.assert_array_equal(coarse.v0[:n3], unscaled.v0[:n3])


def test_unscaled_rotations_need_a_tiny_step_and_a_fixed_step_above_the_limit_is_refused() -> None:
    unscaled = prepare(net(extra=("simulation.rotary_inertia_scaling=false",)))
    scaled = prepare(net())
    assert unscaled.built.rotary_inertia_scale == 1.0
    assert unscaled.built.stable_step < 0.01 * scaled.built.stable_step
    with pytest.raises(SceneError, match="simulation.dt"):
        prepare(net(extra=("simulation.adaptive=false", "simulation.dt=1e-3")))


def test_an_inverted_element_stops_the_run() -> None:
    """A rod element stretched far beyond its rest length without tension (its material axis
    turned against its chord; seen in a generalized-alpha run of the reference net at
    error_tolerance 1e-3 m: 46 elements up to 7 times their length, threads in effect cut) ends
    the run with a message naming the element; a regular frame passes."""
    from rodnet.errors import SimulationFailed
    from rodnet.io.recorder import Recorder
    from rodnet.state import Configuration, State

    p = prepare(net(integrator="generalized-alpha"))
    recorder = Recorder(p.system.frame, None, [p.system.check_frame])
    recorder(0.0, p.state)
    a, b = p.model.pos_nodes[7]
    x = p.q0.x.copy()
    x[b] = x[a] + 2.0 * p.model.rest_length[7] * np.array([0.0, 0.0, 1.0])
    with pytest.raises(SimulationFailed, match=r"rod element \d+ .* times its rest length .* inverted"):
        recorder(0.01, State(Configuration(x, p.q0.quat), p.v0))


CROSSING = """
[simulation]
duration = 0.3
integrator = "{integrator}"
adaptive = false
dt = 5.0e-5
[model]
type = "cosserat"
""" + cord() + """
[[rods]]
name = "r"
material = "cord"
points = [[0.0, 0.0, 0.0], [0.1, 0.0, 0.0]]
elements = 1
[[masses]]
node = "r:start"
mass = 0.01
velocity = [1.0, 0.0, 0.0]
[[masses]]
node = "r:end"
mass = 0.01
velocity = [-1.0, 0.0, 0.0]
[output]
frame_interval = 1.0e-3
vtk = false
"""


@pytest.mark.parametrize("integrator", ["explicit", "generalized-alpha"])
def test_ends_driven_through_each_other_bounce_and_the_thread_holds(integrator: str,
                                                                  tmp_path: Path) -> None:
    """A slack element whose two ends are driven through each other along its axis (chord to
    zero, then reversed: material axis against the chord) is pushed back by (C51), a spring of
    stiffness ``k = REVERSED_STIFFNESS EA / L`` on the reversed chord: the ends, closing at
    ``v = 2`` m/s, overshoot by ``v sqrt(mu / k)`` (``mu`` their reduced mass), bounce, and the
    thread then catches them in tension at its length (elastic stretch ``v sqrt(mu L / EA)``).
    With the tension-only law alone the reversed element has no axial force and the ends fly
    apart (the run stops on the inverted element). The step resolves the bounce (symplectic
    Euler's energy error while the ends press stays below the run's 10 % guard)."""
    scene = scene_from_toml(CROSSING.format(integrator=integrator))
    r = run(scene, tmp_path, progress=False)
    assert r.status == "ok", r.message
    x = r.arrays["positions"]
    separation = x[:, 1, 0] - x[:, 0, 0]           # along the rod's own axis, +x at rest
    material = scene.materials[0]                    # the cord: EA and mass per length given
    m = 0.01 + 0.5 * material.mass_per_length * 0.1
    k = REVERSED_STIFFNESS * material.axial_stiffness / 0.1
    overshoot = 2.0 * np.sqrt(0.5 * m / k)
    assert -separation.min() == pytest.approx(overshoot, rel=0.03)
    # the tension caught them at L, stretching the thread by at most v sqrt(mu L / EA)
    assert separation.max() - 0.1 < 1.05 * 2.0 * np.sqrt(0.5 * m * 0.1 / material.axial_stiffness)
    after = r.arrays["time"] > 0.07                  # they met at 0.05 s
    assert separation[after].max() > 0.09            # apart again: the bounce kept its energy


PASSING_MASSES = """
[simulation]
duration = 0.7
gravity = [0.0, 0.0, 0.0]
integrator = "{integrator}"
[model]
type = "cosserat"
[[materials]]
name = "t"
density = 1000.0
youngs_modulus = 1.0e9
diameter = 1.0e-3
axial_stiffness = 1000.0
mass_per_length = 1.0e-6
viscosity = 0.0
[[rods]]
name = "th"
material = "t"
points = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0]]
elements = 1
[[masses]]
node = "th:start"
mass = 1.0
velocity = [1.0, 0.01, 0.0]
[[masses]]
node = "th:end"
mass = 1.0
velocity = [-1.0, -0.01, 0.0]
[output]
frame_interval = 1.0e-2
vtk = false
"""
"""Two 1 kg masses on a slack, nearly massless 1 m thread pass each other 1 cm apart at 0.5 s
(an outside check's scene): the chord turns over within milliseconds, the section with its
raised rotary inertia does not, and the element is inside out while the thread is slack."""


def test_a_section_left_behind_by_its_chord_is_told(tmp_path: Path) -> None:
    explicit = run(scene_from_toml(PASSING_MASSES.format(integrator="explicit")),
                   tmp_path / "explicit", progress=False)
    assert explicit.status == "ok", explicit.message
    assert explicit.arrays["tension"][-1, 0] > 1.0      # 0.01 EA pulls on a slack chord
    assert any("inside out" in w and "rotary_inertia_scaling = false" in w
               for w in explicit.summary["warnings"])
    implicit = run(scene_from_toml(PASSING_MASSES.format(integrator="bdf2")),
                   tmp_path / "bdf2", progress=False)
    assert implicit.status == "ok", implicit.message
    assert implicit.arrays["tension"].max() == 0.0       # slack all the way
    assert not any("inside out" in w for w in implicit.summary["warnings"])


SHAFT = """
[simulation]
duration = 0.002
integrator = "explicit"
rotary_inertia_scaling = {scaling}
[model]
type = "cosserat"
[[materials]]
name = "steel"
density = 7850.0
youngs_modulus = 2.1e11
poisson_ratio = 0.3
diameter = 0.01
[[rods]]
name = "shaft"
material = "steel"
points = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0]]
elements = 20
[[supports]]
node = "shaft:start"
fix = "clamp"
[[loads]]
node = "shaft:end"
moment = [10.0, 0.0, 0.0]
[output]
frame_interval = 1.0e-4
vtk = false
"""
"""A clamped steel shaft twisted by a suddenly applied end torque (an outside check's scene):
its first torsion period is 1.28 ms."""


def test_a_moment_on_sections_of_raised_inertia_is_told(tmp_path: Path) -> None:
    """With the raised rotary inertia the shaft twists far more slowly than its torsion
    period says (the tip reaches its static twist T L / GJ only after the quarter period
    0.32 ms without it); the run says why."""
    GJ = 2.1e11 / 2.6 * np.pi * 0.01**4 / 32.0
    twist = {}
    for scaling in ("true", "false"):
        r = run(scene_from_toml(SHAFT.format(scaling=scaling)), tmp_path / scaling,
                progress=False)
        assert r.status == "ok", r.message
        told = [w for w in r.summary["warnings"] if "loads[0].moment" in w]
        assert bool(told) == (scaling == "true")
        quat = r.arrays["rotations"][:, -1]                # the tip section, (w, x, y, z)
        twist[scaling] = 2.0 * np.arccos(np.clip(np.abs(quat @ quat[0]), 0.0, 1.0))
    t = r.arrays["time"]
    quarter = np.searchsorted(t, 0.32e-3)
    static = 10.0 / GJ
    assert twist["false"][quarter] > 0.8 * static          # at the quarter period, as it should
    assert twist["true"][quarter] < 0.5 * static           # far behind with the raised inertia


def test_a_spin_on_sections_whose_inertia_was_not_raised_is_not_told(tmp_path: Path) -> None:
    """A free stiff rod spinning about its axis (an outside check's torque-free top) needs no
    raise at the explicit step: the factor is 1 to round-off (1 + 3e-14 there), and the
    warning about slowed sections, which claimed a raise 'up to 1 times', is not given."""
    text = SHAFT.format(scaling="true").replace("duration = 0.002", "duration = 0.05")
    text = text.split("[[supports]]")[0] + "[output]\nframe_interval = 0.01\nvtk = false\n"
    text = text.replace('diameter = 0.01\n', 'diameter = 0.01\naxial_stiffness = 1.0e7\n'
                        'shear_stiffness = 1.0e7\nbending_stiffness = 1.0e4\n'
                        'torsional_stiffness = 1.0e4\nmass_per_length = 1.0\n'
                        'rotary_inertia_per_length = 0.05\n')
    text = text.replace('elements = 20\n', 'elements = 10\nangular_velocity = [20.0, 0.0, 2.0]\n')
    r = run(scene_from_toml(text), tmp_path, progress=False)
    assert r.status == "ok", r.message
    assert r.summary["integrator"]["rotary_inertia_scale"] == pytest.approx(1.0, abs=1e-9)
    assert not [w for w in r.summary["warnings"] if "angular_velocity" in w]
