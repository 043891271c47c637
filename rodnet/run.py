"""Run a scene end to end: check, build, integrate, and write every result the scene asks for.

Everything that can be checked is checked before the output directory is touched, so a bad scene
never leaves a half-written directory. Once the run starts, every computed frame is kept: a run that
diverges still writes its frames, ``result.npz`` and a ``summary.json`` with ``status = "failed"``
and the reason; one stopped by Ctrl-C (SIGINT) or SIGTERM (what ``timeout``, batch schedulers and
dask workers send) the same with ``status = "interrupted"``.

The run knows no model: the registry (:mod:`rodnet.models.registry`) turns the scene into a system
and its initial state, :data:`INTEGRATORS` picks the integrator by name, and the recorder
(:mod:`rodnet.io.recorder`) keeps the frames the system's frame function makes of the state.
"""

from __future__ import annotations

import dataclasses
import math
import signal
import threading
import time
from collections.abc import Iterator
from contextlib import ExitStack, contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable

import numpy as np
import scipy.sparse as sp
from numpy.typing import NDArray
from scipy.sparse.csgraph import connected_components

from rodnet import config
from rodnet.config import Scene
from rodnet.contact.rigid_body import start_motion
from rodnet.errors import SceneError, SimulationFailed
from rodnet.integrate.explicit import integrate_explicit
from rodnet.integrate.frames import StepStats, frame_times
from rodnet.integrate.implicit import NEWTON_TARGET, SCHEMES, integrate_implicit
from rodnet.integrate.newton import NewtonOptions
from rodnet.integrate.rk45 import integrate_rk45
from rodnet.integrate.static import STATIC_TIME, solve_static
from rodnet.io.recorder import (FrameCheck, Recorder, energy_gain, energy_guard,
                                mechanical_energy)
from rodnet.io.restart import restarted, saved_frame
from rodnet.io.results import output_directory, scene_as_dict, write_npz, write_summary
from rodnet.io.vtk import VtkSeries
from rodnet.kernels.cache import compile_timer
from rodnet.kernels.cosserat_strain import ROTATION_STOP
from rodnet.kernels.schedule import break_times, jump_times, schedule_of
from rodnet.kernels.threads import use_threads
from rodnet.metrics import distance, mouth_area, net_metrics
from rodnet.models.loads import timings
from rodnet.models.registry import MODELS, Built, build, unused_keys
from rodnet.models.system import ThreadSystem
from rodnet.progress import Progress
from rodnet.state import Configuration, State
from rodnet.topology import Structure

IMPLICIT_ADVICE = ("reduce simulation.dt or set simulation.adaptive = true (with it, a smaller "
                   "error_tolerance or dt_max)")
"""What a run's stability messages advise for the implicit integrators."""


@dataclass(frozen=True)
class Prepared:
    """A scene turned into a system, an initial state and a stepping plan, ready to run."""

    scene: Scene
    built: Built
    times: NDArray[np.float64]
    """Where the integrators stop: the saved frames and the times a load switches."""
    frames: NDArray[np.float64]
    """The saved frames' times (load steps of a static run)."""
    breaks: NDArray[np.float64]
    """The times a load's factor jumps or kinks, in ``times`` too."""
    start_quat: NDArray[np.float64]
    """The rotation nodes' quaternions (R, 4) at the start (the integrators advance the state in
    place)."""
    jumps: NDArray[np.float64] = dataclasses.field(default_factory=lambda: np.zeros(0))
    """The breaks where a load's factor jumps: where implicit schemes start afresh."""

    @property
    def system(self) -> ThreadSystem:
        return self.built.system

    @property
    def model(self) -> Any:
        """The thread model of the system."""
        return self.built.system.model

    @property
    def state(self) -> State:
        return self.built.state

    @property
    def q0(self) -> Configuration:
        """The initial configuration."""
        return self.built.state.q

    @property
    def v0(self) -> NDArray[np.float64]:
        """The initial velocities (n_dof,)."""
        return self.built.state.v

    @property
    def structure(self) -> Structure:
        return self.built.structure

    @property
    def mass(self) -> NDArray[np.float64]:
        """(N,) translational node masses [kg]."""
        return self.built.system.node_mass

    @property
    def dt(self) -> float:
        """The explicit step [s] (before shrinking to whole steps), else ``simulation.dt``."""
        control = self.built.system.control
        return control.dt if control is not None else self.scene.simulation.dt


def prepare(scene: Scene) -> Prepared:
    """Build the system and check the stepping plan; raises :class:`SceneError` on bad input."""
    built = build(scene)
    contact = built.system.contact
    if not built.system.free.any() and not (contact and len(contact.moving)):
        raise SceneError("supports", f"{len(scene.supports)} entries",
                         "hold every degree of freedom of the structure and there is no free "
                         "body: nothing can move; free a node or a direction to run the scene")
    if scene.simulation.type == "static":
        _check_supported(built.system, built.structure, scene)
        if scene.initial is not None and scene.initial.from_ is not None:
            built = _static_start(scene, built)
        times = np.arange(1, scene.simulation.load_steps + 1) / scene.simulation.load_steps
        return Prepared(scene, built, times, times, np.zeros(0), built.state.q.quat.copy())
    _check_run_size(scene, built)
    frames = frame_times(scene.simulation.duration, scene.output.frame_interval)
    if scene.initial is not None and scene.initial.from_ is not None:
        built, frames = _restart(scene, built, frames)
    schedule, end = schedule_of(timings(scene)), float(frames[-1])
    breaks = _on_frames(break_times(schedule, end), frames, scene)
    return Prepared(scene, built, np.union1d(frames, breaks), frames, breaks,
                    built.state.q.quat.copy(), _on_frames(jump_times(schedule, end), frames, scene))


FRAME_MEMORY = 8 * 2**30
"""The most memory [bytes] the saved frames of a run may take (positions and velocities alone);
result.npz takes as much on disk."""

MAX_EXPLICIT_STEPS = 1e10
"""The most steps an explicit run may plan (at a microsecond each, about three hours)."""


def _check_run_size(scene: Scene, built: Built) -> None:
    """Refuse a dynamic run whose saved frames would not fit in memory (a duration written in
    milliseconds as seconds) or whose explicit stability limit asks for more than
    :data:`MAX_EXPLICIT_STEPS` steps (a stiffness written many orders too high)."""
    sim = scene.simulation
    frames = sim.duration / scene.output.frame_interval + 1.0
    size = frames * 48.0 * built.system.n_dof
    if size > FRAME_MEMORY:
        raise SceneError("output.frame_interval", scene.output.frame_interval,
                         f"saves {frames:.3g} frames over simulation.duration = {sim.duration:g} s, "
                         f"about {size / 2**30:.3g} GiB of positions and velocities alone (at most "
                         f"{FRAME_MEMORY / 2**30:g} GiB): raise output.frame_interval or shorten "
                         "simulation.duration")
    control = built.system.control
    if scene.integrator != "explicit" or control is None or not sim.adaptive:
        return
    step = control.stable_step * sim.explicit_safety
    steps = sim.duration / step if step > 0.0 else math.inf
    near = sim.duration / control.near_dt if control.near_dt > 0.0 else math.inf
    if scene.bodies and steps <= MAX_EXPLICIT_STEPS and not near <= MAX_EXPLICIT_STEPS:
        # a stiffness written many orders too high: the compiled loop would run for days
        # between frames, deaf to a stop request (1e18 N/m ran on after SIGTERM, outside check)
        raise SceneError("contact.stiffness",
                         built.system.contact.bodies.law.stiffness,  # type: ignore[union-attr]
                         f"makes the explicit step near a body {control.near_dt:.3g} s, so "
                         f"simulation.duration = {sim.duration:g} s would take up to {near:.3g} "
                         f"steps there (at most {MAX_EXPLICIT_STEPS:.0e}): choose it from the "
                         "loads and the admissible penetration (docs/contact.md), or use an "
                         "implicit integrator")
    if not steps <= MAX_EXPLICIT_STEPS:
        limit = (f"is {control.stable_step:.3g} s, so simulation.duration = {sim.duration:g} "
                 f"s would take {steps:.3g} steps (at most {MAX_EXPLICIT_STEPS:.0e})"
                 ) if control.stable_step > 0.0 else "rounds to 0 s"
        raise SceneError("simulation.integrator", "explicit",
                         f"the explicit stability limit of this scene {limit}: a thread far too stiff for its "
                         "lightest node (check the materials' youngs_modulus, axial_stiffness and "
                         "viscosity, and the masses), or use an implicit integrator")


def _restart(scene: Scene, built: Built, frames: NDArray[np.float64]
             ) -> tuple[Built, NDArray[np.float64]]:
    """``built`` starting from the saved frame ``[initial]`` names, and the frame times from
    that frame's time on (the original grid where it lies on it)."""
    assert scene.initial is not None
    t0, frame = saved_frame(scene.initial)
    if t0 >= frames[-1] - 1e-9 * scene.output.frame_interval:
        raise SceneError("simulation.duration", scene.simulation.duration,
                         f"must be later than the saved frame's time {t0:g} s that the run "
                         "starts from (initial.from): duration is the end time")
    contact = built.system.contact

    def bodies_from(saved: dict[str, NDArray[Any]]) -> Any:
        assert contact is not None
        inertia = np.where(contact.bodies.free[:, None, None], contact.bodies.inertia, 0.0)
        return start_motion(saved["body_positions"], saved["body_rotations"],
                            saved["body_velocities"], saved["body_angular_velocities"], inertia)

    state = restarted(built.state, frame, bodies_from, built.system.n_moving > 0,
                      str(scene.initial.from_))
    on_grid = np.abs(frames - t0) <= 1e-9 * scene.output.frame_interval
    later = frames[frames > t0 + 1e-9 * scene.output.frame_interval]
    start = frames[on_grid][:1] if on_grid.any() else np.array([t0])
    return dataclasses.replace(built, state=state), np.concatenate([start, later])


def _static_start(scene: Scene, built: Built) -> Built:
    """``built`` whose static solves start from the positions and rotations of the saved frame
    ``[initial]`` names (its velocities, time and bodies left out: a static run's bodies are
    fixed where the scene puts them)."""
    assert scene.initial is not None
    _, frame = saved_frame(scene.initial)
    threads = {k: v for k, v in frame.items() if not k.startswith("body_")}
    state = restarted(built.state, threads, lambda saved: None, False, str(scene.initial.from_))
    return dataclasses.replace(built, state=dataclasses.replace(state, v=np.zeros_like(state.v)))


def _on_frames(breaks: NDArray[np.float64], frames: NDArray[np.float64],
               scene: Scene) -> NDArray[np.float64]:
    """The times ``breaks`` where a load's factor jumps or kinks (window ends, table rows) after
    the first frame, one within 1e-9 of the frame interval of a frame moved onto it: the
    steppers land on them, so no step straddles one (a pulse gives its impulse exactly)."""
    breaks = breaks[breaks > frames[0]]   # a restart begins at its saved frame's time
    if not len(breaks):
        return breaks
    nearest = frames[np.abs(breaks[:, None] - frames[None, :]).argmin(axis=1)]
    return np.unique(np.where(np.abs(breaks - nearest) <= 1e-9 * scene.output.frame_interval,
                              nearest, breaks))


def _check_supported(system: ThreadSystem, structure: Structure, scene: Scene) -> None:
    """Refuse a static scene that no load can hold: a connected part of the structure without a
    supported position (nor a fixed body it could rest on) moves freely under any load that
    does not balance itself, and so does a part that no support holds along one of x, y, z.
    Parts held by their load alone (a slack cable between two pins, a net hung from a knot, a
    rod whose zero modes the load stiffens) are solved."""
    if any(body.fixed for body in scene.bodies):
        return
    n = structure.n_nodes
    graph = sp.coo_matrix((np.ones(len(structure.segments)), tuple(structure.segments.T)),
                          shape=(n, n))
    count, part = connected_components(graph, directed=False)
    axes = ~system.free[:3 * n].reshape(-1, 3)   # (N, 3) the supported translations
    loose = sorted(set(range(count)) - set(part[axes.any(axis=1)]))
    supports = [s.node for s in scene.supports] or "none"
    if loose:
        node = int(np.flatnonzero(part == loose[0])[0])
        raise SceneError("supports", supports,
                         f"{len(loose)} part(s) of the structure have no node with a supported "
                         f"position (node {node} is in one; supported rotations alone do not "
                         "hold it): no load holds a free part in a static run. Support a "
                         "position in [[supports]] or run it dynamically")
    # a translation along an axis no support of the part holds changes neither the internal
    # forces nor the dead loads: no load holds it either (the part would drift along it)
    for k in range(count):
        free_axes = [name for name, held_axis in zip("xyz", axes[part == k].any(axis=0))
                     if not held_axis]
        if free_axes:
            node = int(np.flatnonzero(part == k)[0])
            along = " and ".join(free_axes)
            raise SceneError("supports", supports,
                             f"the part of the structure with node {node} is free to translate "
                             f"along {along}: none of its supports holds that displacement, and "
                             "no load holds a rigid translation in a static run. Hold it along "
                             f"{along} in [[supports]] (dofs) or run it dynamically")


def _energy_checks(p: Prepared) -> list[FrameCheck]:
    """The energy guard (:func:`~rodnet.io.recorder.energy_guard`) of a dynamic run, whatever
    its integrator, whose energy nothing can raise: every force that does work has a
    potential (:func:`_worked_by`), and the potential then counts. Symplectic Euler's energy
    swings by about ``omega h / 2`` of itself on a resolved mode (a spring at a third of its
    period per step: 0.86 to 1.19 of the start, bounded), so the explicit integrator is allowed
    to double its energy, or to gain as much as it has in motion where forces do work, before
    it is deemed unstable; the others a tenth of that."""
    forces = _worked_by(p.scene)
    if forces is None:
        return []
    return [energy_guard(growth=1.0 if p.scene.integrator == "explicit" else 0.1,
                         potential=bool(forces), forces=forces)]


def _worked_by(scene: Scene) -> str | None:
    """What does work on a dynamic scene, where all of it has a potential that the frames'
    ``potential_energy`` counts (less its ``load_factor_energy``, what the loads' time factors
    changed of it, :func:`rodnet.kernels.schedule.factor_energy`): ``""`` (nothing),
    ``"gravity"``, ``"loads"`` or ``"gravity and loads"``; None for a static scene, or where a
    force without a potential does work (a dead moment)."""
    sim = scene.simulation
    loads = [*scene.loads, *scene.line_loads]
    if sim.type != "dynamic" or any(any(l.moment) for l in scene.loads):
        return None
    return " and ".join(name for name, acts in (("gravity", any(sim.gravity)),
                                                ("loads", bool(loads))) if acts)


# --- the integrators, by name ------------------------------------------------------------

Integrate = Callable[[Prepared, Recorder, Progress, StepStats], StepStats]


FIXED_STEP_ITERATIONS = 1000
"""Newton's iteration limit at fixed implicit steps, where a failed solve ends the run (adaptive
steps and static load steps keep 200 and halve the step instead; adaptive steps of threads with
rotations also give up a long solve whose residual stopped halving):
the backward-Euler step of the pinned Cosserat net at t = 0.728 s, h = 2 ms, converges
linearly and takes 380 iterations (docs/rod_model.md, Limits)."""


def _rotations_creep(p: Prepared) -> bool:
    """Whether the run's Newton solves may creep on rotation nodes of almost no stiffness
    (threads with rotation unknowns, in adaptive dynamic runs; a free body's own rotation does
    not count). There a shorter step converges in fewer iterations, so a solve of at least
    twice ``NEWTON_TARGET`` iterations whose residual has not halved in the last
    ``NEWTON_TARGET`` is given up (the step is taken again at half the size), and a step's
    iterations shrink the next one (:func:`rodnet.integrate.implicit._resize_factor`); see
    docs/rod_model.md, Limits. Elsewhere neither: on the capture of docs/capture.md (lumped
    threads, contact, free target) the first made 12,746 steps and 109,412 iterations of the
    2,227 and 29,004 without it, the second 1,821 steps and 12,180 iterations in the first
    1.5 s against 1,047 and 7,269, its contact steps being no easier when shorter."""
    sim = p.scene.simulation
    return sim.type == "dynamic" and sim.adaptive and len(p.system.model.rotation_dofs()) > 0


def _newton(p: Prepared) -> NewtonOptions:
    """Newton's options for the prepared run ``p``: a fixed step's iteration limit, and the
    progress limit where rotations creep (:func:`_rotations_creep`)."""
    sim = p.scene.simulation
    options = NewtonOptions(rtol=min(sim.rtol, 1e-6) * 1e-2,
                            reuse_factorization=sim.reuse_factorization)
    if sim.type == "dynamic" and not sim.adaptive:
        return dataclasses.replace(options, max_iterations=FIXED_STEP_ITERATIONS,
                                   standing_iterations=None)
    if _rotations_creep(p):
        return dataclasses.replace(options, progress_iterations=NEWTON_TARGET)
    return options


ERROR_FRACTION = 3e-5
"""The default ``simulation.error_tolerance`` as a fraction of the structure's size (the largest
distance between two of its nodes at rest, :attr:`rodnet.topology.Structure.size`): 0.9 mm on
the reference net, 30 um on a 1 m thread. Measured
(validation/benchmarks/results/implicit_defaults.md): the reference deployment's largest mouth
area within 0.35 % of the converged one with cable threads (BDF2), the 1 m thread's tip within
0.42 mm of a run at 1e-7 m; the 1.5 m thread of validation/benchmarks/thread_defaults.py up to
7.8 mm from its converged run over 1 s (results/thread_defaults.md)."""


def error_tolerance(p: Prepared) -> float | None:
    """The local error tolerance of an adaptive implicit run [m]: ``simulation.error_tolerance``,
    or by default :data:`ERROR_FRACTION` of the structure's size; None for fixed steps."""
    sim = p.scene.simulation
    if not sim.adaptive:
        return None
    return sim.error_tolerance if sim.error_tolerance is not None else \
        ERROR_FRACTION * p.system.length_scale


def _implicit(p: Prepared, recorder: Recorder, bar: Progress, stats: StepStats) -> StepStats:
    sim = p.scene.simulation
    cls = SCHEMES[p.scene.integrator]
    extra = {"rho_inf": sim.rho_inf} if "rho_inf" in cls.__dataclass_fields__ else {}
    scheme = cls(p.system, _newton(p), **extra)
    return integrate_implicit(scheme, p.state, p.times, sim.dt, sim.adaptive, recorder, bar,
                              dt_max=sim.dt_max, error_tolerance=error_tolerance(p), stats=stats,
                              restarts=frozenset(float(t) for t in p.jumps),
                              newton_shrinks=_rotations_creep(p))


INTEGRATORS: dict[str, Integrate] = {
    **{name: _implicit for name in SCHEMES},
    "explicit": lambda p, rec, bar, stats: integrate_explicit(p.system, p.state, p.times, rec,
                                                              bar, stats=stats),
    "rk45": lambda p, rec, bar, stats: integrate_rk45(p.system, p.state, p.times,
                                                      p.scene.simulation.rtol, rec, bar,
                                                      stats=stats, breaks=p.breaks),
}
"""``simulation.integrator`` -> how a prepared run is integrated."""


def register_integrator(name: str, integrate: Integrate) -> None:
    """Make ``simulation.integrator = name`` run ``integrate(prepared, recorder, progress,
    stats) -> stats``."""
    INTEGRATORS[name] = integrate
    if name not in config.INTEGRATORS:
        config.INTEGRATORS.append(name)


def _static(p: Prepared, recorder: Recorder, bar: Progress, stats: StepStats) -> StepStats:
    return solve_static(p.system, p.state, p.scene.simulation.load_steps, _newton(p),
                        recorder, stats=stats)


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
    p = prepare(scene)
    n_threads = use_threads(p.system.parallel_work(), threads)
    with ExitStack() as context:   # a stop from here on keeps what was computed and says so
        stop = context.enter_context(_stop_on_signals())
        out = output_directory(directory if directory is not None else scene.output.directory,
                               "output.directory" if directory is None else "-o (output directory)")
        (out / "summary.json").unlink(missing_ok=True)   # an earlier run's: not this one's
        structure = p.structure
        vtk = VtkSeries(out, structure.segments, p.system.surfaces(), thread=structure.thread) \
            if scene.output.vtk else None
        dynamic = scene.simulation.type == "dynamic"
        checks = _energy_checks(p) + [p.system.check_frame]
        recorder = Recorder(_frame_function(p), vtk, checks, skip_first=not dynamic,
                            advice=_stability_advice(p), only={float(t) for t in p.frames})
        bar = Progress(scene.simulation.duration, enabled=progress)
        # what the scene alone decides is said before a run that may take hours, and after it
        for warning in [f"{w} (about {_explicit_steps(p):.3g} steps for simulation.duration = "
                        f"{scene.simulation.duration:g} s)" for w in _viscous_step(p)] + \
                _scene_warnings(p):
            bar.note(f"rodnet: warning: {warning}")
        status, message, stats = "ok", "", StepStats()
        integrate = INTEGRATORS[scene.integrator] if dynamic else _static
        start = time.perf_counter()
        stopped_by = None
        compiling = context.enter_context(compile_timer())
        try:
            stats = integrate(p, stop.checked(recorder), stop.checked(bar), stats)
        except SimulationFailed as exc:
            status, message = "failed", str(exc)
        except KeyboardInterrupt as exc:
            stopped_by = exc.args[0] if isinstance(exc, Terminated) else "SIGINT"
            status = "interrupted"
            message = (f"interrupted by {'SIGTERM' if stopped_by == 'SIGTERM' else 'Ctrl-C (SIGINT)'}"
                       "; the frames computed so far are kept")
        except Exception as exc:   # not the physics (a full disk ...): kept, said, raised again
            status, message = "failed", f"stopped by an error: {type(exc).__name__}: {exc}"
            raise
        finally:
            stop.armed = False
            bar.close()
            wall, compiled = time.perf_counter() - start, compiling()
            arrays = recorder.arrays(structure.n_nodes, len(structure.segments))
            arrays["segments"] = np.asarray(structure.segments)
            arrays["support_nodes"] = supported_nodes(p)
            arrays.update(_inertias(p))
            summary = _summary(p, arrays, stats, status, message, wall, recorder.monitors)
            summary["threads"] = n_threads
            summary["scene"]["output"]["directory"] = str(out)   # -o, where it was given
            summary["compile_time_s"] = compiled
            if stopped_by is not None:
                summary["signal"] = stopped_by
            for key, value in p.system.summary(arrays).items():
                if isinstance(value, dict) and isinstance(summary.get(key), dict):
                    summary[key].update(value)
                else:
                    summary[key] = value
            _contact_peaks(summary["metrics"], stats)
            write_npz(out / "result.npz", arrays)
            write_summary(out / "summary.json", summary)
    result = RunResult(status, message, out, summary, arrays)
    if after is not None:
        after(result)
    return result


CONTACT_PEAKS = ("max_contact_force", "max_contact_count", "max_contact_depth")
"""The contact metrics that the integrators also track over their steps."""


def _contact_peaks(metrics: dict[str, Any], stats: StepStats) -> None:
    """The contact metrics of a run with bodies over every step, not the saved frames only
    (those stay as ``<name>_at_frames``): an impact between two frames had read as no contact
    at all while friction took 271 J of an 11 x 11 net's energy (outside check)."""
    if CONTACT_PEAKS[0] not in metrics:
        return
    for key in CONTACT_PEAKS:
        at_frames = metrics[key]
        metrics[key] = max(at_frames, type(at_frames)(getattr(stats, key)))
        metrics[f"{key}_at_frames"] = at_frames


class Terminated(KeyboardInterrupt):
    """A run stopped by a signal (``args[0]``: its name), so that it keeps every frame."""


class StopRequest:
    """SIGTERM or Ctrl-C (SIGINT) noted by its handler and acted on by :meth:`check` between
    steps: an exception raised by a signal handler inside the calls of the compiled loops can
    leave them broken (measured: segmentation faults after SIGTERM), so the run stops where
    the integrator reports progress or a frame. A second Ctrl-C raises at once where Python
    runs (not inside a compiled explicit frame interval)."""

    def __init__(self) -> None:
        self.signal_name: str | None = None
        self.armed = True

    def note(self, signum: int, frame: Any) -> None:
        if signum == signal.SIGINT and self.signal_name is not None:
            raise KeyboardInterrupt   # asked twice: now
        self.signal_name = signal.Signals(signum).name

    def check(self) -> None:
        """Raise :class:`Terminated` once, after a signal."""
        if self.signal_name is not None and self.armed:
            self.armed = False
            raise Terminated(self.signal_name)

    def checked(self, report: Callable[..., None]) -> Callable[..., None]:
        """``report`` followed by :meth:`check` (the frame or progress is kept first)."""
        def call(*args: Any) -> None:
            report(*args)
            self.check()
        return call


@contextmanager
def _stop_on_signals() -> Iterator[StopRequest]:
    """Within the block SIGTERM and SIGINT are noted in the :class:`StopRequest` given to it
    (SIGINT only where it is not ignored). Only in the main thread, where Python delivers
    signals (elsewhere nothing changes)."""
    request = StopRequest()
    if threading.current_thread() is not threading.main_thread():
        yield request
        return
    previous = {sig: signal.getsignal(sig) for sig in (signal.SIGTERM, signal.SIGINT)}
    signal.signal(signal.SIGTERM, request.note)
    if previous[signal.SIGINT] is not signal.SIG_IGN:
        signal.signal(signal.SIGINT, request.note)
    try:
        yield request
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler)


def _stability_advice(p: Prepared) -> str:
    """What to change when a run turns unstable."""
    if p.scene.simulation.type == "static":
        return ("a static run's frames are its load factors (t = 1 the full load): use more "
                "simulation.load_steps, or check that the structure can carry the load")
    if p.scene.integrator == "rk45":
        return "set a smaller simulation.rtol"
    if p.scene.integrator != "explicit":
        if p.scene.integrator == "midpoint" and p.system.contact is not None:
            return ("use simulation.integrator = 'bdf2': the midpoint rule is not energy-stable "
                    "with contact (docs/contact.md)")
        if p.scene.simulation.adaptive:
            return ("set a smaller simulation.error_tolerance or simulation.dt_max (below the "
                    "period of the fastest motion that matters, such as a contact's)")
        return IMPLICIT_ADVICE
    if p.built.rotary_inertia_scale is not None:
        return ("reduce simulation.explicit_safety; if integrator.max_element_rotation in "
                "summary.json is near 2 pi, use more elements_per_thread")
    return "reduce simulation.explicit_safety (or simulation.dt with adaptive = false)"


def _inertias(p: Prepared) -> dict[str, NDArray[np.float64]]:
    """The masses the run moves: ``node_mass`` (N,) [kg] and, for rod sections,
    ``rotation_node_inertia`` (R, 3) [kg m^2] in each rotation node's material frame (explicit
    runs: as raised by C49), so that momenta can be summed from the frames, and the rotation
    node of each element end ``element_rotation_nodes`` (E, 2); with bodies their
    ``body_mass`` (B,) [kg] and ``body_inertia`` (B, 3, 3) [kg m^2] about the centre of mass in
    body axes (nan for a fixed body without a mass)."""
    out = {"node_mass": np.asarray(p.mass, dtype=float)}
    inertia = getattr(p.model, "rotary_inertia", None)
    if inertia is not None and len(inertia):
        out["rotation_node_inertia"] = np.asarray(inertia, dtype=float)
        # which rows of the rotation-node arrays each element's ends take (their order is not
        # the nodes': a pinned knot has one per thread end, a corner mass follows its thread)
        out["element_rotation_nodes"] = np.asarray(p.model.rot_nodes, dtype=np.int64)
    contact = p.system.contact
    if contact is not None:
        out["body_mass"] = np.asarray(contact.bodies.mass, dtype=float)
        out["body_inertia"] = np.asarray(contact.bodies.inertia, dtype=float)
    return out


def supported_nodes(p: Prepared) -> NDArray[np.int64]:
    """(S,) the nodes that ``[[supports]]`` hold, each once, in the order of the entries."""
    nodes = [p.structure.node(s.node, f"supports[{i}].node")
             for i, s in enumerate(p.scene.supports)]
    return np.array(list(dict.fromkeys(nodes)), dtype=np.int64)


def _frame_function(p: Prepared) -> Callable[[float, State], dict[str, Any]]:
    """The system's frame with ``support_reactions`` (S, 3) [N], the supports' forces on the
    nodes of :func:`supported_nodes`. A static frame's time is its load factor."""
    nodes = supported_nodes(p)
    static = p.scene.simulation.type == "static"

    def frame_of(t: float, state: State) -> dict[str, Any]:
        frame = p.system.frame(STATIC_TIME if static else t, state)
        if static:   # the loads and gravity at the frame's load factor
            frame["potential_energy"] *= t
        v = np.zeros_like(state.v) if static else state.v
        frame["support_reactions"] = p.system.support_reactions(
            state.q, v, STATIC_TIME if static else t, t if static else 1.0, nodes) \
            if len(nodes) else np.zeros((0, 3))
        return frame

    return frame_of


def compile_frames(scene: Scene) -> None:
    """Compute ``scene``'s first frame and throw it away: compiles (and caches) the kernels of
    a run's frames without stepping. ``rodnet demo`` does this in a second process while its
    first run compiles the explicit loop, which the integrator compiles before the first frame
    (:func:`rodnet.tools.precompile.warm_up`)."""
    p = prepare(scene)
    _frame_function(p)(float(p.times[0]), p.state)


def _closed_rods(p: Prepared) -> list[str]:
    """A warning for every ``[[rods]]`` entry whose last point lies on its first (within 1e-6 of
    its length): its two end nodes are not joined, so a ring or frame posed that way is open
    there (an outside check's ring opened by 36 mm under 0.01 N where the closed ring moves
    1.5 mm)."""
    out = []
    for i, rod in enumerate(p.scene.rods):
        points = np.asarray(rod.points, dtype=float)
        length = float(np.linalg.norm(np.diff(points, axis=0), axis=1).sum())
        if len(points) > 2 and np.linalg.norm(points[-1] - points[0]) <= 1e-6 * length:
            out.append(f"rods[{i}].points ends where it starts, but a rod is never closed: its "
                       "first and last nodes are separate nodes, so the ring or frame is cut "
                       "there (as a split ring); closed rods, and joints between nodes, cannot "
                       "be posed in this version")
    return out


def _without_effect(p: Prepared) -> list[str]:
    """A warning for keys the scene sets to no effect: ``fix`` beside ``dofs``, ``[contact]``
    without bodies, a load that starts at or after the run's end (dynamic runs),
    ``rotation_center`` without ``angular_velocity``, the inertia of a fixed body."""
    scene, out = p.scene, []
    for i, support in enumerate(scene.supports):
        if support.fix is not None and support.dofs is not None:
            out.append(f"supports[{i}].fix = '{support.fix}' has no effect: dofs = "
                       f"{list(support.dofs)} is the whole set of DOFs the support holds")
    if scene.contact is not None and not scene.bodies:
        out.append("[contact] has no effect: the scene has no [[bodies]] (threads do not "
                   "touch each other)")
    if scene.simulation.type == "dynamic":
        end = scene.simulation.duration
        for kind, entries in (("loads", scene.loads), ("line_loads", scene.line_loads)):
            for i, load in enumerate(entries):
                if load.start >= end:
                    out.append(f"{kind}[{i}].start = {load.start:g} s is not before "
                               f"simulation.duration = {end:g} s: the load never acts")
    for i, rod in enumerate(scene.rods):
        if rod.rotation_center is not None and not any(rod.angular_velocity):
            out.append(f"rods[{i}].rotation_center has no effect without "
                       f"rods[{i}].angular_velocity")
    for i, body in enumerate(scene.bodies):
        if body.fixed and body.inertia is not None:
            out.append(f"bodies[{i}].inertia has no effect: the body is fixed (a fixed body "
                       "never moves; its mass is only reported)")
    return out


def _shared_supports(p: Prepared) -> list[str]:
    """A warning for every node that more than one ``[[supports]]`` entry holds: their fixed
    DOFs are combined, which may not be what was meant (a pin and a clamp on one node make a
    clamp)."""
    holders: dict[int, list[int]] = {}
    for i, support in enumerate(p.scene.supports):
        holders.setdefault(p.structure.node(support.node, f"supports[{i}].node"), []).append(i)
    out = []
    for node, entries in holders.items():
        if len(entries) > 1:
            names = [f"supports[{i}]" for i in entries]
            out.append(f"{', '.join(names[:-1])} and {names[-1]} hold the same node {node}: the "
                       "DOFs they fix are combined")
    return out


def _loads_on_supports(p: Prepared) -> list[str]:
    """A warning for every ``[[loads]]`` entry whose node its supports hold along every
    direction the load acts in (a force's nonzero global components, the rotations ``r1, r2,
    r3`` of the node's material axes at the start that a moment turns): the supports take the
    whole load and the structure does not feel it."""
    held: dict[int, set[str]] = {}
    for i, support in enumerate(p.scene.supports):
        node = p.structure.node(support.node, f"supports[{i}].node")
        held.setdefault(node, set()).update(support.fixed)
    # the moments in the material axes (the scene's loads come first among the model's)
    body = p.model.load_moments(p.start_quat) if hasattr(p.model, "load_moments") else None
    out = []
    for i, load in enumerate(p.scene.loads):
        node = p.structure.node(load.node, f"loads[{i}].node")
        acting = {axis for axis, c in zip(("x", "y", "z"), load.force) if c != 0.0}
        if any(c != 0.0 for c in load.moment):
            turned = np.abs(body[i]) > 1e-9 * np.abs(body[i]).max() if body is not None \
                else np.ones(3, bool)
            acting |= {f"r{k + 1}" for k in range(3) if turned[k]}
        if acting and acting <= held.get(node, set()):
            out.append(f"loads[{i}] acts on node {node} ('{load.node}'), which supports hold in "
                       f"every direction the load acts in ({', '.join(sorted(acting))}): the "
                       "supports take it and the structure does not feel it")
    return out


def _has_implicit(p: Prepared) -> bool:
    """Whether the scene's model runs with an implicit integrator (Kirchhoff threads do not)."""
    return any(i in SCHEMES for i in MODELS[p.built.variant].supports.integrators)


VISCOUS_STEP_FACTOR = 2.0
"""An explicit stability limit this many times shorter with the threads' damping than without
it is said in the warnings (S10: strong Kelvin-Voigt damping shortens the limit as 1 / zeta)."""


def _viscous_step(p: Prepared) -> list[str]:
    """The warning of an explicit run whose step the threads' viscosity shortens by more than
    :data:`VISCOUS_STEP_FACTOR` (a draped cable with viscosity 1e6 Pa s took 35.6 million
    steps; a steel cantilever of Cosserat rods at a damping ratio of 0.02 in torsion 18 times
    the undamped steps)."""
    control = p.system.control
    if p.scene.integrator != "explicit" or control is None:
        return []
    damped, free = control.stable_step, control.undamped_step
    if not (np.isfinite(free) and free > VISCOUS_STEP_FACTOR * damped):
        return []
    implicit = _has_implicit(p)
    return [f"the explicit stability limit is {damped:.3g} s, {free / damped:.3g} times shorter "
            f"than the {free:.3g} s it would be without the threads' Kelvin-Voigt damping "
            "(S10, C48): materials.viscosity sets the step; a smaller viscosity"
            + (", or an implicit integrator," if implicit else "") + " takes fewer steps"]


def _explicit_steps(p: Prepared) -> float:
    """The steps of an explicit run: at ``explicit_safety`` times its stability limit, or at
    ``dt`` with ``adaptive = false``."""
    sim, control = p.scene.simulation, p.system.control
    assert control is not None
    return sim.duration / (control.stable_step * sim.explicit_safety if sim.adaptive else sim.dt)


def _unforced_energy(p: Prepared, arrays: dict[str, NDArray[Any]]
                     ) -> tuple[NDArray[Any], NDArray[Any], str] | None:
    """The saved frames' energy (:func:`rodnet.io.recorder.mechanical_energy`, with the
    potential of what does work) (F,), its part in motion (F,) and what does work
    (:func:`_worked_by`), for a dynamic run on which only forces with a potential do work;
    None otherwise, or with fewer than two frames."""
    forces = _worked_by(p.scene)
    if forces is None or "kinetic_energy" not in arrays or len(arrays["time"]) < 2:
        return None
    energy, motion = mechanical_energy(arrays, bool(forces))
    return energy, motion, forces


ENERGY_RISE = 0.05
"""A dynamic run whose energy, which nothing raises, rose by more than this fraction warns
(of its start, or under gravity of the largest energy in motion; undamped threads snapping at
the default step: +45 % on a 5 x 5 net)."""


def _energy_rise(p: Prepared, arrays: dict[str, NDArray[Any]]) -> list[str]:
    """The warning of a dynamic run whose energy (:func:`rodnet.io.recorder.mechanical_energy`)
    rose by more than :data:`ENERGY_RISE` although nothing but forces with a potential do work
    on it (:func:`_worked_by`): the energy guard allows symplectic Euler's swing up to 100 %,
    which undamped snaps reach only at the stability limit, while at the default step they
    already gain tens of percent (and a light rope pressed on a drum by its weight grows without
    bound); the implicit schemes' guard 10 %, below which the midpoint rule in contact can gain
    a few percent."""
    scene, sim = p.scene, p.scene.simulation
    unforced = _unforced_energy(p, arrays)
    if unforced is None:
        return []
    energy, motion, forces = unforced
    gain = energy_gain(energy, energy[0])
    if forces:
        shares = gain / np.maximum(np.maximum.accumulate(motion), np.finfo(float).tiny)
        worst = int(np.argmax(shares))
        rise = float(shares[worst])
    else:
        rise = float(gain.max() / energy[0]) if energy[0] > 0.0 else 0.0
    if not rise > ENERGY_RISE:
        return []
    measure = (f"the energy, the potential of {forces} included, rose by "
               + _share(rise, float(gain[worst]))) if forces else \
        f"the kinetic and elastic energy rose by {100.0 * rise:.3g} %"
    measure += " over the saved frames"   # a failed run's message tells the step's own figure
    told = f"{measure} although nothing does work on the structure" + \
        (f" but {forces}" if forces else "")
    if scene.integrator != "explicit":
        return [f"{told}: simulation.integrator = "
                f"'{scene.integrator}' is not energy-stable where its steps leave fast events "
                "unresolved (the midpoint rule in contact: a thread bouncing on a box at a fixed "
                "1.5 ms +6.7 %); use 'bdf2' or shorter steps (simulation.dt, dt_max or "
                "error_tolerance)"]
    step = f"simulation.explicit_safety = {sim.explicit_safety:g}" if sim.adaptive else \
        f"simulation.dt = {sim.dt:g} s with adaptive = false"
    smaller = "a smaller explicit_safety" if sim.adaptive else "a smaller simulation.dt"
    return [f"{told}: the explicit step ({step}) is long for the fastest "
            "motion: symplectic Euler takes a snap's or contact's force at the start of the "
            "step, and without damping nothing takes the gain away, and on a smooth vibration "
            "its energy swings by about omega dt / 2 of itself and comes back (undamped nets: within 0.4 % "
            "at explicit_safety = 0.25, a 5 x 5 net hitting a free box 1.2 %); use "
            f"{smaller}, materials.viscosity > 0"
            + (", contact.damping > 0" if scene.bodies else "") + _energy_stable_choice(p)]


def _share(fraction: float, joules: float) -> str:
    """An energy change of ``joules`` [J], ``fraction`` of the largest energy in motion at a
    saved frame, in words; above 1 the motion that made it fell between the frames (a thread
    pressed onto a box by a load: 1.16e+05 % of the frames' energy in motion, outside check)."""
    if fraction <= 1.0:
        return f"{100.0 * fraction:.3g} % of the largest energy in motion"
    return (f"{joules:.3g} J, {fraction:.3g} times the largest energy in motion at a saved "
            "frame (the motion that made the change fell between the frames)")


ENERGY_LOSS = 0.05
"""A dynamic run under a dissipative implicit scheme whose energy fell by more than this fraction
(of its start, or under gravity of the largest energy in motion) in a scene where nothing
dissipates warns."""

DISSIPATIVE_SCHEMES = ("bdf2", "generalized-alpha", "backward-euler")
"""The implicit integrators with numerical damping."""


def _energy_loss(p: Prepared, arrays: dict[str, NDArray[Any]]) -> list[str]:
    """The warning of a run whose energy fell by more than :data:`ENERGY_LOSS` under a
    :data:`DISSIPATIVE_SCHEMES` integrator where nothing in the scene dissipates (no viscosity,
    no contact damping or friction) and nothing but forces with a potential do work
    (:func:`_worked_by`): what the scheme's numerical damping took at snaps and contacts its
    steps do not resolve (an outside check: a rod hitting a free sphere head-on lost 24 % of its
    energy under BDF2 at default steps, its exit velocity 5.7 % low; 0.2 % at a fixed 2.5e-6 s;
    without a word)."""
    scene = p.scene
    law = None if p.system.contact is None else p.system.contact.bodies.law
    dissipates = any(m.viscosity > 0.0 for m in scene.materials) or (
        law is not None and (law.damping > 0.0 or law.friction > 0.0))
    unforced = _unforced_energy(p, arrays)
    if scene.integrator not in DISSIPATIVE_SCHEMES or dissipates or unforced is None:
        return []
    energy, motion, forces = unforced
    scale = float(np.max(motion)) if forces else float(energy[0])
    loss = float(energy[0] - energy[-1]) / scale if scale > 0.0 else 0.0
    if not loss > ENERGY_LOSS:
        return []
    keeps = "'explicit' keeps" if scene.bodies else "'midpoint' and 'explicit' keep"
    return [f"the energy fell by "
            + (_share(loss, float(energy[0] - energy[-1])) + " " if forces else
               f"{100.0 * loss:.3g} % ")
            + "although nothing in the scene dissipates it (no materials.viscosity"
            + (", contact.damping or contact.friction" if scene.bodies else "")
            + f"): simulation.integrator = '{scene.integrator}' damps what its steps resolve "
            "coarsely (vibrations of few steps per period, threads snapping taut, contacts); "
            f"{keeps} the energy, or resolve that motion with a smaller simulation.dt_max or "
            "error_tolerance (or dt with adaptive = false)"]


def _energy_stable_choice(p: Prepared) -> str:
    """The advice's last item: the implicit integrator that keeps the energy, where the model has
    one (Kirchhoff threads have none): the midpoint rule, or BDF2 with bodies (the midpoint
    rule is not energy-stable in contact)."""
    if not _has_implicit(p):
        return ""
    return ", or simulation.integrator = \"bdf2\"" if p.scene.bodies else ", or the midpoint rule"


def _raised_inertia(p: Prepared) -> float | None:
    """The explicit integrator's largest raise of the rotary inertia (C49), None where it raised
    nothing beyond round-off (1 + 3e-14 where the step needs no raise) or does not apply."""
    scale = p.built.rotary_inertia_scale
    if p.scene.integrator != "explicit" or scale is None or not scale > 1.0 + 1e-9:
        return None
    return scale


def _sunk(p: Prepared, arrays: dict[str, NDArray[Any]], stats: StepStats) -> list[str]:
    """A warning where a thread's centreline sank into a body at a saved frame or, between the
    frames, at a step (the contact's penalty stiffness too soft for the loads: a 1 km thread of
    1 m radius sank 6 m into a box under the default 1e5 N/m, outside check)."""
    depth = arrays.get("contact_depth")
    if depth is None or not len(depth):
        return []
    k = int(np.argmax(depth))
    if float(depth[k]) > 1.0:
        when = (f"{float(depth[k]):.3g} thread radii into a body at t = "
                f"{float(arrays['time'][k]):.6g} s")
    elif stats.max_contact_depth > 1.0:
        when = (f"{stats.max_contact_depth:.3g} thread radii into a body between the saved "
                f"frames (at most {float(depth[k]):.3g} at a frame)")
    else:
        return []
    stiffness = p.system.contact.bodies.law.stiffness   # type: ignore[union-attr]
    return [f"a thread's surface sank {when} (its centreline inside the body): contact.stiffness "
            f"= {stiffness:g} N/m lets it in (a steady load W sinks W / stiffness, a point of "
            "mass m hitting at speed v about v sqrt(m / stiffness)); raise it where the depth "
            "matters, with the steps that a stiffer contact needs"]


def _scene_warnings(p: Prepared) -> list[str]:
    """The warnings that the scene alone decides, known before the run (:func:`run` says them
    at the start too): a clamp on threads without rotations, nodes held or loaded on their
    supports, keys set to no effect, closed rods, moments or spins on sections whose explicit
    rotary inertia is raised, the midpoint rule with bodies, rigid knots with one element per
    thread, a fixed step longer than the frame interval."""
    out: list[str] = []
    clamps = [i for i, support in enumerate(p.scene.supports)
              if support.clamped]
    if clamps and not len(p.model.rotation_dofs()):
        label = MODELS[p.built.variant].label
        named = f"supports[{clamps[0]}].fix = 'clamp' holds" if len(clamps) == 1 else \
            f"supports[{', '.join(str(i) for i in clamps)}].fix = 'clamp' each hold"
        out.append(f"{named} only the node's position, as fix = 'pin' "
                   f"does (no rotations in {label}: the thread turns freely about the node, "
                   "carrying no bending moment); use model.type = 'cosserat' with bending for a "
                   "clamped rod")
    out += _shared_supports(p) + _loads_on_supports(p) + _without_effect(p) + _closed_rods(p)
    scale = _raised_inertia(p)
    turned = [f"loads[{i}].moment" for i, load in enumerate(p.scene.loads) if any(load.moment)] + \
        [f"rods[{i}].angular_velocity" for i, rod in enumerate(p.scene.rods)
         if any(rod.angular_velocity)]
    if scale is not None and turned:
        out.append(f"{turned[0]} turns sections whose rotary inertia the explicit integrator "
                   f"raised up to {scale:.3g} times (simulation.rotary_inertia_scaling): their own "
                   "turning is slowed, so torsion modes come out slow (a steel shaft's first "
                   "-69 % at 21 times), a spin about a thread's axis is lost and the response to "
                   "a suddenly applied moment is off (6 % of a rod's motion); set "
                   "simulation.rotary_inertia_scaling = false, or use an implicit integrator "
                   "with dt_max below the torsion period")
    if p.system.contact is not None:
        bodies = p.system.contact.bodies
        for a, b in bodies.overlaps:
            out.append(f"bodies[{a}] ({bodies.names[a]!r}) and bodies[{b}] ({bodies.names[b]!r}) "
                       "overlap at the start: bodies do not touch each other "
                       "(docs/contact.md), so a free one moves through the other as if it were "
                       "not there; move them apart (fixed bodies may overlap to build one "
                       "obstacle)")
    if p.scene.integrator == "midpoint" and p.system.contact is not None:
        out.append("simulation.integrator = 'midpoint' with [[bodies]]: the midpoint rule is not "
                   "energy-stable in contact (a penalty force that switches on within a step "
                   "can add energy: a thread thrown at a free box gained 7.9 %); use 'bdf2' "
                   "for captures (docs/contact.md)")
    model = p.scene.model
    if p.built.variant == "rods" and p.structure.net is not None and model.knots == "rigid" \
            and model.elements_per_thread == 1:
        out.append("model.knots = 'rigid' with model.elements_per_thread = 1: a thread between "
                   "two rigid knots bends only through its one element's shear (shear locking), "
                   "so the net resists any change of its mesh angles far too stiffly (a 5 x 5 "
                   "net sagging under gravity: 0.063 m instead of 0.284 m); use "
                   "elements_per_thread >= 2 or knots = 'pinned'")
    sim, interval = p.scene.simulation, p.scene.output.frame_interval
    if sim.type == "dynamic" and not sim.adaptive and sim.dt > interval * (1.0 + 1e-9):
        out.append(f"simulation.dt = {sim.dt:g} s is longer than output.frame_interval = "
                   f"{interval:g} s: the steps were cut to land on every frame, so the run "
                   f"stepped at {interval:g} s")
    return out


def _warnings(p: Prepared, stats: StepStats, monitors: dict[str, float],
              arrays: dict[str, NDArray[Any]]) -> list[str]:
    """What the user should know about a completed or failed run: a clamp on threads without
    rotations (it holds the node's position only, as a pin does: such threads pass no moment);
    a static equilibrium that is unstable (:func:`rodnet.integrate.static.unstable`);
    a rod element turned past the rotation stop (C52), where the stop's moment, not the
    section, resisted its rotation; a node held by more than one support entry; a load that
    its node's supports take whole; a net of rigid knots with one element per thread (shear
    locking); keys set to no effect; rod elements turned inside out (C51); the midpoint rule
    with contact; moments or spins on sections whose explicit rotary inertia was raised; an
    explicit run whose energy rose (:func:`_energy_rise`); a fixed step longer than the frame
    interval; an explicit step that the threads' Kelvin-Voigt damping shortens more than
    :data:`VISCOUS_STEP_FACTOR` times. ``monitors``: :data:`rodnet.io.recorder.MONITORS` over
    the saved frames ``arrays``."""
    out = _viscous_step(p) + _energy_rise(p, arrays) + _energy_loss(p, arrays) + \
        _scene_warnings(p) + _sunk(p, arrays, stats)
    frames = len(arrays["time"])
    scale = _raised_inertia(p)
    if "jump_from" in stats.extra:
        e = stats.extra
        out.append(f"between load factors {e['jump_from']:.4g} and {e['jump_to']:.4g} the "
                   f"equilibrium jumped (a node moved {e['jump_move']:.3g} m in one load step, "
                   + ("far more than the linear response at the unloaded state says"
                      if e["jump_from"] == 0.0 else "far more per load than before")
                   + "): the load passed a limit point (a "
                   "snap-through) or a bifurcation (buckling), and the states from there on are "
                   "on another branch of equilibria; the path between them was not followed"
                   + (f" (it jumped again {e['jumps_later']:.0f} time(s), the last between "
                      f"{e['last_jump_from']:.4g} and {e['last_jump_to']:.4g})"
                      if e.get("jumps_later") else ""))
    if stats.extra.get("unstable"):
        out.append("the static equilibrium found is unstable: its tangent stiffness has a "
                   "negative eigenvalue (a link or column in compression that would buckle, a "
                   "chain folded on itself), so a nearby state of lower energy exists; more "
                   "simulation.load_steps, or a dynamic run with damping, can reach a stable one")
    inside_out = int(monitors.get("inside_out_elements", 0))
    if inside_out and p.scene.simulation.type == "static":
        out.append(f"{inside_out} rod element(s) turned inside out (the chord against the "
                   "section's axis, FORMULATION.md C51): a compressive load folded them through "
                   "themselves, held only by the regularising spring of 0.01 EA"
                   + (" of the tension-only law, which carries no compression; a column or beam "
                      "needs model.axial = 'linear'" if p.scene.model.axial == "tension-only"
                      else "; the load exceeds what the rod can carry in compression"))
    elif monitors.get("inside_out_elements_last", 0.0) > 0.0 or \
            monitors.get("inside_out_elements_frames", 0.0) > 0.1 * max(frames, 1):
        # a passing inversion (the reference deployment: at 5 of 301 frames, 4.7 N) is not told
        scaled = scale is not None
        # still folded at the end: a slack chord that turned over past its section (two masses
        # passing each other on a slack thread) is short only while it turns
        folded = int(monitors.get("folded_elements_last", 0))
        said = (f"up to {inside_out} rod element(s) were inside out at saved frames (the chord "
                "against the section's axis, FORMULATION.md C51)")
        if folded and p.scene.model.axial == "tension-only":
            # pushed through themselves: more elements or shorter steps would not help
            out.append(said + f", {folded} of them shorter than a tenth of their rest length at "
                       "the last frame: "
                       "compression pushed them through themselves, which the tension-only law "
                       "does not resist (only the regularising spring of 0.01 EA holds them); a "
                       "rod that must push (a column, a rod driven from behind) needs "
                       "model.axial = 'linear'")
        else:
            out.append(said + ": their sections did not turn with their chords, and the "
                       "regularising spring of 0.01 EA pulled on chords shorter than their rest "
                       "length, where a thread is slack"
                       + ("; the explicit integrator's raised rotary inertia (factor "
                          f"{scale:.3g}) slows the sections: use an implicit "
                          "integrator or simulation.rotary_inertia_scaling = false"
                          if scaled else "; use more elements (model.elements_per_thread, or "
                          "rods.elements) or shorter steps"))
    phi = max(stats.max_element_rotation or 0.0, monitors.get("max_element_rotation", 0.0))
    if phi <= ROTATION_STOP:
        return out
    return out + [f"a rod element turned by {phi:.4f} rad between its end triads, "
            f"{phi - ROTATION_STOP:.2g} rad past the rotation stop at {ROTATION_STOP:g} rad "
            "(FORMULATION.md C52): there the stop's stiffness, not the section's, resisted it, "
            "so the rod bends or twists more sharply than its elements resolve; use more "
            "elements (model.elements_per_thread, or rods.elements)"]


def _summary(p: Prepared, arrays: dict[str, NDArray[Any]], stats: StepStats, status: str,
             message: str, wall: float, monitors: dict[str, float] | None = None
             ) -> dict[str, Any]:
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
    control = p.system.control
    return {
        "status": status, "message": message, "wall_time_s": wall,
        "steps": stats.steps, "newton_iterations": stats.newton_iterations,
        "factorizations": stats.factorizations, "rejected_steps": stats.rejected_steps,
        "retaken_steps": stats.retaken_steps,
        "function_evaluations": stats.function_evaluations,
        "frames": len(arrays["time"]), "simulated_time_s": float(arrays["time"][-1]) if len(arrays["time"]) else 0.0,
        "integrator": {"name": p.scene.integrator,
                       "dt": control.dt if control is not None else None,
                       "dt_near_bodies": (control.near_dt if control is not None
                                          and p.system.contact is not None else None),
                       "dt_min": stats.dt_min if stats.steps else None, "dt_max": stats.dt_max or None,
                       "stable_step": p.built.stable_step,
                       "rotary_inertia_scale": p.built.rotary_inertia_scale,
                       "max_element_rotation": stats.max_element_rotation},
        "model": {"type": p.scene.model.type, "nodes": structure.n_nodes,
                  "elements": len(structure.segments), "dofs": p.system.n_dof},
        "nodes": structure.selectors, "metrics": metrics,
        "warnings": _warnings(p, stats, monitors or {}, arrays),
        "scene": scene_as_dict(p.scene, unused_keys(p.scene)),
    }
