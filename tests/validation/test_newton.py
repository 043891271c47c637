"""Newton's method on stiff threads: few iterations, quadratic convergence.

A real thread of 1 mm diameter and 1 m length has ``EA L^2 / EI = 16 L^2 / d^2`` of about
1.6e7. The rods here have ``EA L^2 / EI = 1e7`` (``EA = 1e7 N``, ``EI = 1 N m^2``, 32 elements):

- Rolled up by an end moment ``M = pi EI / L`` in ten load steps, the cantilever must become a
  half circle (closed form: the tip at ``(0, 2 L / pi)``, to the small axial and shear
  compliance), in at most 6 Newton iterations per load step on average and without a split
  step; the same for a tip force (the elastica, checked against scipy's solution of the
  elastica below).
- The residuals of a static load step and of one large dynamic step (backward Euler,
  generalized-alpha, BDF2) contract quadratically at the end: ``log e_{k+1} / log e_k >= 1.8``
  for the relative residuals ``e`` of the last iterations above the round-off floor.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
from scipy.integrate import solve_bvp

from rodnet.integrate.implicit import SCHEMES
from rodnet.integrate.newton import NewtonOptions
from rodnet.integrate.static import solve_static
from rodnet.run import prepare, run
from rodnet.scene import scene_from_toml

EA, EI, ELEMENTS = 1.0e7, 1.0, 32

STIFF_ROD = """
[simulation]
type = "{kind}"
load_steps = 10
duration = 0.1
dt = 0.05
gravity = {gravity}

[model]
type = "cosserat"
axial = "linear"

[[materials]]
name = "stiff"
density = 1000.0
youngs_modulus = 1.0e9
poisson_ratio = 0.3
diameter = 0.01
axial_stiffness = {EA}
shear_stiffness = {GA}
bending_stiffness = {EI}

[[rods]]
name = "rod"
material = "stiff"
points = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0]]
elements = {elements}

[[supports]]
node = "rod:start"
fix = "clamp"

[[loads]]
node = "rod:end"
{load}

[output]
vtk = false
"""


def stiff_rod(load: str, kind: str = "static", gravity: str = "[0.0, 0.0, 0.0]") -> str:
    return STIFF_ROD.format(kind=kind, gravity=gravity, EA=EA, GA=EA / 2.6, EI=EI,
                            elements=ELEMENTS, load=load)


def last_order(residuals: list[float], floor: float) -> float:
    """``log e_{k+1} / log e_k`` of the last pair of relative residuals ``e = r / r_0`` whose
    smaller one is above ``floor`` (relative) and whose larger one is below 5e-2 (a dynamic
    step's first correction lands near 1e-2: 1, 1.0e-2, 1.9e-7, 2.9e-14 for backward Euler),
    and which still contracts (halves: a static solve takes one more correction at its
    round-off floor, 4.6e-8 -> 3.2e-8 N on the stiff rod)."""
    e = np.asarray(residuals) / residuals[0]
    pairs = [(a, b) for a, b in zip(e[:-1], e[1:]) if a < 5e-2 and b > floor and b < 0.5 * a]
    assert pairs, f"no contraction to measure in {e}"
    a, b = pairs[-1]
    return math.log(b) / math.log(a)


def elastica_tip(P: float) -> tuple[float, float]:
    """Tip of an inextensible cantilever of unit length and EI under a transverse dead tip load
    ``P`` (the elastica: theta'' = -P cos(theta), theta(0) = 0, theta'(1) = 0)."""
    s = np.linspace(0.0, 1.0, 401)

    def rhs(x, y):  # y = [theta, theta', x, y]
        return np.vstack([y[1], -P * np.cos(y[0]), np.cos(y[0]), np.sin(y[0])])

    def bc(a, b):
        return np.array([a[0], b[1], a[2], a[3]])

    guess = np.zeros((4, len(s)))
    guess[2] = s
    sol = solve_bvp(rhs, bc, s, guess, tol=1e-10, max_nodes=20000)
    assert sol.success
    return float(sol.y[2, -1]), float(sol.y[3, -1])


@pytest.mark.parametrize("case", ["moment", "force"])
def test_a_stiff_cantilever_takes_few_newton_iterations_per_load_step(case: str,
                                                                      tmp_path: Path) -> None:
    load = "moment = [0.0, 0.0, 3.141592653589793]" if case == "moment" else \
        "force = [0.0, 3.0, 0.0]"
    r = run(scene_from_toml(stiff_rod(load)), tmp_path, progress=False)
    summary = json.loads((tmp_path / "summary.json").read_text())
    tip = r.arrays["positions"][-1, -1]
    expected = (0.0, 2.0 / math.pi) if case == "moment" else elastica_tip(3.0)
    per_step = summary["newton_iterations"] / summary["steps"]
    print(f"\n{case}: {summary['steps']} load steps, {summary['newton_iterations']} Newton "
          f"iterations ({per_step:.1f} per step), {summary['rejected_steps']} split; tip "
          f"{tip[:2]} against {expected}")
    assert r.status == "ok"
    assert summary["steps"] == 10 and summary["rejected_steps"] == 0
    assert per_step <= 6.0
    assert np.allclose(tip[:2], expected, atol=2e-3)


def test_a_static_load_step_of_a_stiff_rod_converges_quadratically() -> None:
    """The first of the ten load steps of the roll-up, alone: 0.1 pi N m."""
    prepared = prepare(scene_from_toml(stiff_rod("moment = [0.0, 0.0, 0.3141592653589793]")))
    history: list[float] = []
    stats = solve_static(prepared.system, prepared.state, 1, NewtonOptions(rtol=1e-10),
                         lambda t, s: None, history=history)
    print(f"\nresiduals of the load step [N]: {['%.2e' % r for r in history]}")
    assert stats.rejected_steps == 0 and stats.newton_iterations <= 6
    assert last_order(history, 1e-12) >= 1.8


@pytest.mark.parametrize("scheme", ["backward-euler", "generalized-alpha", "bdf2"])
def test_a_large_dynamic_step_of_a_stiff_rod_converges_quadratically(scheme: str) -> None:
    """The straight cantilever released under gravity, steps of 0.05 s (its first bending
    period is 1.8 s, the axial one 0.2 ms): the second step (BDF2's first own step)."""
    prepared = prepare(scene_from_toml(stiff_rod("force = [0.0, 0.0, 0.0]", "dynamic",
                                                 "[0.0, -9.81, 0.0]")))
    stepper = SCHEMES[scheme](prepared.system, NewtonOptions(rtol=1e-10))
    motion = stepper.initial(prepared.state.q, prepared.state.v, 0.0)
    motion, result = stepper.step(motion, 0.0, 0.05)
    assert result.converged
    stepper.history = []
    _, result = stepper.step(motion, 0.05, 0.05)
    print(f"\n{scheme}: residuals [N] {['%.2e' % r for r in stepper.history]}")
    assert result.converged and result.iterations <= 8
    assert last_order(stepper.history, 1e-12) >= 1.8


def test_bdf2_never_gains_energy_on_the_net_with_thick_threads(tmp_path) -> None:
    """The reference net with 3 mm threads under BDF2 and default step control: variable steps
    and threads snapping taut within a step cost BDF2 its energy stability (without the guard
    the energy rose 10 % by 0.11 s and the run stopped); steps that gain energy are taken again
    by backward Euler, so kinetic plus elastic energy never rises (nothing does work)."""
    from rodnet.cli import demo_scene_text
    from rodnet.run import run

    scene = scene_from_toml(demo_scene_text(), [
        "simulation.integrator=bdf2", "materials[0].diameter=3e-3", "simulation.duration=0.15",
        "output.vtk=false", "output.picture=false"])
    r = run(scene, tmp_path, progress=False)
    assert r.status == "ok", r.message
    energy = r.arrays["kinetic_energy"] + r.arrays["elastic_energy"]
    assert energy.max() <= energy[0] * (1.0 + 1e-3)
    assert r.arrays["time"][-1] == pytest.approx(0.15)
    assert 0 < r.summary["retaken_steps"] < r.summary["steps"]   # the guard acted, and said so
