"""``rodnet bench``: the work-precision study of the reference deployment.

Every run is the built-in reference deployment (``rodnet demo``) with a few ``--set``-style
overrides, executed in its own process so that its peak memory is its own. A run records its
wall time, steps, Newton iterations, factorisations and peak memory, and the deployment measures
of :mod:`rodnet.metrics`. Errors are taken against the reference run of the run's *family*
(runs that model the same physics: threads without bending, threads with bending): the finest
run of that family, named in the table.

Error measures (all against the family's reference):

- ``max_mouth_area``: relative error of the largest mouth area;
- ``time_of_max``: absolute error [s] of its time;
- ``distance_at_max``: absolute error [m] of the distance travelled at that time;
- ``com_path``: largest difference [m] of the net's centre-of-mass distance over all frames.

Below the table: the observed order of the largest mouth area in elements per thread and in
the setting (where it is monotone), what a launch 1e-9 faster or slower changes (sensitivity
runs, :func:`perturbed`: the floor below which two runs cannot be told apart), the observed
orders of the largest mouth area and of its time taken between the saved frames
(:func:`peak_orders`), and those of the mouth-area and centre-of-mass histories up to a few
times and over the whole run (:func:`history_orders`), differences at or below the floor
starred.

``rodnet bench --defaults`` (:func:`defaults_study`) runs instead every model at its default
settings beside explicit runs on the full reference deployment, with wall times as multiples of
the lumped explicit default.

Outputs in the chosen folder: ``work_precision.md`` (Markdown table), ``work_precision.csv``,
``work_precision.png`` (wall time against the max-mouth-area error, one curve per model) and
``runs/<label>.json`` with every run's summary (a rerun skips runs already there, so an
interrupted study loses nothing).
"""

from __future__ import annotations

import csv
import json
import math
import re
import signal
import subprocess
import sys
import tempfile
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

CHILD = r"""
import json, resource, sys, time
start = time.perf_counter()
import numpy as np
from rodnet.data import reference_scene_text as demo_scene_text
from rodnet.run import run
from rodnet.scene import scene_from_toml
overrides = json.loads(sys.argv[1]) + ["output.vtk=false", "output.picture=false", "output.plot=false"]
r = run(scene_from_toml(demo_scene_text(), overrides), sys.argv[2])  # progress lines on stderr
keys = ("status", "message", "wall_time_s", "steps", "newton_iterations", "factorizations",
        "rejected_steps", "metrics", "simulated_time_s")
series = {k: r.arrays[k].tolist() for k in ("time", "mouth_area", "distance", "kinetic_energy", "elastic_energy") if k in r.arrays}
print(json.dumps({"summary": {k: r.summary.get(k) for k in keys}, "series": series,
                  "process_wall_s": time.perf_counter() - start,
                  "process_cpu_s": sum(resource.getrusage(resource.RUSAGE_SELF)[:2]),
                  "peak_rss_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024}))
"""


@dataclass(frozen=True)
class BenchRun:
    """One run of the study.

    Attributes
    ----------
    curve : str
        The model it belongs to in the plot, e.g. ``"cosserat n=2"``.
    setting : str
        What varies along the curve, e.g. ``"tol 1e-4"``.
    family : str
        Runs of one family model the same physics and share a reference.
    overrides : tuple of str
        ``key=value`` overrides of the reference deployment.
    """

    curve: str
    setting: str
    family: str
    overrides: tuple[str, ...]
    twin: str = ""
    """Label of the run this one repeats with a perturbed launch (a sensitivity run, made by
    :func:`perturbed`); empty for an ordinary run."""

    @property
    def label(self) -> str:
        return re.sub(r"[^A-Za-z0-9.=-]+", "_", f"{self.curve} {self.setting}").strip("_")


@dataclass
class Study:
    """Runs and, per family, the label of its reference run."""

    runs: list[BenchRun]
    references: dict[str, str]
    duration: float
    notes: list[str] = field(default_factory=list)
    scene: str = "the reference deployment"
    """What the runs simulate, for the table's title."""
    order_windows: tuple[float, ...] = ()
    """Times [s] up to which :func:`history_orders` also compares the histories (the whole run
    is always compared)."""
    baseline: str = ""
    """Label of the run whose wall time the others are given as multiples of (none: empty)."""


DEMO_LAUNCH_SPEED = 20.0
"""``net.launch_speed`` [m/s] of the reference deployment (rodnet/data/deploy_reference.toml)."""


def perturbed(run: BenchRun, relative: float) -> BenchRun:
    """``run`` with its corner masses launched ``1 + relative`` times as fast.

    Its difference from ``run`` is not a discretisation error: it measures how much the
    deployment amplifies a perturbation far below any modelling or numerical error (a relative
    1e-9 is 2e-8 m/s at 20 m/s), the floor below which two runs cannot be told apart. The
    launch speed is the run's own ``net.launch_speed`` override, else the reference
    deployment's.
    """
    speed = DEMO_LAUNCH_SPEED
    for item in run.overrides:
        if item.startswith("net.launch_speed="):
            speed = float(item.split("=", 1)[1])
    return BenchRun(run.curve, f"{run.setting}, launch speed {relative:+.0e}", run.family,
                    run.overrides + (f"net.launch_speed={speed * (1.0 + relative)!r}",),
                    twin=run.label)


LUMPED = ("model.type=lumped",)
CABLE = ("model.type=cosserat", "model.bending=false", "model.torsion=false", "model.knots=pinned")
ROD = ("model.type=cosserat", "model.knots=rigid")


def _n(n: int) -> tuple[str, ...]:
    return (f"model.elements_per_thread={n}",)


def _implicit(tolerance: float | None) -> tuple[str, ...]:
    """BDF2 (the Cosserat default) with the local error control at ``tolerance`` [m], or at
    its default (3e-5 of the structure's size) for None."""
    control = () if tolerance is None else (f"simulation.error_tolerance={tolerance:g}",)
    return ("simulation.integrator=bdf2", "simulation.adaptive=true", *control)


def _tol(tolerance: float | None) -> str:
    return "tol default" if tolerance is None else f"tol {tolerance:g}"


def default_study(quick: bool = False) -> Study:
    """The runs of ``rodnet bench``; ``quick``: a 5 x 5 net for 1 s, a smoke test of the
    study in a few minutes."""
    base: tuple[str, ...] = ()
    duration = 3.0
    if quick:
        base = ("net.nodes_per_side=5", "net.mesh_length=1.0", "net.corner_mass=0.2",
                "net.launch_speed=10.0")
        duration = 1.0
    base += (f"simulation.duration={duration:g}",)
    runs: list[BenchRun] = []
    tolerances: tuple[float | None, ...] = (None, 1e-4) if quick else (1e-2, None, 1e-4)
    # threads without bending: the lumped model is the reference physics
    for safety in ((0.5,) if quick else (0.5, 0.25)):
        runs.append(BenchRun("lumped explicit", f"safety {safety:g}", "no bending",
                             base + LUMPED + _n(1) + (f"simulation.explicit_safety={safety:g}",)))
    runs.append(BenchRun("lumped rk45", "rtol 1e-8", "no bending",
                         base + LUMPED + _n(1) + ("simulation.integrator=rk45", "simulation.rtol=1e-8")))
    for tol in tolerances:
        runs.append(BenchRun("lumped implicit", _tol(tol), "no bending",
                             base + LUMPED + _n(1) + _implicit(tol)))
        runs.append(BenchRun("cable n=1", _tol(tol), "no bending",
                             base + CABLE + _n(1) + _implicit(tol)))
    # threads with bending and torsion
    for n in ((1, 2) if quick else (1, 2, 4, 8)):
        for tol in tolerances:
            runs.append(BenchRun(f"cosserat n={n}", _tol(tol), "bending",
                                 base + ROD + _n(n) + _implicit(tol)))
        for safety in (0.5, 0.25):  # explicit, scaled rotary inertia (FORMULATION.md C49)
            runs.append(BenchRun(f"cosserat explicit n={n}", f"safety {safety:g}", "bending",
                                 base + ROD + _n(n) + ("simulation.integrator=explicit",
                                                       f"simulation.explicit_safety={safety:g}")))
    # sensitivity runs: the explicit runs at safety 0.5 (lumped, rods with two elements per
    # thread) launched 1e-9 faster and slower
    twins = [run for run in runs if run.setting == "safety 0.5"
             and run.curve in ("lumped explicit", "cosserat explicit n=2")]
    runs += [perturbed(run, relative) for run in twins for relative in (1e-9, -1e-9)]
    finest_n = 2 if quick else 8
    references = {"no bending": BenchRun("lumped rk45", "rtol 1e-8", "", ()).label,
                  "bending": BenchRun(f"cosserat n={finest_n}", _tol(tolerances[-1]), "", ()).label}
    return Study(runs, references, duration, order_windows=(0.1, 0.3) if quick else (0.2, 0.5, 1.3))


def defaults_study() -> Study:
    """The runs of ``rodnet bench --defaults``: every model of the reference deployment at its
    default settings (no integrator or step key: explicit for the lumped model, BDF2 with the
    default error control for Cosserat threads), two elements per thread, beside the explicit
    runs at half and a quarter of the stability limit (scaled rotary inertia, FORMULATION.md
    C49 for rods) and the lumped model stepped implicitly. The reference of each family is its
    explicit run at a quarter of the stability limit; wall times are also given as multiples of
    the lumped explicit default (the lumped ``rodnet demo``). Cheap runs first, so that an
    interrupted study has them all."""
    models = (("lumped", LUMPED + _n(1)), ("cable n=2", CABLE + _n(2)),
              ("cosserat pinned n=2", ("model.type=cosserat", "model.knots=pinned") + _n(2)),
              ("cosserat rigid n=2", ROD + _n(2)))
    runs: list[BenchRun] = []
    references: dict[str, str] = {}
    implicit: list[BenchRun] = []
    for name, keys in models:
        for safety in (0.5, 0.25):
            runs.append(BenchRun(f"{name} explicit", f"safety {safety:g}", name,
                                 keys + ("simulation.integrator=explicit",
                                         f"simulation.explicit_safety={safety:g}")))
        references[name] = runs[-1].label
        extra = ("simulation.integrator=bdf2",) if name == "lumped" else ()
        implicit.append(BenchRun(f"{name} implicit", "default" if not extra else "bdf2 default",
                                 name, keys + extra))
    baseline = BenchRun("lumped explicit", "default", "lumped", LUMPED + _n(1))
    runs.insert(2, baseline)  # after the first lumped run, which compiles the kernels
    runs += implicit
    return Study(runs, references, 3.0, order_windows=(0.2, 0.5, 1.3),
                 scene="the reference deployment, every model at its defaults",
                 baseline=baseline.label, notes=[
                     "Default settings: the scene's own, no integrator or step key (lumped: "
                     "explicit at half the stability limit; Cosserat threads: BDF2 with the "
                     "default local error control, rodnet.run.ERROR_FRACTION)."])


GRACE = 120.0
"""Seconds a run may take to save its frames after the interrupt before it is killed."""

PROGRESS_SECONDS = 300.0
"""A run's progress line (simulated time, steps, step size, wall time) is passed on to the
study's standard error at most this often [s]."""


def run_one(run: BenchRun, folder: Path, timeout: float | None = None,
            grace: float = GRACE, progress_every: float = PROGRESS_SECONDS) -> dict[str, Any]:
    """Run (or reuse the stored result of) one case in its own process; the record is also
    written to ``folder/runs/<label>.json``. The run's progress lines are passed on to standard
    error, at most one every ``progress_every`` seconds.

    A run still going after ``timeout`` seconds is interrupted (SIGTERM, as ``timeout`` sends;
    not SIGINT, which a run started from a background job ignores, as Python does): it keeps its
    frames and reports how far it got, with ``timed_out`` set in the record; one still going
    ``grace`` seconds after the interrupt is killed, recorded as failed with ``hung`` set. The
    record also holds the child's ``returncode`` and the wall time seen here, ``parent_wall_s``.
    """
    store = folder / "runs" / f"{run.label}.json"
    if store.is_file():
        return json.loads(store.read_text())
    store.parent.mkdir(parents=True, exist_ok=True)
    timed_out = hung = False
    start = time.perf_counter()
    with tempfile.TemporaryDirectory(prefix="rodnet-bench-") as out:
        child = subprocess.Popen([sys.executable, "-c", CHILD, json.dumps(list(run.overrides)), out],
                                 stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        readers = _Readers(child, progress_every)
        try:
            child.wait(timeout=timeout)
        except subprocess.TimeoutExpired:
            timed_out = True
            child.send_signal(signal.SIGTERM)
            try:  # a run saves its frames on SIGTERM; one that ignores it is killed
                child.wait(timeout=grace)
            except subprocess.TimeoutExpired:
                hung = True
                child.kill()
                child.wait()
        stdout, stderr = readers.join()
    lines = stdout.strip().splitlines()
    if hung or child.returncode not in (0, 1) or not lines:
        tail = stderr.strip().splitlines()
        message = (f"did not end within {grace:g} s of the interrupt; killed" if hung else
                   tail[-1] if tail else f"exit status {child.returncode}, no output")
        record: dict[str, Any] = {"summary": {"status": "failed", "message": message}, "series": {}}
    else:
        record = json.loads(lines[-1])
    record.update(timed_out=timed_out, hung=hung, returncode=child.returncode,
                  parent_wall_s=time.perf_counter() - start,
                  run={"curve": run.curve, "setting": run.setting, "family": run.family,
                       "overrides": list(run.overrides)})
    store.write_text(json.dumps(record))
    return record


class _Readers:
    """Threads that read a child's standard output and error while it runs, passing its progress
    lines (``rodnet: t = ...``) on to this process's standard error, at most one every
    ``every`` seconds."""

    def __init__(self, child: subprocess.Popen, every: float) -> None:  # type: ignore[type-arg]
        self.out: list[str] = []
        self.err: list[str] = []
        self.every, self.last = every, -math.inf
        self.threads = [threading.Thread(target=self._read, args=(child.stdout, False), daemon=True),
                        threading.Thread(target=self._read, args=(child.stderr, True), daemon=True)]
        for thread in self.threads:
            thread.start()

    def _read(self, stream: Any, is_err: bool) -> None:
        for line in stream:
            (self.err if is_err else self.out).append(line)
            if is_err and line.startswith("rodnet: t = ") and \
                    time.perf_counter() - self.last >= self.every:
                self.last = time.perf_counter()
                print("rodnet bench:     " + line[len("rodnet: "):].rstrip(), file=sys.stderr,
                      flush=True)

    def join(self) -> tuple[str, str]:
        """Everything the child wrote to its standard output and error, once it has ended."""
        for thread in self.threads:
            thread.join()
        return "".join(self.out), "".join(self.err)


def errors(record: dict[str, Any], reference: dict[str, Any]) -> dict[str, float]:
    """The four error measures of a run against its family's reference (nan when either run
    did not complete): the first three signed (the run's value less the reference's, the area
    relative to it), the centre-of-mass path's the largest distance."""
    nan = {"max_mouth_area": math.nan, "time_of_max": math.nan, "distance_at_max": math.nan,
           "com_path": math.nan}
    if record["summary"].get("status") != "ok" or reference["summary"].get("status") != "ok":
        return nan
    m, r = record["summary"]["metrics"], reference["summary"]["metrics"]
    if "max_mouth_area" not in m or "max_mouth_area" not in r:
        return nan
    d, d_ref = np.asarray(record["series"]["distance"]), np.asarray(reference["series"]["distance"])
    k = min(len(d), len(d_ref))
    return {"max_mouth_area": m["max_mouth_area"] / r["max_mouth_area"] - 1.0,
            "time_of_max": m["time_of_max_mouth_area"] - r["time_of_max_mouth_area"],
            "distance_at_max": m["distance_at_max_mouth_area"] - r["distance_at_max_mouth_area"],
            "com_path": float(np.max(np.abs(d[:k] - d_ref[:k]), initial=0.0))}


COLUMNS = ("model", "setting", "status", "wall s", "CPU s", "steps", "Newton its", "factorisations",
           "peak MB", "max area m^2", "t of max s", "err max area %", "err t of max s",
           "err distance m", "err COM path m")


def table_rows(study: Study, records: dict[str, dict[str, Any]]) -> list[list[str]]:
    """One row per run, in the study's order."""
    rows = []
    for run in study.runs:
        rec = records[run.label]
        s = rec["summary"]
        ref = records.get(study.references.get(run.family, ""), rec)
        e = errors(rec, ref)
        metrics = s.get("metrics") or {}
        status = s.get("status", "?") if s.get("status") == "ok" else \
            f"{s.get('status')}: {str(s.get('message', ''))[:60]}"
        if rec.get("timed_out"):
            status = f"interrupted at the time limit, t = {_fmt(s.get('simulated_time_s'))} s"
        rows.append([run.curve, run.setting, status, _fmt(rec.get("process_wall_s")),
                     _fmt(rec.get("process_cpu_s")),
                     _fmt(s.get("steps")), _fmt(s.get("newton_iterations")),
                     _fmt(s.get("factorizations")), _fmt(rec.get("peak_rss_mb")),
                     _fmt(metrics.get("max_mouth_area")), _fmt(metrics.get("time_of_max_mouth_area")),
                     _fmt(100 * e["max_mouth_area"]), _fmt(e["time_of_max"]),
                     _fmt(e["distance_at_max"]), _fmt(e["com_path"])])
    return rows


def _fmt(value: Any) -> str:
    if value is None:
        return "-"
    if isinstance(value, int):
        return str(value)
    value = float(value)
    if math.isnan(value):
        return "-"
    return f"{value:.4g}"


_N_CURVE = re.compile(r"(.*?)\s*n=(\d+)")
"""A curve refined in elements per thread: ``"<model> n=<n>"``."""
_SETTING = re.compile(r"(\w+)\s+([0-9.eE+-]+)")
"""A setting refined along a curve: ``"<name> <value>"`` (``"safety 0.25"``, ``"tol 1e-4"``)."""


def spatial_orders(study: Study, records: dict[str, dict[str, Any]]) -> list[str]:
    """Observed spatial order of the max mouth area of every model refined in elements per
    thread: runs whose curve ends in ``n=<elements>`` are grouped by the rest of the curve name
    (``"cosserat pinned explicit n=4"``: ``"cosserat pinned explicit"``) and by setting, and
    ``log2(|A_n - A_2n| / |A_2n - A_4n|)`` is reported for successive halvings (none when the
    two differences differ in sign: not monotone)."""
    groups: dict[tuple[str, str], dict[int, float]] = {}
    for run in study.runs:
        match = _N_CURVE.fullmatch(run.curve)
        rec = records[run.label]
        if match and rec["summary"].get("status") == "ok" and not run.twin:
            areas = groups.setdefault((match.group(1), run.setting), {})
            areas[int(match.group(2))] = rec["summary"]["metrics"]["max_mouth_area"]
    lines = []
    for (model, setting), areas in groups.items():
        ns = sorted(areas)
        if len(ns) < 2:
            continue
        lines.append(f"{model}, {setting}: max mouth area "
                     + ", ".join(f"{areas[n]:.6g} m^2 at n = {n}" for n in ns))
        for a, b, c in zip(ns, ns[1:], ns[2:]):
            if b == 2 * a and c == 2 * b:
                lines.append(f"{model}, {setting}: observed order, n = {a}, {b}, {c}: "
                             + _order(areas[a], areas[b], areas[c], 2.0))
    return lines


def _order(a1: float, a2: float, a3: float, ratio: float) -> str:
    """``log(|a1 - a2| / |a2 - a3|) / log(ratio)`` for a quantity refined twice by ``ratio``;
    when the two differences differ in sign the sequence is not yet converging monotonically
    and no order is given."""
    d1, d2 = a1 - a2, a2 - a3
    if d1 * d2 < 0.0:
        return f"none, not monotone (differences {d1:+.3g}, {d2:+.3g} m^2)"
    if d2 == 0.0 or d1 == 0.0:
        return "none, a difference is zero"
    return f"{math.log(d1 / d2) / math.log(ratio):.2f}"


def setting_orders(study: Study, records: dict[str, dict[str, Any]]) -> list[str]:
    """Observed order of the max mouth area in the setting refined along one curve.

    Runs of one curve whose setting is ``"<name> <value>"`` (``"safety 0.25"``, ``"tol 1e-4"``)
    are grouped by curve and name; for three values refined by one constant ratio ``r``,
    ``log(|A_1 - A_2| / |A_2 - A_3|) / log(r)`` is reported (none when the two differences
    differ in sign: not monotone). With the explicit rods ``safety`` scales both the step and
    the added rotary inertia (FORMULATION C49), so this is the order of that joint refinement,
    not of the step alone.
    """
    groups: dict[tuple[str, str], dict[float, float]] = {}
    for run in study.runs:
        match = _SETTING.fullmatch(run.setting)
        rec = records[run.label]
        if match and rec["summary"].get("status") == "ok":
            values = groups.setdefault((run.curve, match.group(1)), {})
            values[float(match.group(2))] = rec["summary"]["metrics"]["max_mouth_area"]
    lines = []
    for (curve, name), areas in groups.items():
        values = sorted(areas, reverse=True)
        for a, b, c in zip(values, values[1:], values[2:]):
            if math.isclose(a / b, b / c, rel_tol=1e-6):
                lines.append(f"{curve}: max mouth area " + ", ".join(
                    f"{areas[v]:.6g} m^2 at {name} {v:g}" for v in (a, b, c))
                    + f"; observed order in {name}: " + _order(areas[a], areas[b], areas[c], a / b))
    return lines


def interpolated_peak(record: dict[str, Any]) -> tuple[float, float] | None:
    """Time [s] and value [m^2] of the largest mouth area between the frames: the vertex of the
    parabola through the largest saved frame and its two neighbours (the frames alone resolve
    the time only to the frame interval, and the largest value to about ``A'' dt^2 / 8``).
    None for a run without its series or with its largest area at the first or last frame."""
    series = record.get("series", {})
    if record["summary"].get("status") != "ok" or "mouth_area" not in series:
        return None
    t, a = np.asarray(series["time"]), np.asarray(series["mouth_area"])
    i = int(np.argmax(a))
    if i == 0 or i == len(a) - 1:
        return None
    curvature = a[i - 1] - 2.0 * a[i] + a[i + 1]
    if curvature >= 0.0:
        return None
    shift = 0.5 * (a[i - 1] - a[i + 1]) / curvature  # in frame intervals, within [-1/2, 1/2]
    return float(t[i] + shift * (t[i + 1] - t[i])), float(a[i] - 0.25 * (a[i - 1] - a[i + 1]) * shift)


def history_difference(a: dict[str, Any], b: dict[str, Any], key: str,
                       until: float = math.inf) -> float:
    """Largest ``|a - b|`` of the series ``key`` (``"mouth_area"`` [m^2], ``"distance"`` [m])
    over the frames the two runs share with time <= ``until`` [s]; nan when either run did not
    complete."""
    if any(r["summary"].get("status") != "ok" or not {key, "time"} <= r.get("series", {}).keys()
           for r in (a, b)):
        return math.nan
    k = min(len(a["series"][key]), len(b["series"][key]))
    t = np.asarray(a["series"]["time"][:k])
    keep = t <= until * (1.0 + 1e-9)
    d = np.abs(np.asarray(a["series"][key][:k]) - np.asarray(b["series"][key][:k]))[keep]
    return float(np.max(d, initial=0.0))


HISTORIES = (("mouth_area", "mouth-area history", "m^2"), ("distance", "centre-of-mass distance", "m"))


def _windows(study: Study) -> list[float]:
    return [w for w in sorted(study.order_windows) if w < study.duration] + [study.duration]


def sensitivity(study: Study, records: dict[str, dict[str, Any]]) -> tuple[list[str], dict]:
    """What a perturbed launch changes, per sensitivity run (:func:`perturbed`).

    Returns the table's lines and the floor: ``{(family, key, window): difference}``, the
    largest difference over the family's sensitivity runs of the history ``key`` up to
    ``window``. Two runs of that family whose histories differ by no more than the floor are
    not resolved from each other.
    """
    lines: list[str] = []
    floor: dict[tuple[str, str, float], float] = {}
    for run in study.runs:
        rec, twin = records.get(run.label), records.get(run.twin)
        if not run.twin or rec is None or twin is None:
            continue
        if rec["summary"].get("status") != "ok" or twin["summary"].get("status") != "ok":
            lines.append(f"sensitivity, {run.curve}, {run.setting}: not available (a run failed)")
            continue
        m, m0 = rec["summary"]["metrics"], twin["summary"]["metrics"]
        da = m["max_mouth_area"] - m0["max_mouth_area"]
        parts = [f"largest mouth area {da:+.3g} m^2 ({100 * da / m0['max_mouth_area']:+.2g} %), "
                 f"its time {m['time_of_max_mouth_area'] - m0['time_of_max_mouth_area']:+.3g} s"]
        peak, peak0 = interpolated_peak(rec), interpolated_peak(twin)
        if peak is not None and peak0 is not None:
            dt_peak, da_peak = peak[0] - peak0[0], peak[1] - peak0[1]
            parts.append(f"between the frames {da_peak:+.3g} m^2 at {1e3 * dt_peak:+.3g} ms")
            for key, d in (("peak_area", abs(da_peak)), ("peak_time", abs(dt_peak))):
                floor[(run.family, key, math.inf)] = max(floor.get((run.family, key, math.inf), 0.0), d)
        for key, name, unit in HISTORIES:
            values = []
            for w in _windows(study):
                d = history_difference(rec, twin, key, w)
                values.append(d)
                slot = (run.family, key, w)
                floor[slot] = max(floor.get(slot, 0.0), d)
            parts.append(f"{name} up to " + ", ".join(f"{d:.3g}" for d in values) + f" {unit}")
        when = ", ".join(f"{w:g}" for w in _windows(study))
        lines.append(f"sensitivity, {run.curve}, {run.setting} (against the unperturbed run): "
                     + "; ".join(parts) + f" (by t = {when} s)")
    return lines, floor


def _sequences(study: Study, records: dict[str, dict[str, Any]]) -> list[tuple[str, float, list[str]]]:
    """Runs refined three or more times by one ratio: ``(title, ratio, labels)``, coarsest
    first; in elements per thread (curves ending in ``n=<n>``, one setting) and in the setting
    (``"<name> <value>"`` along one curve). Sensitivity runs and failed runs are left out."""
    by_n: dict[tuple[str, str], dict[float, str]] = {}
    by_setting: dict[tuple[str, str], dict[float, str]] = {}
    for run in study.runs:
        if run.twin or records.get(run.label, {}).get("summary", {}).get("status") != "ok":
            continue
        match = _N_CURVE.fullmatch(run.curve)
        if match:
            by_n.setdefault((match.group(1), run.setting), {})[float(match.group(2))] = run.label
        match = _SETTING.fullmatch(run.setting)
        if match:
            by_setting.setdefault((run.curve, match.group(1)), {})[float(match.group(2))] = run.label
    out = []
    for groups, name, increasing in ((by_n, "n", True), (by_setting, None, False)):
        for (head, tail), members in groups.items():
            values = sorted(members, reverse=not increasing)
            chain = values[:1]
            for v in values[1:]:  # the longest run of one ratio from the coarsest value
                if len(chain) == 1 or math.isclose(v / chain[-1], chain[1] / chain[0], rel_tol=1e-6):
                    chain.append(v)
            if len(chain) < 3:
                continue
            title = (f"{head}, {tail}, n = " if name else f"{head}, {tail} = ") + \
                ", ".join(f"{v:g}" for v in chain)
            out.append((title, chain[1] / chain[0], [members[v] for v in chain]))
    return out


def _ratio_order(d1: float, d2: float, ratio: float) -> str:
    """``log(d1 / d2) / log(r)``, ``r = max(ratio, 1 / ratio)``, for successive differences of
    one sign, the coarser first (a setting that shrinks has ``ratio < 1``)."""
    return f"{math.log(d1 / d2) / math.log(max(ratio, 1.0 / ratio)):.2f}"


def peak_orders(study: Study, records: dict[str, dict[str, Any]]) -> list[str]:
    """Observed orders of the largest mouth area and of its time between the frames
    (:func:`interpolated_peak`) under refinement (:func:`_sequences`): ``log(|d_i| / |d_i+1|) /
    log(r)`` of successive differences ``d_i``; none where they change sign, and, where the
    family has sensitivity runs, none from a difference not above theirs (starred)."""
    _, floor = sensitivity(study, records)
    lines = []
    for title, ratio, labels in _sequences(study, records):
        peaks = [interpolated_peak(records[label]) for label in labels]
        if any(p is None for p in peaks):
            continue
        family = next(r.family for r in study.runs if r.label == labels[0])
        parts = []
        for k, key, name, unit, scale in ((1, "peak_area", "largest mouth area", "m^2", 1.0),
                                          (0, "peak_time", "its time", "ms", 1e3)):
            values = [scale * p[k] for p in peaks]  # type: ignore[index]
            ds = [a - b for a, b in zip(values, values[1:])]
            f = floor.get((family, key, math.inf))
            marks = ["*" if f is not None and abs(d) <= scale * f else "" for d in ds]
            orders = []
            for i in range(len(ds) - 1):
                if marks[i] or marks[i + 1] or ds[i] * ds[i + 1] <= 0.0:
                    orders.append("-")
                else:
                    orders.append(_ratio_order(ds[i], ds[i + 1], ratio))
            parts.append(f"{name} " + ", ".join(f"{v:.6g}" for v in values) + f" {unit} "
                         "(differences " + ", ".join(f"{d:+.3g}{m}" for d, m in zip(ds, marks))
                         + "; orders " + ", ".join(orders) + ")")
        lines.append(f"{title}: between the frames, " + "; ".join(parts))
    if lines and floor:
        lines.append("Between the frames: the vertex of the parabola through the largest saved "
                     "frame and its neighbours; no order where successive differences change "
                     "sign; *: not above what the sensitivity runs change.")
    return lines


def history_orders(study: Study, records: dict[str, dict[str, Any]]) -> list[str]:
    """Observed orders of the mouth-area and centre-of-mass histories under refinement.

    For runs refined by a ratio ``r`` (:func:`_sequences`), ``D_i`` is the largest difference
    between the histories of runs ``i`` and ``i + 1`` up to a window (each of
    ``study.order_windows`` and the whole run), and ``log(D_i / D_i+1) / log(r)`` the observed
    order (r < 1 for a setting that shrinks, so the order is positive when the differences
    shrink). Unlike the largest mouth area, a largest difference of histories has no sign to
    change. Where the family has sensitivity runs, a difference not above their difference in
    the same window (the floor) is starred and no order is taken from it.
    """
    _, floor = sensitivity(study, records)
    lines = []
    for title, ratio, labels in _sequences(study, records):
        family = next(r.family for r in study.runs if r.label == labels[0])
        for w in _windows(study):
            parts = []
            for key, name, unit in HISTORIES:
                ds = [history_difference(records[a], records[b], key, w)
                      for a, b in zip(labels, labels[1:])]
                if any(math.isnan(d) for d in ds):  # a run without histories
                    continue
                f = floor.get((family, key, w))
                marks = ["*" if f is not None and d <= f else "" for d in ds]
                orders = ["-" if marks[i + 1] or ds[i + 1] == 0.0 or marks[i]
                          else _ratio_order(ds[i], ds[i + 1], ratio) for i in range(len(ds) - 1)]
                parts.append(f"{name} " + ", ".join(f"{d:.3g}{m}" for d, m in zip(ds, marks))
                             + f" {unit} (orders " + ", ".join(orders) + ")")
            span = "the whole run" if w >= study.duration else f"t <= {w:g} s"
            if parts:
                lines.append(f"{title}, {span}: differences of successive runs: "
                             + "; ".join(parts))
    if floor and lines:
        lines.append("*: not above the difference the sensitivity runs make in the same window "
                     "(the floor); no order is taken from it.")
    return lines


def baseline_ratios(study: Study, records: dict[str, dict[str, Any]]) -> list[str]:
    """Every run's wall time as a multiple of the study's baseline run (none without one)."""
    base = records.get(study.baseline, {}).get("process_wall_s")
    if not base:
        return []
    parts = [f"{run.curve}, {run.setting}: {records[run.label]['process_wall_s'] / base:.3g}"
             + (" (interrupted)" if records[run.label].get("timed_out") else "")
             for run in study.runs if run.label != study.baseline
             and records[run.label].get("process_wall_s") is not None]
    return [f"wall time as a multiple of `{study.baseline}` ({base:.3g} s): " + "; ".join(parts)]


def write_outputs(study: Study, records: dict[str, dict[str, Any]], folder: Path) -> str:
    """Write the Markdown table, the CSV and the plot; return the Markdown."""
    rows = table_rows(study, records)
    md = [f"# Work-precision study: {study.scene}", "",
          f"{study.duration:g} s simulated. Errors against the reference of each family: "
          + "; ".join(f"{fam}: `{label}`" for fam, label in study.references.items()) + ".", "",
          "| " + " | ".join(COLUMNS) + " |", "|" + "---|" * len(COLUMNS)]
    md += ["| " + " | ".join(r) + " |" for r in rows]
    md += ["", *[f"- {line}" for line in spatial_orders(study, records)
                 + setting_orders(study, records) + sensitivity(study, records)[0]
                 + peak_orders(study, records) + history_orders(study, records)
                 + baseline_ratios(study, records) + study.notes]]
    text = "\n".join(md) + "\n"
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "work_precision.md").write_text(text)
    with open(folder / "work_precision.csv", "w", newline="") as f:
        writer = csv.writer(f)
        writer.writerow(COLUMNS)
        writer.writerows(rows)
    _plot(study, records, folder / "work_precision.png")
    return text


def _plot(study: Study, records: dict[str, dict[str, Any]], path: Path) -> None:
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:  # the plot is optional; the table says everything
        return
    fig, ax = plt.subplots(figsize=(7, 5))
    curves: dict[str, list[tuple[float, float]]] = {}
    for run in study.runs:
        rec = records[run.label]
        ref = records.get(study.references.get(run.family, ""))
        if ref is None or run.twin or run.label == study.references.get(run.family):
            continue
        e = abs(errors(rec, ref)["max_mouth_area"])   # a log scale: the size
        if np.isfinite(e) and e > 0:
            curves.setdefault(run.curve, []).append((100 * e, rec["process_wall_s"]))
    for curve, points in curves.items():
        points.sort()
        ax.loglog(*zip(*points), "o-", label=curve)
    ax.set_xlabel("error in max mouth area [%]")
    ax.set_ylabel("wall time [s]")
    ax.set_title(f"{study.scene[0].upper()}{study.scene[1:]}: cost against accuracy")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def bench(folder: Path, quick: bool = False, only: str | None = None,
          limit: float | None = 3600.0, defaults: bool = False) -> str:
    """Run the study (skipping runs stored in ``folder/runs``) and write its outputs; a run
    still going after ``limit`` wall seconds is interrupted and reported as such. ``defaults``:
    :func:`defaults_study` instead of the work-precision study."""
    if defaults and quick:
        raise ValueError("rodnet bench: --defaults and --quick cannot be combined (--defaults "
                         "runs the full reference deployment)")
    study = defaults_study() if defaults else default_study(quick)
    if only:
        keep = [r for r in study.runs if only in r.curve] 
        needed = {lbl for lbl in study.references.values()}
        study.runs = keep + [r for r in study.runs if r.label in needed and r not in keep]
    return write_outputs(study, run_study(study, folder, limit), folder)


def run_study(study: Study, folder: Path, limit: float | None = None) -> dict[str, dict[str, Any]]:
    """Every run of ``study`` by :func:`run_one` (stored in ``folder/runs``, reused on a rerun),
    with a progress line per run on stderr; returns the records by label. A run still going
    after ``limit`` wall seconds is interrupted and reported as such."""
    records = {}
    for k, run in enumerate(study.runs, 1):
        print(f"rodnet bench: [{k}/{len(study.runs)}] {run.curve}, {run.setting} ...", file=sys.stderr, flush=True)
        records[run.label] = run_one(run, folder, timeout=limit)
        s = records[run.label]["summary"]
        print(f"rodnet bench:     {s.get('status')} in {_fmt(records[run.label].get('process_wall_s'))} s",
              file=sys.stderr, flush=True)
    return records
