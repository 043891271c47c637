"""Benchmark: stability sweep of the reference deployment at fixed steps.

The reference deployment (``rodnet demo``) with ``simulation.adaptive = false`` at dt = 1e-4,
1e-3 and 1e-2 s, and at each step the reference parameters and one parameter at a time moved to
the ends of its range: Young's modulus 1 and 200 GPa, thread diameter 0.5 and 3 mm, launch speed
5 and 50 m/s. Every run must either complete with finite states and no energy growth (nothing
does work on the net, so kinetic plus elastic energy can only fall; the table reports the largest
rise of every run, "completed" needs it below 1 %, and the run's own guard stops it at a 10 %
rise), or stop with a message naming the cause. A run still going after the time limit is
interrupted like Ctrl-C and reported with how far it got: slow, not hung.

Usage: ``python validation/benchmarks/stability_sweep.py [--model cosserat|cable|lumped]
[--n 2] [--duration 1.5] [--limit 900]``; writes ``results/stability_sweep_<model>.md``.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from rodnet.bench import BenchRun, run_one

HERE = Path(__file__).parent
MODELS = {"cosserat": ("model.type=cosserat", "model.knots=rigid"),
          "cable": ("model.type=cosserat", "model.bending=false", "model.torsion=false",
                    "model.knots=pinned"),
          "lumped": ("model.type=lumped",)}
VARIATIONS = [("reference", ()),
              ("E 1 GPa", ("materials[0].youngs_modulus=1e9",)),
              ("E 200 GPa", ("materials[0].youngs_modulus=2e11",)),
              ("d 0.5 mm", ("materials[0].diameter=5e-4",)),
              ("d 3 mm", ("materials[0].diameter=3e-3",)),
              ("v 5 m/s", ("net.launch_speed=5",)),
              ("v 50 m/s", ("net.launch_speed=50",))]


def verdict(record: dict) -> tuple[str, str]:
    """``(outcome, detail)``: completed / stopped with a message / interrupted at the limit."""
    s = record["summary"]
    series = record.get("series", {})
    energy = np.add(series.get("kinetic_energy", []), series.get("elastic_energy", []))
    growth = float(np.max(energy / energy[0] - 1.0)) if len(energy) and energy[0] > 0 else float("nan")
    reached = s.get("simulated_time_s")
    if record.get("timed_out"):
        return "interrupted at the limit", f"reached t = {reached:.3g} s; largest energy rise {growth:+.2e}"
    if s.get("status") == "ok":
        finite = bool(np.isfinite(energy).all())
        return ("completed" if finite and growth <= 0.01 else "completed, NOT OK",
                f"largest energy rise {growth:+.2e}, max area {s['metrics'].get('max_mouth_area', float('nan')):.1f} m^2")
    return "stopped with a message", str(s.get("message", ""))[:160]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--model", choices=list(MODELS), default="cosserat")
    parser.add_argument("--n", type=int, default=2, help="elements per thread")
    parser.add_argument("--duration", type=float, default=1.5, help="simulated seconds")
    parser.add_argument("--limit", type=float, default=900.0, help="wall seconds per run")
    parser.add_argument("--dts", default="1e-4,1e-3,1e-2")
    args = parser.parse_args()
    folder = HERE / "results" / f"stability_{args.model}"
    rows = []
    for dt in [float(x) for x in args.dts.split(",")]:
        for name, overrides in VARIATIONS:
            run = BenchRun(f"{args.model} n={args.n}", f"dt {dt:g} {name}", "sweep",
                           MODELS[args.model] + (f"model.elements_per_thread={args.n}",
                                                 "simulation.integrator=generalized-alpha",
                                                 "simulation.adaptive=false", f"simulation.dt={dt:g}",
                                                 f"simulation.duration={args.duration:g}") + overrides)
            record = run_one(run, folder, timeout=args.limit)
            outcome, detail = verdict(record)
            wall = record.get("process_wall_s", float("nan"))
            rows.append(f"| {dt:g} | {name} | {outcome} | {wall:.1f} | {detail} |")
            print(rows[-1], flush=True)
    text = "\n".join([f"# Stability sweep: {args.model}, n = {args.n}, generalized-alpha, fixed steps, "
                      f"{args.duration:g} s simulated, limit {args.limit:g} s wall per run", "",
                      "| dt s | variation | outcome | wall s | detail |", "|---|---|---|---|---|", *rows])
    (HERE / "results" / f"stability_sweep_{args.model}.md").write_text(text + "\n")
    print(text)


if __name__ == "__main__":
    main()
