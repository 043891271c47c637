"""Run a scene end to end: check, build, integrate, and write every result the scene asks for.

Everything that can be checked is checked before the output directory is touched, so a bad scene
never leaves a half-written directory. Once the run starts, every computed frame is kept: a run that
diverges or is interrupted still writes its frames, ``result.npz`` and a ``summary.json`` with
``status = "failed"`` and the reason.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable

import numpy as np
from numpy.typing import NDArray

from rodnet.config import Scene
from rodnet.contact.bodies import check_contact_supported
from rodnet.contact.output import ContactLog, body_surfaces
from rodnet.errors import SceneError, SimulationFailed
from rodnet.integrate.frames import StepStats, frame_times
from rodnet.io.results import output_directory, scene_as_dict, write_npz, write_summary
from rodnet.io.vtk import VtkSeries
from rodnet.kernels.cosserat_strain import ROTATION_STOP
from rodnet.kernels.threads import use_threads
from rodnet.metrics import distance, mouth_area, net_metrics
from rodnet.progress import Progress
from rodnet.formulations.cosserat_build import build_cosserat
from rodnet.integrate.implicit import Stepper, integrate_implicit, solve_static
from rodnet.integrate.newton import NewtonOptions
from rodnet.formulations.kirchhoff import check_kirchhoff, hinges_of
from rodnet.reference.lumped import build_lumped
from rodnet.topology import Structure, build_structure

IMPLICIT = ("generalized-alpha", "backward-euler", "midpoint")
LUMPED_ONLY = ("rk45",)
IMPLICIT_ADVICE = ("reduce simulation.dt or set simulation.adaptive = true (with it, a smaller "
                   "error_tolerance or dt_max)")
"""What a run's stability messages advise for the implicit integrators."""


@dataclass(frozen=True)
class Prepared:
    """A scene turned into a model, an initial state and a stepping plan, ready to run."""

    scene: Scene
    model: Any            # LumpedModel (lumped, or cable threads) or CosseratModel
    q0: Any
    v0: NDArray[np.float64]
    times: NDArray[np.float64]
    dt: float
    mass: NDArray[np.float64]   # (N,) translational node masses [kg]
    structure: Structure
    near_dt: float | None = None  # explicit with bodies: the step while a body is within reach
    rod_plan: Any = None  # explicit Cosserat rods: the ExplicitRodPlan (step, rotary inertia)


def prepare(scene: Scene) -> Prepared:
    """Build the model and check the stepping plan; raises :class:`SceneError` on bad input."""
    sim, integrator = scene.simulation, scene.integrator
    structure = build_structure(scene)
    rods_mode = scene.model.type == "cosserat" and (scene.model.bending or scene.model.torsion)
    check_contact_supported(scene)
    if rods_mode:
        model, q0, v0 = build_cosserat(scene, structure)
        if scene.bodies:
            from rodnet.contact.cosserat import cosserat_with_bodies

            model = cosserat_with_bodies(model, scene, structure)
        if integrator in LUMPED_ONLY and sim.type == "dynamic":
            raise SceneError("simulation.integrator", integrator, "Cosserat rods need an implicit "
                             f"integrator ({', '.join(IMPLICIT)}) or 'explicit'")
        mass = model.node_mass
        if integrator == "explicit" and sim.type == "dynamic":
            from rodnet.integrate.explicit_rods import explicit_plan, node_inverse_mass

            plan = explicit_plan(model, sim.dt, sim.adaptive, sim.explicit_safety,
                                 sim.rotary_inertia_scaling)
            near_dt = None
            if scene.bodies:  # the step while a body is within reach: contact springs too (E1)
                near = model.contact.combined_step(plan.stable_step, node_inverse_mass(model))
                near_dt = sim.explicit_safety * near if sim.adaptive else min(plan.dt, near)
            return _prepared_times(scene, plan.model(model), q0, plan.initial_velocities(model, v0),
                                   plan.dt, mass, structure, rod_plan=plan, near_dt=near_dt)
    else:  # lumped reference, Kirchhoff threads, or Cosserat threads without bending and torsion
        kirchhoff = scene.model.type == "kirchhoff"
        if kirchhoff:
            check_kirchhoff(scene)
        hinges = hinges_of(scene, structure) if kirchhoff and scene.model.bending else None
        model = build_lumped(scene, structure, hinges)
        q0, mass = structure.positions.copy(), model.mass
        v0 = structure.velocities.copy()
        v0[model.inv_mass == 0.0] = 0.0
        v0 = v0.ravel() if integrator in IMPLICIT or sim.type == "static" else v0
    dt, near_dt = sim.dt, None
    if sim.type == "dynamic" and integrator == "explicit":
        # with bodies: the threads' own limit while every body is out of reach, the limit with
        # the contact springs (model.stable_step) while one is within reach (E5)
        near = model.stable_step()
        far = getattr(model, "far_stable_step", None)
        limit = near if far is None else far()
        if sim.adaptive:
            dt = sim.explicit_safety * limit
        elif dt > limit:
            raise SceneError("simulation.dt", dt, f"exceeds the explicit stability limit "
                             f"{limit:.3g} s of this scene; use dt <= {limit:.3g} "
                             f"(about half of it for accurate snap loads) or adaptive = true")
        if far is not None:
            near_dt = sim.explicit_safety * near if sim.adaptive else min(dt, near)
    if sim.type == "static":
        _check_supported(model, q0, [s.node for s in scene.supports])
    return _prepared_times(scene, model, q0, v0, dt, mass, structure, near_dt=near_dt)


def _prepared_times(scene: Scene, model: Any, q0: Any, v0: NDArray[np.float64], dt: float,
                    mass: NDArray[np.float64], structure: Structure, **extra: Any) -> Prepared:
    """:class:`Prepared` with the output times: load levels of a static run, frames else."""
    if scene.simulation.type == "static":
        times = np.arange(1, scene.simulation.load_steps + 1) / scene.simulation.load_steps
    else:
        times = frame_times(scene.simulation.duration, scene.output.frame_interval)
    return Prepared(scene, model, q0, v0, times, dt, mass, structure, **extra)


def _check_supported(model: Any, q0: Any, supports: list[str]) -> None:
    """Refuse a static scene whose unloaded tangent stiffness is singular (a free rigid motion,
    a mechanism, or slack tension-only threads): no static equilibrium would be determined."""
    import scipy.sparse.linalg as spla

    K = model.tangents(q0, np.zeros(model.n_dof), 0.0, 0.0)[1].tocsc()
    scale = float(np.abs(K.diagonal()).max(initial=0.0))
    try:
        pivots = np.abs(spla.splu(K).U.diagonal())
        singular = int(np.sum(pivots <= 1e-10 * scale)) if scale > 0 else K.shape[0]
    except RuntimeError:
        singular = 1
    if singular:
        raise SceneError("supports", supports or "none",
                         f"the structure is not held against rigid motion: its static stiffness has "
                         f"{singular} zero mode(s). Add [[supports]] (a clamp, or pins that stop every "
                         "translation and rotation) or run it dynamically; with axial = 'tension-only' "
                         "a thread at rest has no axial stiffness at all: use 'linear' for structures")


def _kinetic_and_elastic(model: Any, q: Any, v: NDArray[np.float64], t: float) -> tuple[float, float]:
    """Kinetic (translational and rotational) and elastic energy [J] of a frame."""
    if isinstance(q, np.ndarray):  # the lumped model: implicit integrators pass flat velocities
        q, v = q.reshape(-1, 3), v.reshape(-1, 3)
    energy = model.energy(q, v, t)
    return energy["kinetic"], energy["elastic"]


@dataclass
class Recorder:
    """Keeps every frame in memory and streams it to VTK when asked."""

    model: Any
    vtk: VtkSeries | None
    skip_first: bool = False
    energy_guard: bool = False
    """Stop the run when the energy grows: only for scenes with nothing that does work on them
    (no gravity, no loads), whose kinetic plus elastic energy can only fall."""
    advice: str = IMPLICIT_ADVICE
    """What the messages of the energy and inverted-element checks tell the user to do."""
    time: list[float] = field(default_factory=list)
    frames: list[dict[str, NDArray[np.float64]]] = field(default_factory=list)
    max_element_rotation: float = 0.0
    """Largest relative rotation [rad] of a rod element's end triads over the saved frames."""

    ENERGY_GROWTH = 0.1
    """The guard's threshold: a rise above the start energy by this fraction of it."""

    def __call__(self, t: float, q: Any, v: NDArray[np.float64]) -> None:
        if self.skip_first:  # a static run's unloaded start is not a load step
            self.skip_first = False
            return
        frame = self.model.frame_arrays(q, v)
        frame["kinetic_energy"], frame["elastic_energy"] = _kinetic_and_elastic(self.model, q, v, t)
        if hasattr(self.model, "element_rotation"):
            self.max_element_rotation = max(self.max_element_rotation,
                                            float(self.model.element_rotation(q).max(initial=0.0)))
        self.time.append(t)
        self.frames.append(frame)
        if self.vtk is not None:
            self.vtk.write(t, frame)
        if self.energy_guard:
            self._check_energy(t)
        self._check_inverted(t, frame)

    INVERTED_STRETCH = 1.5
    """Chord over rest length above which a rod element counts as inverted."""

    def _check_inverted(self, t: float, frame: dict[str, NDArray[np.float64]]) -> None:
        """Raise :class:`SimulationFailed` when a rod element's chord is longer than
        ``INVERTED_STRETCH`` times its rest length: its material axis has turned against the
        chord (FORMULATION.md §10), and with the tension-only law it carries no axial force at
        any length, so the thread is in effect cut (the frame is kept: it shows the element)."""
        ends = getattr(self.model, "pos_nodes", None)
        rest = getattr(self.model, "rest_length", None)
        if ends is None or rest is None or not hasattr(self.model, "rot_nodes"):
            return
        x = frame["positions"]
        stretch = np.linalg.norm(x[ends[:, 1]] - x[ends[:, 0]], axis=1) / rest
        e = int(np.argmax(stretch))
        if stretch[e] > self.INVERTED_STRETCH:
            raise SimulationFailed(
                f"rod element {e} (nodes {ends[e, 0]}-{ends[e, 1]}) is {stretch[e]:.3g} times its "
                f"rest length at t = {t:.6g} s with an axial force of {frame['tension'][e]:.3g} N: "
                "its material axis has turned against its chord (an inverted element), so it "
                f"resists no stretching; {self.advice}")

    def _check_energy(self, t: float) -> None:
        """Raise :class:`SimulationFailed` when the energy exceeds its start value by more than
        ``ENERGY_GROWTH`` of it (the frame is kept: it shows the growth)."""
        start = self.frames[0]["kinetic_energy"] + self.frames[0]["elastic_energy"]
        now = self.frames[-1]["kinetic_energy"] + self.frames[-1]["elastic_energy"]
        if not np.isfinite(now):
            raise SimulationFailed(f"the state became non-finite (NaN or inf) by t = {t:.6g} s")
        if now > start * (1.0 + self.ENERGY_GROWTH) and now - start > 1e-9:
            raise SimulationFailed(
                f"the energy grew from {start:.6g} J to {now:.6g} J by t = {t:.6g} s although "
                f"nothing does work on the structure: the time integration is unstable at this "
                f"step; {self.advice}")

    def arrays(self, structure: Structure) -> dict[str, NDArray[Any]]:
        """``time``, ``kinetic_energy`` and ``elastic_energy`` (F,), ``positions`` and
        ``velocities`` (F, N, 3), ``tension`` (F, E), rods also ``rotations`` (F, N, 4),
        ``curvature`` and ``twist`` (F, E); ``segments`` (E, 2)."""
        n, e = structure.n_nodes, len(structure.segments)
        out: dict[str, NDArray[Any]] = {"time": np.array(self.time)}
        shapes = {"positions": (n, 3), "velocities": (n, 3), "rotations": (n, 4), "tension": (e,),
                  "curvature": (e,), "twist": (e,), "kinetic_energy": (), "elastic_energy": ()}
        keys = self.frames[0].keys() if self.frames else ("positions", "velocities", "tension")
        for key in keys:
            out[key] = np.array([f[key] for f in self.frames]).reshape(-1, *shapes[key])
        out["segments"] = np.asarray(structure.segments)
        return out


@dataclass(frozen=True)
class RunResult:
    """What a run produced: its status, where it wrote, the summary and the arrays."""

    status: str
    message: str
    directory: Path
    summary: dict[str, Any]
    arrays: dict[str, NDArray[Any]]


def run(scene: Scene, directory: str | Path | None = None, *, progress: bool | None = None,
        after: Callable[[RunResult], None] | None = None, threads: int | None = None) -> RunResult:
    """Run ``scene`` and write its results to ``directory`` (default: ``output.directory``).

    Parameters
    ----------
    progress : bool, optional
        Show the progress line; default: only when standard error is a terminal.
    after : callable, optional
        Called with the result once the files are written (pictures, plots).
    threads : int, optional
        Threads of the compiled parallel loops; default: :func:`rodnet.kernels.threads.use_threads`
        chooses from the problem size.
    """
    prepared = prepare(scene)
    n_threads = use_threads(len(prepared.structure.segments), threads)
    out = output_directory(directory if directory is not None else scene.output.directory,
                           "output.directory" if directory is None else "-o (output directory)")
    vtk = VtkSeries(out, prepared.structure.segments, body_surfaces(prepared.model)) \
        if scene.output.vtk else None
    unloaded = not any(scene.simulation.gravity) and not scene.loads
    recorder = Recorder(prepared.model, vtk, skip_first=scene.simulation.type == "static",
                        energy_guard=unloaded and scene.simulation.type == "dynamic",
                        advice=_stability_advice(prepared))
    bar = Progress(scene.simulation.duration, enabled=progress)
    status, message, stats = "ok", "", StepStats()
    contact = getattr(prepared.model, "contact", None)
    log = ContactLog(contact, recorder, stats) if contact is not None else None
    start = time.perf_counter()
    try:
        stats = _integrate(prepared, log or recorder, bar, stats)
    except SimulationFailed as exc:
        status, message = "failed", str(exc)
    except KeyboardInterrupt:
        status, message = "failed", "interrupted by the user; the frames computed so far are kept"
    finally:
        bar.close()
        wall = time.perf_counter() - start
        arrays = recorder.arrays(prepared.structure)
        summary = _summary(prepared, arrays, stats, status, message, wall,
                           recorder.max_element_rotation)
        summary["threads"] = n_threads
        if log is not None:
            log.add_results(arrays, summary)
        write_npz(out / "result.npz", arrays)
        write_summary(out / "summary.json", summary)
    result = RunResult(status, message, out, summary, arrays)
    if after is not None:
        after(result)
    return result


def _integrate(p: Prepared, recorder: Recorder, bar: Progress, stats: StepStats) -> StepStats:
    sim = p.scene.simulation
    # an adaptive dynamic run halves a step on which Newton stalls instead of iterating on
    options = NewtonOptions(rtol=min(sim.rtol, 1e-6) * 1e-2,
                            reuse_factorization=sim.reuse_factorization,
                            stall_iterations=4 if sim.adaptive and sim.type == "dynamic" else None)
    if sim.type == "static":
        return solve_static(p.model, p.q0, sim.load_steps, options, recorder, stats=stats)
    if p.scene.integrator == "rk45":
        from rodnet.integrate.rk45 import integrate_rk45

        return integrate_rk45(p.model, p.q0, p.v0, p.times, sim.rtol, recorder, bar, stats=stats)
    if p.rod_plan is not None:
        from rodnet.integrate.explicit_rods import integrate_explicit_rods

        return integrate_explicit_rods(p.model, p.q0, p.v0, p.times, p.rod_plan, recorder, bar,
                                       stats=stats, near_dt=p.near_dt)
    if p.scene.integrator == "explicit":
        from rodnet.integrate.explicit import integrate_explicit

        return integrate_explicit(p.model, p.q0, p.v0, p.times, p.dt, recorder, bar, stats=stats,
                                  near_dt=p.near_dt)
    stepper = Stepper(p.model, p.scene.integrator, sim.rho_inf, options)
    return integrate_implicit(stepper, p.q0, p.v0, p.times, p.dt, sim.adaptive, recorder, bar,
                              dt_max=sim.dt_max, error_tolerance=sim.error_tolerance, stats=stats)


ROTATION_KEYS = ("model.bending", "model.torsion", "model.knots", "model.shear_correction",
                 "simulation.rotary_inertia_scaling")
"""Keys that only rod elements with rotations read."""


def unused_keys(scene: Scene) -> tuple[str, ...]:
    """The scene keys that have no effect on the run of ``scene``'s model (left out of
    ``summary.json``): the rotation keys for the lumped model, cable threads (Cosserat threads
    without bending and torsion) and Kirchhoff threads (whose bending is ``model.bending`` and
    whose knots must be pinned), and ``rotary_inertia_scaling`` for implicit rods."""
    model = scene.model
    if model.type == "lumped" or (model.type == "cosserat" and not (model.bending or model.torsion)):
        return ROTATION_KEYS
    if model.type == "kirchhoff":
        return tuple(k for k in ROTATION_KEYS if k not in ("model.bending", "model.knots"))
    return ("simulation.rotary_inertia_scaling",) if scene.integrator != "explicit" else ()


def _stability_advice(p: Prepared) -> str:
    """What to change when a run turns unstable."""
    if p.scene.integrator != "explicit":
        return IMPLICIT_ADVICE
    if p.rod_plan is not None:
        return ("reduce simulation.explicit_safety; if integrator.max_element_rotation in "
                "summary.json is near 2 pi, use more elements_per_thread")
    return "reduce simulation.explicit_safety (or simulation.dt with adaptive = false)"


def _stable_step(p: Prepared) -> float | None:
    """The explicit stability limit [s]: (S10) of lumped models and cables, (C48) of explicit rods."""
    if p.rod_plan is not None:
        return p.rod_plan.stable_step
    return p.model.stable_step() if hasattr(p.model, "stable_step") else None


def _warnings(stats: StepStats, frame_rotation: float) -> list[str]:
    """What the user should know about a completed or failed run: a rod element turned past the
    rotation stop (C52), where the stop's moment, not the section, resisted its rotation."""
    phi = max(stats.max_element_rotation or 0.0, frame_rotation)
    if phi <= ROTATION_STOP:
        return []
    return [f"a rod element turned by {phi:.4f} rad between its end triads, "
            f"{phi - ROTATION_STOP:.2g} rad past the rotation stop at {ROTATION_STOP:g} rad "
            "(FORMULATION.md C52): there the stop's stiffness, not the section's, resisted it, "
            "so the rod bends or twists more sharply than its elements resolve; use more "
            "elements (model.elements_per_thread, or rods.elements)"]


def _summary(p: Prepared, arrays: dict[str, NDArray[Any]], stats: StepStats, status: str,
             message: str, wall: float, frame_rotation: float = 0.0) -> dict[str, Any]:
    structure = p.structure
    metrics: dict[str, float] = {}
    if len(arrays["time"]):
        metrics["max_tension"] = max(stats.max_tension, float(arrays["tension"].max(initial=0.0)))
        metrics["max_tension_at_frames"] = float(arrays["tension"].max(initial=0.0))
    if structure.net is not None and len(arrays["time"]):
        area = mouth_area(arrays["positions"], structure.net)
        dist = distance(arrays["positions"], p.mass, structure.net)
        arrays["mouth_area"], arrays["distance"] = area, dist
        metrics.update(net_metrics(arrays["time"], area, dist))
    return {
        "status": status, "message": message, "wall_time_s": wall,
        "steps": stats.steps, "newton_iterations": stats.newton_iterations,
        "factorizations": stats.factorizations, "rejected_steps": stats.rejected_steps,
        "function_evaluations": stats.function_evaluations,
        "frames": len(arrays["time"]), "simulated_time_s": float(arrays["time"][-1]) if len(arrays["time"]) else 0.0,
        "integrator": {"name": p.scene.integrator, "dt": p.dt if p.scene.integrator == "explicit" else None,
                       "dt_near_bodies": p.near_dt,
                       "dt_min": stats.dt_min if stats.steps else None, "dt_max": stats.dt_max or None,
                       "stable_step": _stable_step(p),
                       "rotary_inertia_scale": p.rod_plan.scale if p.rod_plan is not None else None,
                       "max_element_rotation": stats.max_element_rotation},
        "model": {"type": p.scene.model.type, "nodes": structure.n_nodes,
                  "elements": len(structure.segments), "dofs": p.model.n_dof},
        "nodes": structure.selectors, "metrics": metrics,
        "warnings": _warnings(stats, frame_rotation),
        "scene": scene_as_dict(p.scene, unused_keys(p.scene)),
    }
