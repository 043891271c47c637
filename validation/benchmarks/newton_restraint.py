"""Benchmark: Newton's restrained correction (``NewtonOptions.restrain``) on the first part of
the reference deployment with Cosserat threads, two elements per thread, pinned or rigid knots,
the default integrator (BDF2, adaptive steps).

Each run integrates the first ``--duration`` seconds with ``restrain`` on (the default) and off
(rotations beyond the cap only cut, any full step may be the watchdog's free one) and reports
steps, Newton iterations, factorisations, rejected steps and CPU time of the integration (one
BLAS thread). Usage::

    python validation/benchmarks/newton_restraint.py [--duration 0.1] [--knots pinned]

The table is printed as Markdown (results/newton_restraint.md holds the measured ones).
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import time

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

from rodnet.integrate.implicit import SCHEMES, integrate_implicit  # noqa: E402
from rodnet.integrate.frames import StepStats  # noqa: E402
from rodnet.run import _newton, error_tolerance, prepare  # noqa: E402
from rodnet.scene import load_scene  # noqa: E402
from importlib.resources import files  # noqa: E402


def one(knots: str, duration: float, restrain: bool) -> dict[str, float]:
    """Steps, iterations, factorisations, rejected steps and CPU seconds of one run."""
    scene = load_scene(str(files("rodnet.data") / "deploy_reference.toml"), overrides=[
        "model.type=cosserat", f"model.knots={knots}", "model.elements_per_thread=2",
        "output.vtk=false", f"simulation.duration={duration}"])
    p = prepare(scene)
    sim = scene.simulation
    options = dataclasses.replace(_newton(p), restrain=restrain)
    scheme = SCHEMES[scene.integrator](p.system, options)
    stats = StepStats()
    start = time.process_time()
    integrate_implicit(scheme, p.state, p.times, sim.dt, sim.adaptive, lambda t, s: None,
                       dt_max=sim.dt_max, error_tolerance=error_tolerance(p), stats=stats)
    return {"steps": stats.steps, "iterations": stats.newton_iterations,
            "factorizations": stats.factorizations, "rejected": stats.rejected_steps,
            "cpu": time.process_time() - start}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--duration", type=float, default=0.1)
    parser.add_argument("--knots", default="pinned", choices=("pinned", "rigid"))
    args = parser.parse_args()
    print(f"| knots | duration [s] | restrain | steps | Newton iterations | factorisations "
          f"| rejected | CPU [s] |\n|---|---:|---|---:|---:|---:|---:|---:|")
    for restrain in (False, True):
        r = one(args.knots, args.duration, restrain)
        print(f"| {args.knots} | {args.duration:g} | {'on' if restrain else 'off'} | "
              f"{r['steps']} | {r['iterations']} | {r['factorizations']} | {r['rejected']} | "
              f"{r['cpu']:.1f} |", flush=True)


if __name__ == "__main__":
    main()
