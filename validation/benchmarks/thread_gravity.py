"""Benchmark: a 1.5 m x 1 mm nylon thread, clamped at one end, released straight and horizontal
under gravity; 20 Cosserat elements, 1 s simulated, generalized-alpha at several steps.

Reports CPU seconds per simulated second, steps, Newton iterations, factorisations and the tip
error (largest over the saved frames) against a reference with the same 20 elements and a step
100 times smaller than 1e-3 s; the spatial error (20 against 80 elements at a small step) is
reported separately. The CPU time (``time.process_time``) is the least of ``REPEATS`` identical
runs: other work on the machine only ever adds to it. When ``pyelastica`` is importable
(``pip install -e '.[peers]'``) the same thread runs in PyElastica at its largest stable step
(5.6e-7 s here) and the ratio is printed.

Usage: ``python validation/benchmarks/thread_gravity.py [--quick]``
"""

from __future__ import annotations

import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from rodnet.run import run
from rodnet.scene import scene_from_toml

HERE = Path(__file__).parent
REPEATS = 3
SCENE = """
[simulation]
type = "dynamic"
duration = {duration}
dt = {dt}
adaptive = false
integrator = "{integrator}"
rho_inf = {rho_inf}
gravity = [0.0, 0.0, -9.81]
[model]
type = "cosserat"
axial = "linear"
[[materials]]
name = "nylon"
density = 1150.0
youngs_modulus = 2.5e9
poisson_ratio = 0.35
diameter = 1.0e-3
[[rods]]
name = "thread"
material = "nylon"
points = [[0, 0, 0], [1.5, 0, 0]]
elements = {elements}
[[supports]]
node = "thread:start"
fix = "clamp"
[output]
frame_interval = 0.01
vtk = false
"""


def simulate(dt: float, elements: int = 20, integrator: str = "generalized-alpha",
             rho_inf: float = 0.7, duration: float = 1.0) -> dict:
    scene = scene_from_toml(SCENE.format(dt=dt, elements=elements, integrator=integrator,
                                         rho_inf=rho_inf, duration=duration))
    cpu = time.process_time()
    result = run(scene, tempfile.mkdtemp(prefix="rodnet-thread-"), progress=False)
    cpu = time.process_time() - cpu
    tip = result.arrays["positions"][:, result.summary["nodes"]["thread:end"]]
    return {"cpu": cpu, "tip": tip, "summary": result.summary, "status": result.status,
            "message": result.message}


def pyelastica_cpu_per_second(seconds: float = 0.02) -> float | None:
    """CPU seconds per simulated second of PyElastica on the same thread (after a first run that
    compiles its kernels), or None when it is not installed."""
    _pyelastica_run(1e-4)
    return _pyelastica_run(seconds)


def _pyelastica_run(seconds: float) -> float | None:
    try:
        done = pyelastica_thread(seconds)
    except ImportError:
        return None
    return done[1] / seconds


def pyelastica_thread(seconds: float, dt: float = 5.6e-7, elements: int = 20) -> tuple:
    """The thread in PyElastica (position Verlet at ``dt`` [s]) for ``seconds`` [s]: the rod,
    the CPU and wall seconds of its time loop and its steps. Raises ImportError without it."""
    import elastica as ea

    class Sim(ea.BaseSystemCollection, ea.Constraints, ea.Forcing, ea.Damping):
        pass

    sim = Sim()
    rod = ea.CosseratRod.straight_rod(elements, np.zeros(3), np.array([1.0, 0, 0]),
                                      np.array([0, 0, 1.0]), 1.5, 0.5e-3, 1150.0,
                                      youngs_modulus=2.5e9, shear_modulus=2.5e9 / 2.7)
    sim.append(rod)
    sim.constrain(rod).using(ea.OneEndFixedBC, constrained_position_idx=(0,),
                             constrained_director_idx=(0,))
    sim.add_forcing_to(rod).using(ea.GravityForces, acc_gravity=np.array([0, 0, -9.81]))
    sim.finalize()
    steps = int(round(seconds / dt))
    cpu, wall = time.process_time(), time.perf_counter()
    ea.integrate(ea.PositionVerlet(), sim, seconds, steps, progress_bar=False)
    return rod, time.process_time() - cpu, time.perf_counter() - wall, steps


def timed(dt: float, integrator: str, rho_inf: float, repeats: int = REPEATS) -> dict:
    """:func:`simulate`, with the least CPU time of ``repeats`` identical runs."""
    runs = [simulate(dt, integrator=integrator, rho_inf=rho_inf) for _ in range(repeats)]
    return {**runs[0], "cpu": min(r["cpu"] for r in runs)}


def main(quick: bool = False) -> str:
    dts = [1e-3, 2e-3, 5e-3, 1e-2]
    ref = simulate(1e-5 if not quick else 1e-4)
    rows, cpu = [], {}
    for integrator, rho in [("generalized-alpha", 0.7), ("generalized-alpha", 0.3), ("backward-euler", 0.7)]:
        for dt in dts:
            r = timed(dt, integrator, rho)
            s = r["summary"]
            if r["status"] != "ok":
                rows.append(f"| {integrator} {rho} | {dt:g} | failed: {r['message'][:60]} | | | | |")
                continue
            err = np.linalg.norm(r["tip"] - ref["tip"], axis=1).max()
            cpu[integrator, rho, dt] = r["cpu"]
            rows.append(f"| {integrator} (rho_inf {rho}) | {dt:g} | {r['cpu']:.3f} | {s['steps']} | "
                        f"{s['newton_iterations']} | {s['factorizations']} | {1e3 * err:.3f} |")
    fine = simulate(1e-4, elements=80)
    coarse = simulate(1e-4, elements=20)
    spatial = np.linalg.norm(fine["tip"] - coarse["tip"], axis=1).max()
    lines = ["| integrator | dt s | CPU s per simulated s | steps | Newton iterations | factorisations "
             "| tip error mm (max over run) |", "|---|---|---|---|---|---|---|", *rows, "",
             f"CPU time: the least of {REPEATS} identical runs.",
             f"Reference: same 20 elements, dt = {'1e-5' if not quick else '1e-4'} s, "
             f"{ref['cpu']:.1f} CPU s. Spatial error, 20 against 80 elements at dt = 1e-4 s: "
             f"{1e3 * spatial:.2f} mm (max over the run).",
             f"Tip at t = 0.3 s (20 elements, reference): {(np.round(ref['tip'][30], 4) + 0.0).tolist()} m."]
    peer = pyelastica_cpu_per_second()
    ours = cpu.get(("generalized-alpha", 0.7, 2e-3))
    lines.append("PyElastica: not installed (pip install -e '.[peers]')." if peer is None else
                 f"PyElastica 20 elements, dt 5.6e-7 s: {peer:.1f} CPU s per simulated s"
                 + (f", {peer / ours:.0f} times generalized-alpha (rho_inf 0.7) at dt 2e-3 s."
                    if ours else "."))
    text = "\n".join(lines)
    (HERE / "results").mkdir(exist_ok=True)
    (HERE / "results" / "thread_gravity.md").write_text("# Clamped thread under gravity\n\n" + text + "\n")
    return text


if __name__ == "__main__":
    print(main(quick="--quick" in sys.argv))
