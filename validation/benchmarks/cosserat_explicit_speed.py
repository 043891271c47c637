"""Benchmark: per-step cost of explicit Cosserat threads against cable threads, old and new code.

The reference deployment (``rodnet demo``, 21 x 21 knots, two elements per thread, explicit) is
run for a short time with one fixed step for every variant (``simulation.adaptive = false``,
``simulation.dt`` below every variant's limit), so that the runs take the same steps and their
cost per step compares directly:

- cable: ``model.type = cosserat``, ``bending = false``, ``torsion = false``, pinned knots;
- Cosserat, pinned knots;
- Cosserat, rigid knots (the default).

Each run is a child process (``python -c``, the code under test on ``PYTHONPATH``: this tree and,
with ``--old PATH``, a source tree of an older rodnet) on one thread; it reports the CPU time of
its integrating thread (``time.thread_time`` around :func:`rodnet.run.run`: the machine may be
shared, and a descheduled thread costs no CPU time), the integration wall time of
``summary.json`` and the number of steps. Old and new runs are interleaved and repeated; the
minimum per step is kept. A first run of every variant compiles (numba's cache) and is not timed.
The table also gives ``max_mouth_area`` of every variant, new against old, and the load average.

Usage, from the repository root:
``python validation/benchmarks/cosserat_explicit_speed.py --old ../old [--duration 0.1]
[--repeat 3] [--full]`` (``--full``: also the whole 3 s deployment of the new Cosserat variants
at their default adaptive step, for the mouth area). Writes
``results/cosserat_explicit_speed.md``.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

HERE = Path(__file__).parent
ROOT = HERE.parent.parent
VARIANTS = {
    "cable": ["model.type=cosserat", "model.bending=false", "model.torsion=false",
              "model.knots=pinned"],
    "Cosserat pinned": ["model.type=cosserat", "model.knots=pinned"],
    "Cosserat rigid": ["model.type=cosserat", "model.knots=rigid"],
}
BASE = ["model.elements_per_thread=2", "simulation.integrator=explicit", "output.vtk=false",
        "output.picture=false", "output.plot=false"]
DT = 1.5e-5
"""The common fixed step [s]: below the stability limit of every variant (cable and Cosserat
about 3.5e-5 s with rigid knots, C48) and below the rotation-controlled step of the bent
Cosserat elements (C50)."""

CHILD = """
import json, sys, time
from rodnet.cli import demo_scene_text
from rodnet.run import run
from rodnet.scene import scene_from_toml
scene = scene_from_toml(demo_scene_text(), json.loads(sys.argv[1]), source="benchmark")
start = time.thread_time()
result = run(scene, sys.argv[2], progress=False, threads=1)
cpu = time.thread_time() - start
s = result.summary
print(json.dumps({"cpu": cpu, "wall": s["wall_time_s"], "steps": s["steps"],
                  "area": s["metrics"]["max_mouth_area"] if "metrics" in s else s["max_mouth_area"],
                  "status": s["status"]}))
"""


def child(tree: Path, overrides: list[str], out: Path) -> dict[str, float]:
    """One run of the demo with ``overrides`` on the code of ``tree``."""
    env = {**os.environ, "PYTHONPATH": str(tree), "NUMBA_NUM_THREADS": "1"}
    done = subprocess.run([sys.executable, "-c", CHILD, json.dumps(overrides), str(out)],
                          env=env, capture_output=True, text=True, cwd=tree)
    if done.returncode != 0:
        raise RuntimeError(done.stderr[-3000:])
    return json.loads(done.stdout.strip().splitlines()[-1])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--old", type=Path, required=True, help="source tree of the old rodnet")
    parser.add_argument("--duration", type=float, default=0.1, help="simulated time [s]")
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--full", action="store_true", help="also the 3 s deployment (new)")
    args = parser.parse_args()
    trees = {"old": args.old.resolve(), "new": ROOT}
    loads = [os.getloadavg()[0]]
    best: dict[tuple[str, str], dict[str, float]] = {}
    with tempfile.TemporaryDirectory() as tmp:
        for (variant, sets) in VARIANTS.items():   # compile (numba's cache), untimed
            for name, tree in trees.items():
                child(tree, BASE + sets + ["simulation.duration=0.002"], Path(tmp) / "warm")
        fixed = [f"simulation.duration={args.duration}", "simulation.adaptive=false",
                 f"simulation.dt={DT}"]
        for _ in range(args.repeat):
            for variant, sets in VARIANTS.items():
                for name, tree in trees.items():
                    r = child(tree, BASE + sets + fixed, Path(tmp) / f"{variant}-{name}")
                    r["cpu_step"] = r["cpu"] / r["steps"]
                    r["wall_step"] = r["wall"] / r["steps"]
                    key = (variant, name)
                    if key not in best:
                        best[key] = r
                    else:
                        best[key]["cpu_step"] = min(best[key]["cpu_step"], r["cpu_step"])
                        best[key]["wall_step"] = min(best[key]["wall_step"], r["wall_step"])
                    loads.append(os.getloadavg()[0])
                    print(variant, name, r, flush=True)
        full = {}
        if args.full:
            for variant in ("Cosserat pinned", "Cosserat rigid"):
                for name, tree in trees.items():
                    full[(variant, name)] = child(tree, BASE + VARIANTS[variant],
                                                  Path(tmp) / f"full-{variant}-{name}")
                    print("full", variant, name, full[(variant, name)], flush=True)
    lines = [
        "# Explicit Cosserat threads: cost per step against cable threads, old and new code",
        "",
        f"Reference deployment (`rodnet demo`, 21 x 21 knots, `model.elements_per_thread=2`, "
        f"explicit), {args.duration} s simulated with the fixed step {DT:g} s "
        "(`simulation.adaptive=false`) for every variant, one thread; minimum over "
        f"{args.repeat} interleaved repeats. CPU: `time.thread_time` of the integrating run "
        "(insensitive to being descheduled on a shared machine); wall: `summary.json` "
        f"`wall_time_s`. One-minute load average during the runs: {min(loads):.1f} to "
        f"{max(loads):.1f} on {os.cpu_count()} cores.",
        "",
        "| variant | steps | old CPU [us/step] | new CPU [us/step] | speed-up | old / cable | "
        "new / cable | old wall [us/step] | new wall [us/step] | max_mouth_area old [m^2] | "
        "new [m^2] | difference [% of old] |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for variant in VARIANTS:
        o, n = best[(variant, "old")], best[(variant, "new")]
        co, cn = best[("cable", "old")]["cpu_step"], best[("cable", "new")]["cpu_step"]
        lines.append(
            f"| {variant} | {n['steps']} | {1e6 * o['cpu_step']:.1f} | {1e6 * n['cpu_step']:.1f} | "
            f"{o['cpu_step'] / n['cpu_step']:.2f} | {o['cpu_step'] / co:.2f} | "
            f"{n['cpu_step'] / cn:.2f} | {1e6 * o['wall_step']:.1f} | {1e6 * n['wall_step']:.1f} | "
            f"{o['area']:.6g} | {n['area']:.6g} | {100 * (n['area'] - o['area']) / o['area']:+.4f} |")
    if full:
        lines += ["", "Whole deployment (3 s, default adaptive step, one thread):", "",
                  "| variant | code | steps | max_mouth_area [m^2] | difference [% of old] |",
                  "|---|---|---|---|---|"]
        for variant in ("Cosserat pinned", "Cosserat rigid"):
            o = full[(variant, "old")]
            for name in ("old", "new"):
                r = full[(variant, name)]
                lines.append(f"| {variant} | {name} | {r['steps']} | {r['area']:.6g} | "
                             f"{100 * (r['area'] - o['area']) / o['area']:+.4f} |")
    text = "\n".join(lines) + "\n"
    print(text)
    (HERE / "results" / "cosserat_explicit_speed.md").write_text(text)


if __name__ == "__main__":
    main()
