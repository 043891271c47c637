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
from rodnet.errors import SceneError, SimulationFailed
from rodnet.integrate.frames import StepStats, frame_times
from rodnet.io.results import scene_as_dict, write_npz, write_summary
from rodnet.io.vtk import VtkSeries
from rodnet.metrics import distance, mouth_area, net_metrics
from rodnet.progress import Progress
from rodnet.reference.lumped import LumpedModel, build_lumped
from rodnet.topology import build_structure

IMPLICIT = ("generalized-alpha", "backward-euler")


@dataclass(frozen=True)
class Prepared:
    """A scene turned into a model, an initial state and a stepping plan, ready to run."""

    scene: Scene
    model: LumpedModel
    x0: NDArray[np.float64]
    v0: NDArray[np.float64]
    times: NDArray[np.float64]
    dt: float


def prepare(scene: Scene) -> Prepared:
    """Build the model and check the stepping plan; raises :class:`SceneError` on bad input."""
    sim = scene.simulation
    if scene.model.type != "lumped":
        raise SceneError("model.type", scene.model.type,
                         "this version of rodnet runs the lumped reference model only: use 'lumped'")
    if sim.type == "static":
        raise SceneError("simulation.type", sim.type,
                         "static runs need the implicit solver, not available in this version: use 'dynamic'")
    if scene.integrator in IMPLICIT:
        raise SceneError("simulation.integrator", scene.integrator,
                         "the lumped model runs with 'explicit' or 'rk45' in this version")
    structure = build_structure(scene)
    model = build_lumped(scene, structure)
    v0 = structure.velocities.copy()
    v0[model.inv_mass == 0.0] = 0.0
    dt = sim.dt
    if scene.integrator == "explicit":
        limit = model.stable_step()
        if sim.adaptive:
            dt = sim.explicit_safety * limit
        elif dt > limit:
            raise SceneError("simulation.dt", dt, f"exceeds the explicit stability limit "
                             f"{limit:.3g} s of this scene; use dt <= {limit:.3g} "
                             f"(about half of it for accurate snap loads) or adaptive = true")
    times = frame_times(sim.duration, scene.output.frame_interval)
    return Prepared(scene, model, structure.positions.copy(), v0, times, dt)


@dataclass
class Recorder:
    """Keeps every frame in memory and streams it to VTK when asked."""

    model: LumpedModel
    vtk: VtkSeries | None
    time: list[float] = field(default_factory=list)
    positions: list[NDArray[np.float64]] = field(default_factory=list)
    velocities: list[NDArray[np.float64]] = field(default_factory=list)
    tension: list[NDArray[np.float64]] = field(default_factory=list)

    def __call__(self, t: float, x: NDArray[np.float64], v: NDArray[np.float64]) -> None:
        tension = self.model.tension(x, v)
        self.time.append(t)
        self.positions.append(np.array(x))
        self.velocities.append(np.array(v))
        self.tension.append(tension)
        if self.vtk is not None:
            self.vtk.write(t, x, v, tension)

    def arrays(self) -> dict[str, NDArray[Any]]:
        """``time`` (F,), ``positions`` and ``velocities`` (F, N, 3), ``tension`` (F, E),
        ``segments`` (E, 2) node pairs."""
        n, e = self.model.structure.n_nodes, len(self.model.segments)
        return {"time": np.array(self.time),
                "positions": np.array(self.positions).reshape(-1, n, 3),
                "velocities": np.array(self.velocities).reshape(-1, n, 3),
                "tension": np.array(self.tension).reshape(-1, e),
                "segments": np.asarray(self.model.segments)}


@dataclass(frozen=True)
class RunResult:
    """What a run produced: its status, where it wrote, the summary and the arrays."""

    status: str
    message: str
    directory: Path
    summary: dict[str, Any]
    arrays: dict[str, NDArray[Any]]


def run(scene: Scene, directory: str | Path | None = None, *, progress: bool | None = None,
        after: Callable[[RunResult], None] | None = None) -> RunResult:
    """Run ``scene`` and write its results to ``directory`` (default: ``output.directory``).

    Parameters
    ----------
    progress : bool, optional
        Show the progress line; default: only when standard error is a terminal.
    after : callable, optional
        Called with the result once the files are written (pictures, plots).
    """
    prepared = prepare(scene)
    out = Path(directory if directory is not None else scene.output.directory)
    out.mkdir(parents=True, exist_ok=True)
    vtk = VtkSeries(out, prepared.model.segments) if scene.output.vtk else None
    recorder = Recorder(prepared.model, vtk)
    bar = Progress(scene.simulation.duration, enabled=progress)
    status, message, stats = "ok", "", StepStats()
    start = time.perf_counter()
    try:
        stats = _integrate(prepared, recorder, bar, stats)
    except SimulationFailed as exc:
        status, message = "failed", str(exc)
    except KeyboardInterrupt:
        status, message = "failed", "interrupted by the user; the frames computed so far are kept"
    finally:
        bar.close()
        wall = time.perf_counter() - start
        arrays = recorder.arrays()
        summary = _summary(prepared, arrays, stats, status, message, wall)
        write_npz(out / "result.npz", arrays)
        write_summary(out / "summary.json", summary)
    result = RunResult(status, message, out, summary, arrays)
    if after is not None:
        after(result)
    return result


def _integrate(p: Prepared, recorder: Recorder, bar: Progress, stats: StepStats) -> StepStats:
    if p.scene.integrator == "rk45":
        from rodnet.integrate.rk45 import integrate_rk45

        return integrate_rk45(p.model, p.x0, p.v0, p.times, p.scene.simulation.rtol, recorder, bar)
    from rodnet.integrate.explicit import integrate_explicit

    return integrate_explicit(p.model, p.x0, p.v0, p.times, p.dt, recorder, bar)


def _summary(p: Prepared, arrays: dict[str, NDArray[Any]], stats: StepStats, status: str,
             message: str, wall: float) -> dict[str, Any]:
    structure = p.model.structure
    metrics: dict[str, float] = {}
    if len(arrays["time"]):
        metrics["max_tension"] = max(stats.max_tension, float(arrays["tension"].max(initial=0.0)))
        metrics["max_tension_at_frames"] = float(arrays["tension"].max(initial=0.0))
    if structure.net is not None and len(arrays["time"]):
        area = mouth_area(arrays["positions"], structure.net)
        dist = distance(arrays["positions"], p.model.mass, structure.net)
        arrays["mouth_area"], arrays["distance"] = area, dist
        metrics.update(net_metrics(arrays["time"], area, dist))
    return {
        "status": status, "message": message, "wall_time_s": wall,
        "steps": stats.steps, "newton_iterations": stats.newton_iterations,
        "factorizations": stats.factorizations, "rejected_steps": stats.rejected_steps,
        "function_evaluations": stats.function_evaluations,
        "frames": len(arrays["time"]), "simulated_time_s": float(arrays["time"][-1]) if len(arrays["time"]) else 0.0,
        "integrator": {"name": p.scene.integrator, "dt": p.dt if p.scene.integrator == "explicit" else None,
                       "dt_min": stats.dt_min if stats.steps else None, "dt_max": stats.dt_max or None,
                       "stable_step": p.model.stable_step()},
        "model": {"type": p.scene.model.type, "nodes": structure.n_nodes,
                  "elements": len(structure.segments), "dofs": 3 * structure.n_nodes},
        "nodes": structure.selectors, "metrics": metrics, "scene": scene_as_dict(p.scene),
    }
