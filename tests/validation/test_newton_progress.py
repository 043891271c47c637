"""Newton gives up a solve of at least ``2 progress_iterations`` iterations whose residual has not
halved for the last ``progress_iterations`` (the adaptive step control then takes the step again
at half the size).

The problem is that of ``test_newton_residual_filter.py`` judged by its potential alone
(``RESIDUAL_FILTER = 0``): ``r(u) = u + u^3 / 2 - c`` with a potential whose gradient is
``r - d``, whose minimum lies off the root, so that the search creeps near it.
"""

from __future__ import annotations

import numpy as np
import pytest

import rodnet.integrate.newton as newton_module
from rodnet.data import reference_scene_text
from rodnet.integrate.implicit import NEWTON_TARGET
from rodnet.integrate.newton import LinearSolver, NewtonOptions, newton
from rodnet.run import _newton, prepare
from rodnet.scene import scene_from_toml

from tests.validation.test_newton_residual_filter import _problem


def _solve(progress: int | None) -> tuple[newton_module.NewtonResult, list[float]]:
    history: list[float] = []
    result = newton(_problem(), np.zeros(4), 1.0, LinearSolver(),
                    NewtonOptions(rtol=1e-12, atol=1e-13, progress_iterations=progress), history)
    print("residuals:", " ".join(f"{h:.2e}" for h in history))
    return result, history


def test_a_creeping_solve_is_given_up_after_the_iterations_without_halving(
        monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(newton_module, "RESIDUAL_FILTER", 0.0)
    slow, _ = _solve(None)
    fast, history = _solve(4)
    assert not slow.converged and not fast.converged
    assert "no progress" in fast.message and "no progress" not in slow.message
    # given up in the creep near the potential's minimum (the residual standing at 2e-4), once
    # the solve has taken 8 iterations, where the unlimited solve takes 33 before it stalls
    assert 8 <= fast.iterations <= 12 < slow.iterations
    assert history[-1] > 0.99 * history[-2] > 1e-4


def test_a_converging_solve_is_not_cut_short() -> None:
    # with the limit the runs use: the overshooting first steps from u = 0 do not halve the
    # residual, Newton's tail halves it at every iteration
    result, history = _solve(NEWTON_TARGET)
    assert result.converged, result.message
    assert history[-1] <= 1e-12


def test_only_adaptive_dynamic_runs_of_rods_give_up_on_progress() -> None:
    """Fixed steps end the run on a failed solve, static load steps keep their own splitting,
    and threads without rotations (lumped, contact) take no easier steps when shorter: only
    adaptive dynamic runs of threads with rotation unknowns retry a creeping step at half the
    size."""
    def options(*keys: str) -> NewtonOptions:
        return _newton(prepare(scene_from_toml(reference_scene_text(), list(keys))))
    assert options("model.type=cosserat").progress_iterations == NEWTON_TARGET
    assert options("model.type=cosserat", "simulation.adaptive=false",
                   "simulation.dt=1e-3").progress_iterations is None
    assert options("model.type=lumped", "simulation.integrator=bdf2").progress_iterations is None
    # a fixed step's solve runs on while its residual stands (a failed solve ends the run)
    assert options("model.type=cosserat").standing_iterations == 50
    assert options("model.type=cosserat", "simulation.adaptive=false",
                   "simulation.dt=1e-3").standing_iterations is None


def test_step_control_shrinks_on_iterations_only_where_rotations_creep() -> None:
    """A step that took 24 Newton iterations halves the next where a shorter step converges
    faster (threads with rotation unknowns); elsewhere it only stops the next from growing,
    and the error estimate alone shrinks it."""
    from rodnet.integrate.implicit import _resize_factor
    from rodnet.run import _rotations_creep

    def creep(*keys: str) -> bool:
        return _rotations_creep(prepare(scene_from_toml(reference_scene_text(), list(keys))))
    assert creep("model.type=cosserat")
    assert not creep("model.type=cosserat", "model.bending=false", "model.torsion=false")
    assert not creep("model.type=lumped", "simulation.integrator=bdf2")
    assert not creep("model.type=cosserat", "simulation.adaptive=false", "simulation.dt=1e-3")
    many = 4 * NEWTON_TARGET
    # an error estimate a quarter of the tolerance lets a second-order step grow 1.43 times
    assert _resize_factor(0.25, 1.0, many, 2, newton_shrinks=True) == pytest.approx(0.5)
    assert _resize_factor(0.25, 1.0, many, 2, newton_shrinks=False) == 1.0
    assert _resize_factor(0.25, 1.0, 2, 2, newton_shrinks=False) == pytest.approx(0.9 * 4**(1/3))
    # an error above the tolerance shrinks the step either way
    assert _resize_factor(8.0, 1.0, many, 2, newton_shrinks=False) == pytest.approx(0.45)


SLIDE = """
[simulation]
duration = 0.6
gravity = [0.0, 0.0, -9.81]
[model]
type = "cosserat"
axial = "linear"
bending = false
torsion = false
[[materials]]
name = "steel"
density = 7800.0
youngs_modulus = 2.0e11
poisson_ratio = 0.3
diameter = 0.005
[[rods]]
name = "rod"
material = "steel"
points = [[-0.1, 0.0, 0.0075], [0.1, 0.0, 0.0075]]
elements = 10
velocity = [1.0, 0.0, 0.0]
[[bodies]]
name = "table"
shape = "box"
size = [2.0, 1.0, 0.2]
position = [0.5, 0.0, -0.1]
fixed = true
[contact]
damping = 10.0
friction = 0.3
[output]
vtk = false
"""


def test_a_solve_whose_residual_stands_is_given_up(tmp_path, monkeypatch: pytest.MonkeyPatch) -> None:
    """A steel rod (cable threads, BDF2 at defaults) dropped 5 mm onto a table while moving at
    1 m/s slides to rest under friction 0.3: v0 t_fall + v1^2 / (2 mu g) with the landing's
    friction impulse taking mu sqrt(2 g h) off v0 (0.17140 m). Friction is outside the step's
    potential, so some solves lowered the potential without end at a standing residual (61.5 N
    for 190 iterations) until the 200-iteration limit; they now fail after
    ``standing_iterations`` and the step is taken again at half the size, as before."""
    import rodnet.integrate.implicit as implicit
    from rodnet.run import run

    counts: list[int] = []
    solve = implicit.newton

    def counted(*args, **kwargs):  # type: ignore[no-untyped-def]
        result = solve(*args, **kwargs)
        counts.append(result.iterations)
        return result

    monkeypatch.setattr(implicit, "newton", counted)
    result = run(scene_from_toml(SLIDE), tmp_path, progress=False)
    assert result.status == "ok", result.message
    assert NewtonOptions().standing_iterations == 50
    assert max(counts) <= 55                     # 200 before: the limit of a solve
    g, mu, h = 9.81, 0.3, 0.005
    fall = np.sqrt(2.0 * h / g)
    landed = 1.0 - mu * np.sqrt(2.0 * g * h)
    x = result.arrays["positions"][:, :, 0].mean(axis=1)
    assert x[-1] - x[0] == pytest.approx(fall + landed**2 / (2.0 * mu * g), rel=2e-3)
    assert abs(result.arrays["velocities"][-1, :, 0]).max() < 1e-3
