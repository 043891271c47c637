"""The bending study: the reference deployment without bending, with a braided thread's bending
stiffness and with the solid section's, for rigid and for pinned knots.

Every variant is the built-in reference deployment (``rodnet demo``) with overrides; the threads
are Cosserat rod elements (``elements_per_thread`` below), integrated by generalized-alpha with
the local error control. "No bending" is the cable model (bending and torsion off: the lumped
physics with implicit integration). The braided thread keeps the solid section's axial
stiffness but only ``BRAIDED`` of its bending and torsional stiffness (a braid's fibres slide on
each other in bending; the fraction is a documented assumption, not a measurement).

Writes ``out/<variant>/`` (the runs, not kept in git), ``results.md`` (the table) and the figures
``docs/img/bending_*.png``. Usage, from the repository root:
``python validation/cases/deploy_bending/study.py [--n 2] [--tolerance 1e-4] [--duration 3]``.
"""

from __future__ import annotations

import argparse
import math
import time
from pathlib import Path

import numpy as np

from rodnet.cli import demo_scene_text
from rodnet.run import RunResult, run
from rodnet.scene import scene_from_toml

HERE = Path(__file__).parent
IMG = HERE.parents[2] / "docs" / "img"
BRAIDED = 0.01
E, G, D = 7.0e10, 7.0e10 / (2 * 1.36), 1.0e-3     # the reference Kevlar thread
SOLID_EI, SOLID_GJ = E * math.pi * D**4 / 64, G * math.pi * D**4 / 32


def variants() -> dict[str, tuple[str, ...]]:
    """Name -> overrides of every variant."""
    braided = (f"materials[0].bending_stiffness={BRAIDED * SOLID_EI:.6g}",
               f"materials[0].torsional_stiffness={BRAIDED * SOLID_GJ:.6g}")
    return {
        "no bending": ("model.bending=false", "model.torsion=false", "model.knots=pinned"),
        "braided, rigid knots": ("model.knots=rigid", *braided),
        "braided, pinned knots": ("model.knots=pinned", *braided),
        "solid, rigid knots": ("model.knots=rigid",),
        "solid, pinned knots": ("model.knots=pinned",),
    }


def run_variant(name: str, overrides: tuple[str, ...], n: int, tolerance: float,
                duration: float) -> tuple[RunResult, float]:
    common = ("model.type=cosserat", f"model.elements_per_thread={n}",
              "simulation.integrator=generalized-alpha", "simulation.adaptive=true",
              f"simulation.error_tolerance={tolerance:g}", f"simulation.duration={duration:g}",
              "output.vtk=false", "output.picture=false", "output.plot=false")
    scene = scene_from_toml(demo_scene_text(), (*common, *overrides))
    folder = HERE / "out" / name.replace(", ", "_").replace(" ", "_")
    start = time.perf_counter()
    result = run(scene, folder, progress=None)
    return result, time.perf_counter() - start


def figures(results: dict[str, RunResult]) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (a1, a2, a3) = plt.subplots(3, 1, figsize=(7, 9), sharex=True)
    for name, r in results.items():
        t = r.arrays["time"]
        a1.plot(t, r.arrays["mouth_area"], label=name)
        a2.plot(t, r.arrays["distance"], label=name)
        a3.semilogy(t, np.maximum(r.arrays["tension"].max(axis=1), 1e-3), label=name)
    a1.set_ylabel("mouth area [m^2]")
    a2.set_ylabel("distance [m]")
    a3.set_ylabel("largest tension [N]")
    a3.set_xlabel("time [s]")
    a1.legend(fontsize=8)
    for a in (a1, a2, a3):
        a.grid(alpha=0.3)
    fig.suptitle("Reference deployment: effect of the threads' bending stiffness")
    fig.tight_layout()
    fig.savefig(IMG / "bending_histories.png", dpi=110)
    plt.close(fig)

    shown = [n for n in ("no bending", "braided, rigid knots", "solid, rigid knots") if n in results]
    instants = (0.5, 1.0, 2.0)
    fig = plt.figure(figsize=(10, 3.4 * len(shown)))
    for i, name in enumerate(shown):
        r = results[name]
        for j, when in enumerate(instants):
            k = int(np.argmin(np.abs(r.arrays["time"] - when)))
            ax = fig.add_subplot(len(shown), 3, 3 * i + j + 1, projection="3d")
            x = r.arrays["positions"][k]
            for a, b in r.arrays["segments"]:
                ax.plot(*x[[a, b]].T, color="k", lw=0.4)
            ax.set_title(f"{name}, t = {r.arrays['time'][k]:.2f} s", fontsize=8)
            ax.set_axis_off()
    fig.tight_layout()
    fig.savefig(IMG / "bending_shapes.png", dpi=100)
    plt.close(fig)


def table(results: dict[str, RunResult], walls: dict[str, float]) -> str:
    lines = ["| variant | status | max mouth area m^2 | time of max s | distance at max m | "
             "max tension N | steps | Newton its | wall s |", "|---|---|---|---|---|---|---|---|---|"]
    for name, r in results.items():
        m, s = r.summary["metrics"], r.summary
        lines.append(f"| {name} | {r.status} | {m.get('max_mouth_area', float('nan')):.2f} | "
                     f"{m.get('time_of_max_mouth_area', float('nan')):.2f} | "
                     f"{m.get('distance_at_max_mouth_area', float('nan')):.2f} | "
                     f"{m.get('max_tension', float('nan')):.1f} | {s['steps']} | "
                     f"{s['newton_iterations']} | {walls[name]:.0f} |")
    return "\n".join(lines) + "\n"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--n", type=int, default=2, help="elements per thread")
    parser.add_argument("--tolerance", type=float, default=1e-4, help="error_tolerance [m]")
    parser.add_argument("--duration", type=float, default=3.0)
    parser.add_argument("--only", default=None, help="only the variants whose name contains this")
    args = parser.parse_args()
    results, walls = {}, {}
    for name, overrides in variants().items():
        if args.only and args.only not in name:
            continue
        print(f"deploy_bending: {name} ...", flush=True)
        results[name], walls[name] = run_variant(name, overrides, args.n, args.tolerance, args.duration)
        print(f"  {results[name].status} in {walls[name]:.0f} s: {results[name].summary['metrics']}",
              flush=True)
    text = table(results, walls)
    (HERE / "results.md").write_text(
        f"n = {args.n} elements per thread, error_tolerance = {args.tolerance:g} m, "
        f"{args.duration:g} s simulated\n\n" + text)
    print(text)
    figures(results)


if __name__ == "__main__":
    main()
