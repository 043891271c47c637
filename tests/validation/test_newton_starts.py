"""A step's Newton solve starts from several guesses in turn (:meth:`Scheme._guesses`); the
run's totals of Newton iterations and factorisations count every solve, the failed starts
included, while the step-size control sees only the solve that was kept."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import rodnet.integrate.implicit as implicit
from rodnet.integrate.newton import NewtonResult
from rodnet.run import run
from rodnet.scene import scene_from_toml
from tests.conftest import falling_thread_toml, small_net_toml


def test_failed_starts_are_counted_in_the_run_totals(tmp_path: Path,
                                                     monkeypatch: pytest.MonkeyPatch) -> None:
    real = implicit.newton
    calls: list[tuple[int, int]] = []
    first_of_step = {"flag": True}

    def newton(problem, u0, scale, solver, options, history):  # type: ignore[no-untyped-def]
        if first_of_step["flag"]:            # every step's first start fails after 3 iterations
            first_of_step["flag"] = False
            calls.append((3, 2))
            return NewtonResult(np.array(u0, copy=True), False, 3, 2, 1.0, "forced failure")
        result = real(problem, u0, scale, solver, options, history)
        calls.append((result.iterations, result.factorizations))
        first_of_step["flag"] = result.converged
        return result

    monkeypatch.setattr(implicit, "newton", newton)
    scene = scene_from_toml(small_net_toml(duration=0.02, integrator="backward-euler", n=2))
    r = run(scene, tmp_path, progress=False)
    assert r.summary["status"] == "ok"
    forced = sum(1 for c in calls if c == (3, 2))
    assert forced >= r.summary["steps"] > 0        # every step had a start that failed
    assert r.summary["newton_iterations"] == sum(c[0] for c in calls)
    assert r.summary["factorizations"] == sum(c[1] for c in calls)


def test_a_run_stops_between_failed_solves_when_asked(tmp_path: Path,
                                                      monkeypatch: pytest.MonkeyPatch) -> None:
    """SIGTERM (as Ctrl-C, which a background job ignores) during a stretch of failed solves
    (each retried with half the step) stops the run at the next failure with its frames kept,
    not only at the next accepted step: a step retried from several starts and halvings can
    take minutes on a Cosserat net."""
    import os
    import signal

    calls = {"n": 0}

    def newton(problem, u0, scale, solver, options, history):  # type: ignore[no-untyped-def]
        calls["n"] += 1
        if calls["n"] == 1:
            os.kill(os.getpid(), signal.SIGTERM)   # noted by the run's handler
        return NewtonResult(np.array(u0, copy=True), False, 1, 1, 1.0, "forced failure")

    monkeypatch.setattr(implicit, "newton", newton)
    scene = scene_from_toml(small_net_toml(duration=0.02, integrator="backward-euler", n=2))
    r = run(scene, tmp_path, progress=False)
    assert r.summary["status"] == "interrupted", r.summary.get("message")
    assert r.summary["rejected_steps"] == 1        # stopped at the first failed solve
    assert (tmp_path / "result.npz").is_file()


def test_bdf2_first_start_extrapolates_a_quadratic_velocity_exactly() -> None:
    """BDF2's ``vd`` is the derivative of the parabola through its last three velocities, so
    for a velocity quadratic in time (constant jerk) the first start lands on the next velocity
    whatever the ratio of the steps; a wrong curvature or step ratio in the extrapolation
    would miss it by ``O(h^2)``."""
    from rodnet.integrate.implicit import BDF2, MotionState
    from rodnet.state import Configuration

    a, b, c = np.array([0.3, -1.0]), np.array([2.0, 0.5]), np.array([-4.0, 7.0])
    v = lambda t: a + b * t + c * t * t          # noqa: E731
    vd = lambda t: b + 2.0 * c * t               # noqa: E731
    t, hp, h = 0.7, 0.004, 0.0065
    q = Configuration(np.zeros((1, 3)), np.zeros((0, 4)))
    state = MotionState(q, v(t), vd(t), vd(t), vd(t - hp), increment=np.zeros(2), step=hp,
                        v_previous=v(t - hp))
    first = BDF2._predictor(BDF2.__new__(BDF2), state, h)[0]
    np.testing.assert_allclose(v(t) + h * first, v(t + h), rtol=0, atol=1e-13)
    # the acceleration extrapolated linearly (the other schemes' first start) misses it
    linear = v(t) + h * (2.0 * vd(t) - vd(t - hp))
    assert np.abs(linear - v(t + h)).max() > 1e-6



def _first_corrections(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> tuple[float, float]:
    """The thread's run: the median over its solves of ``|u1 - u*| / |u0 - u*|`` (start,
    first iterate, solution; largest component), and Newton iterations per step."""
    real = implicit.newton
    ratios: list[float] = []

    def newton(problem, u0, scale, solver, options, history):  # type: ignore[no-untyped-def]
        iterates: list[np.ndarray] = []
        accept = problem.on_accept

        def on_accept(u: np.ndarray) -> None:
            iterates.append(np.array(u, copy=True))
            accept(u)

        problem.on_accept = on_accept
        result = real(problem, u0, scale, solver, options, history)
        if result.converged and iterates:
            start = np.abs(u0 - result.u).max()
            if start > 0.0:
                ratios.append(float(np.abs(iterates[0] - result.u).max() / start))
        return result

    monkeypatch.setattr(implicit, "newton", newton)
    r = run(scene_from_toml(falling_thread_toml(duration=0.25, elements=12,
                                                frame_interval=0.05)), tmp_path, progress=False)
    assert r.summary["status"] == "ok"
    return float(np.median(ratios[5:])), r.summary["newton_iterations"] / r.summary["steps"]


def test_first_correction_of_a_stiff_thread_lands_near_the_solution(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """The extrapolated start of a step stretches a stiff thread by the extrapolation's error:
    its axial forces come out many times the thread's weight, of either sign. Its swing and
    bending are held by the tension alone (the geometric stiffness), so a matrix built on those
    forces gets exactly the soft directions wrong. The first matrix takes the stresses of the
    step's start (:meth:`MixedStrains.start`): the first correction then cuts the error of the
    velocities a hundredfold and more (measured: about a thousandfold), and a step takes two
    Newton iterations. With the start's own stresses the first correction leaves most of the
    error (about 0.7 of it) and a step takes three."""
    ratio, per_step = _first_corrections(tmp_path / "start", monkeypatch)
    assert ratio < 1e-2, ratio
    assert per_step < 2.5, per_step
    # the scene tells the two apart: the start's own stresses in the first matrix
    from rodnet.integrate.mixed import MixedStrains

    monkeypatch.setattr(MixedStrains, "start", MixedStrains.accept)
    ratio, per_step = _first_corrections(tmp_path / "own", monkeypatch)
    assert ratio > 0.2, ratio
    assert per_step > 2.8, per_step
