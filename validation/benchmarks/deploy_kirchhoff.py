"""Benchmark: the reference deployment (21 x 21 knots, 3 s) with Kirchhoff threads against cables.

What bending costs when the threads are Kirchhoff threads (``model.type = "kirchhoff"``, pinned
knots: the lumped cable plus a bending hinge at every node inside a thread,
elements/kirchhoff/FORMULATION.md) against the cable (the lumped model, which the cable threads
equal exactly) at the same thread resolution and step, each against the finest run of its own
family. Every run goes through :func:`rodnet.tools.bench.run_one` (own process, stored in
``results/deploy_kirchhoff/runs``, reused on a rerun); the table, CSV and plot come from
:func:`rodnet.tools.bench.write_outputs`.

References: each family's run with two segments per thread at an eighth of its stability limit.
Sensitivity runs (the safety 0.5 runs at n = 2 launched 1e-9 faster and slower,
:func:`rodnet.tools.bench.perturbed`) give the floor below which no difference means anything.

Usage: ``NUMBA_NUM_THREADS=1 python validation/benchmarks/deploy_kirchhoff.py`` on an otherwise
idle machine (the wall times are the comparison).
"""

from __future__ import annotations

from pathlib import Path

from rodnet.tools.bench import BenchRun, Study, perturbed, run_study, write_outputs

HERE = Path(__file__).parent
FOLDER = HERE / "results" / "deploy_kirchhoff"

CABLE = ("model.type=lumped",)
KIRCHHOFF = ("model.type=kirchhoff", "model.knots=pinned")


def _run(model: str, n: int, safety: float) -> BenchRun:
    family, overrides = ("no bending", CABLE) if model == "cable" else ("kirchhoff", KIRCHHOFF)
    name = "lumped explicit" if model == "cable" else "kirchhoff explicit"
    return BenchRun(f"{name} n={n}", f"safety {safety:g}", family,
                    overrides + (f"model.elements_per_thread={n}",
                                 f"simulation.explicit_safety={safety:g}"))


def study() -> Study:
    runs = [_run(model, n, safety) for n, safety in ((2, 1.0), (2, 0.5), (2, 0.25), (4, 0.5),
                                                     (8, 0.5), (2, 0.125))
            for model in ("cable", "kirchhoff")]
    references = {"no bending": runs[-2].label, "kirchhoff": runs[-1].label}
    runs += [perturbed(runs[k], relative) for k in (2, 3) for relative in (1e-9, -1e-9)]
    notes = ["Kirchhoff threads: the cable's segments and explicit step plus one bending hinge "
             "per node inside a thread (solid Kevlar EI = 3.44e-3 N m^2). Wall times: process "
             "wall time with the model build and the 301 frames, one thread "
             "(NUMBA_NUM_THREADS=1), runs one after another on an otherwise idle machine.",
             "The bending reference is the Kirchhoff family's own finest run: the errors measure "
             "convergence in the step within each model, not the distance between models; "
             "docs/kirchhoff.md compares the models."]
    return Study(runs, references, 3.0, notes, order_windows=(0.2, 0.5, 1.3))


def main() -> str:
    s = study()
    records = run_study(s, FOLDER)
    return write_outputs(s, records, FOLDER)


if __name__ == "__main__":
    print(main())
