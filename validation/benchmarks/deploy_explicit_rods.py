"""Benchmark: the reference deployment (21 x 21 knots, 3 s) with explicit Cosserat threads.

Work against accuracy of the explicit rod integrator with scaled rotary inertia (FORMULATION.md
§9b) on the issue's speed case (bending and torsion, two elements per thread), beside the
cable/lumped runs at the same thread resolution. Every run goes through
:func:`rodnet.bench.run_one` (own process, stored in ``results/deploy_explicit_rods/runs``, reused
on a rerun), and the table, CSV and plot come from :func:`rodnet.bench.write_outputs`.

References (the finest run of each family):

- threads with bending: generalized-alpha on the same rods with their true rotary inertia,
  ``error_tolerance`` 1e-3 m (about 50 minutes; on the 5 x 5 net this tolerance is 7e-6 from
  1e-4 in the largest area). It is run like the others unless its record is already stored;
  ``--import-reference DIR`` stores the record of a finished ``rodnet run`` of it from ``DIR``
  instead (``summary.json`` and ``result.npz``).
- threads without bending: the lumped model, two segments per thread, at a quarter of its
  stability limit.

Usage: ``python validation/benchmarks/deploy_explicit_rods.py [--import-reference DIR]``
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

from rodnet.bench import BenchRun, Study, run_one, write_outputs

HERE = Path(__file__).parent
FOLDER = HERE / "results" / "deploy_explicit_rods"

PINNED = ("model.type=cosserat", "model.knots=pinned")
RIGID = ("model.type=cosserat", "model.knots=rigid")
EXPLICIT = ("simulation.integrator=explicit",)
IMPLICIT = ("simulation.integrator=generalized-alpha", "simulation.adaptive=true",
            "simulation.error_tolerance=0.001")


def _n(n: int) -> tuple[str, ...]:
    return (f"model.elements_per_thread={n}",)


def _safety(s: float) -> tuple[str, ...]:
    return (f"simulation.explicit_safety={s:g}",)


REFERENCE = BenchRun("cosserat pinned n=2 implicit", "tol 1e-3", "bending", PINNED + _n(2) + IMPLICIT)


def study() -> Study:
    runs = [
        BenchRun("lumped explicit n=1", "safety 0.5", "no bending", ("model.type=lumped",) + _n(1) + _safety(0.5)),
        BenchRun("lumped explicit n=2", "safety 0.5", "no bending", ("model.type=lumped",) + _n(2) + _safety(0.5)),
        BenchRun("lumped explicit n=2", "safety 0.25", "no bending", ("model.type=lumped",) + _n(2) + _safety(0.25)),
        BenchRun("cosserat pinned explicit n=2", "safety 0.5", "bending", PINNED + _n(2) + EXPLICIT + _safety(0.5)),
        BenchRun("cosserat pinned explicit n=2", "safety 0.25", "bending", PINNED + _n(2) + EXPLICIT + _safety(0.25)),
        BenchRun("cosserat rigid explicit n=2", "safety 0.5", "bending", RIGID + _n(2) + EXPLICIT + _safety(0.5)),
        BenchRun("cosserat pinned explicit n=1", "safety 0.5", "bending", PINNED + _n(1) + EXPLICIT + _safety(0.5)),
        REFERENCE,
    ]
    references = {"no bending": runs[2].label, "bending": REFERENCE.label}
    notes = ["Explicit rods: symplectic Euler with the rotary inertia scaled (C49), the element "
             "forces split over the two cores; wall times on the shared 2-core machine.",
             "The bending reference has the true rotary inertia; the explicit runs' errors against "
             "it include the effect of the scaling."]
    return Study(runs, references, 3.0, notes)


def import_reference(directory: Path) -> None:
    """Store the record of a finished ``rodnet run`` of :data:`REFERENCE` from ``directory``."""
    summary = json.loads((directory / "summary.json").read_text())
    arrays = np.load(directory / "result.npz")
    keys = ("status", "message", "wall_time_s", "steps", "newton_iterations", "factorizations",
            "rejected_steps", "metrics", "simulated_time_s")
    series = {k: arrays[k].tolist() for k in ("time", "mouth_area", "distance", "kinetic_energy",
                                              "elastic_energy") if k in arrays}
    record = {"summary": {k: summary.get(k) for k in keys}, "series": series,
              "process_wall_s": summary["wall_time_s"], "peak_rss_mb": None,
              "timed_out": False, "hung": False, "returncode": 0,
              "parent_wall_s": summary["wall_time_s"],
              "run": {"curve": REFERENCE.curve, "setting": REFERENCE.setting,
                      "family": REFERENCE.family, "overrides": list(REFERENCE.overrides)},
              "imported_from": "rodnet run rodnet/data/deploy_reference.toml --set "
                               + " --set ".join(REFERENCE.overrides)}
    store = FOLDER / "runs" / f"{REFERENCE.label}.json"
    store.parent.mkdir(parents=True, exist_ok=True)
    store.write_text(json.dumps(record))


def main() -> str:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--import-reference", type=Path, default=None)
    args = parser.parse_args()
    if args.import_reference is not None:
        import_reference(args.import_reference)
    s = study()
    records = {run.label: run_one(run, FOLDER) for run in s.runs}
    return write_outputs(s, records, FOLDER)


if __name__ == "__main__":
    print(main())
