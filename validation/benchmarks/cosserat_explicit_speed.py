"""Benchmark: per-step cost of explicit Cosserat threads against cable threads, old and new code.

The reference deployment (``rodnet demo``, 21 x 21 knots, two elements per thread, explicit) is
run for a short time with one fixed step for every variant (``simulation.adaptive = false``,
``simulation.dt`` below every variant's limit), so that the runs take the same steps and their
cost per step compares directly:

- cable: ``model.type = cosserat``, ``bending = false``, ``torsion = false``, pinned knots;
- Cosserat, pinned knots;
- Cosserat, rigid knots (the default).

One child process per code tree (``python -c``, the code under test on ``PYTHONPATH``: this tree
and, with ``--old PATH``, a source tree of an older rodnet), on one thread, runs every variant
once to load or compile numba's cache (untimed), then ``--repeat`` rounds of the three variants
in turn (cable and Cosserat alternated in one process: a change of the machine's load touches
both). Each run reports the CPU time of its thread (``time.thread_time``: the machine may be
shared, and a descheduled thread costs no CPU time) of the whole :func:`rodnet.run.run` call and
of the compiled step loop alone (the loop functions of :mod:`rodnet.integrate.explicit` wrapped
by the child), so the table gives both the cost per step of the whole run (set-up, such as the
explicit plan's element eigenvalues (C48)-(C50), and output spread over the steps) and the
marginal cost per step of a long run. The minimum over the rounds is kept. The table also gives
``max_mouth_area`` of every variant, new against old, and the load average.

Usage, from the repository root:
``python validation/benchmarks/cosserat_explicit_speed.py --old ../old [--duration 0.05]
[--repeat 3]``. Writes the table at the top of ``results/cosserat_explicit_speed.md``; the
sections below it (from its first ``## `` heading on: notes, earlier tables) are kept.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
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
EARLIER = "## Earlier measurements"

CHILD = """
import json, os, sys, tempfile, time
import rodnet.integrate.explicit as ix
from rodnet.cli import demo_scene_text
from rodnet.run import run
from rodnet.scene import scene_from_toml
variants, repeat = json.loads(sys.argv[1]), int(sys.argv[2])
loop_cpu = [0.0]
def timed(f):
    def call(*args):
        start = time.thread_time()
        try:
            return f(*args)
        finally:
            loop_cpu[0] += time.thread_time() - start
    return call
for name in ("march", "march_parallel", "march_nodes"):   # the loops the integrator calls
    if hasattr(ix, name):
        setattr(ix, name, timed(getattr(ix, name)))
if hasattr(ix, "march_for"):   # newer trees pick the loop through march_for
    pick = ix.march_for
    ix.march_for = lambda *args: timed(pick(*args))
def one(overrides, out):
    scene = scene_from_toml(demo_scene_text(), overrides, source="benchmark")
    loop_cpu[0] = 0.0
    start = time.thread_time()
    result = run(scene, out, progress=False, threads=1)
    cpu = time.thread_time() - start
    s = result.summary
    return {"cpu": cpu, "loop": loop_cpu[0], "steps": s["steps"], "status": s["status"],
            "area": s["metrics"]["max_mouth_area"] if "metrics" in s else s["max_mouth_area"],
            "load": os.getloadavg()[0]}
with tempfile.TemporaryDirectory() as tmp:
    for name, (warm, timed_run) in variants.items():
        one(warm, os.path.join(tmp, "warm"))
    for k in range(repeat):
        for name, (warm, timed_run) in variants.items():
            r = one(timed_run, os.path.join(tmp, "run"))
            r.update(variant=name, round=k)
            print(json.dumps(r), flush=True)
"""


def child(tree: Path, duration: float, repeat: int) -> list[dict]:
    """Every variant ``repeat`` times, alternated, in one process on the code of ``tree``."""
    fixed = [f"simulation.duration={duration}", "simulation.adaptive=false",
             f"simulation.dt={DT}"]
    variants = {name: (BASE + sets + ["simulation.duration=0.002"], BASE + sets + fixed)
                for name, sets in VARIANTS.items()}
    env = {**os.environ, "PYTHONPATH": str(tree), "NUMBA_NUM_THREADS": "1"}
    done = subprocess.run([sys.executable, "-c", CHILD, json.dumps(variants), str(repeat)],
                          env=env, capture_output=True, text=True, cwd=tree)
    if done.returncode != 0:
        raise RuntimeError(done.stderr[-3000:])
    return [json.loads(line) for line in done.stdout.splitlines() if line.startswith("{")]


def best(runs: list[dict], variant: str) -> dict:
    """The least CPU time per step of ``variant``'s runs, whole run and step loop."""
    mine = [r for r in runs if r["variant"] == variant]
    steps = mine[0]["steps"]
    return {"steps": steps, "area": mine[0]["area"],
            "run": min(r["cpu"] for r in mine) / steps, "loop": min(r["loop"] for r in mine) / steps,
            "areas": {r["area"] for r in mine}}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--old", type=Path, required=True, help="source tree of the old rodnet")
    parser.add_argument("--duration", type=float, default=0.05, help="simulated time [s]")
    parser.add_argument("--repeat", type=int, default=3)
    args = parser.parse_args()
    runs = {}
    for name, tree in (("old", args.old.resolve()), ("new", ROOT)):
        runs[name] = child(tree, args.duration, args.repeat)
        for r in runs[name]:
            print(name, r, flush=True)
    loads = [r["load"] for rs in runs.values() for r in rs]
    table = {(v, name): best(runs[name], v) for v in VARIANTS for name in runs}
    lines = [
        "# Explicit Cosserat threads: cost per step against cable threads, old and new code",
        "",
        f"Reference deployment (`rodnet demo`, 21 x 21 knots, `model.elements_per_thread=2`, "
        f"explicit), {args.duration} s simulated with the fixed step {DT:g} s "
        "(`simulation.adaptive=false`) for every variant, one thread. One process per code "
        "tree runs the three variants in turn, "
        f"{args.repeat} rounds after an untimed one (numba's cache); minimum per step over the "
        "rounds. CPU time of the thread (`time.thread_time`): *run* is the whole "
        "`rodnet.run.run` call (set-up and output spread over the steps), *loop* the compiled "
        "step loop alone (the marginal cost of a step in a long run). One-minute load average "
        f"during the runs: {min(loads):.1f} to {max(loads):.1f} on {os.cpu_count()} cores.",
        "",
        "| variant | steps | run old [us/step] | run new [us/step] | run speed-up | loop old "
        "[us/step] | loop new [us/step] | loop speed-up | run / cable old | run / cable new | "
        "loop / cable old | loop / cable new | max_mouth_area old [m^2] | new [m^2] | "
        "difference [% of old] |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for v in VARIANTS:
        o, n = table[(v, "old")], table[(v, "new")]
        co, cn = table[("cable", "old")], table[("cable", "new")]
        lines.append(
            f"| {v} | {n['steps']} | {1e6 * o['run']:.1f} | {1e6 * n['run']:.1f} | "
            f"{o['run'] / n['run']:.2f} | {1e6 * o['loop']:.1f} | {1e6 * n['loop']:.1f} | "
            f"{o['loop'] / n['loop']:.2f} | {o['run'] / co['run']:.2f} | "
            f"{n['run'] / cn['run']:.2f} | {o['loop'] / co['loop']:.2f} | "
            f"{n['loop'] / cn['loop']:.2f} | {o['area']:.6f} | {n['area']:.6f} | "
            f"{100 * (n['area'] - o['area']) / o['area']:+.4f} |")
        if len(o["areas"] | n["areas"]) > 1:
            lines.append(f"|  | (areas differ between rounds: {sorted(o['areas'] | n['areas'])}) |")
    path = HERE / "results" / "cosserat_explicit_speed.md"
    earlier = ""
    if path.exists():   # the sections below the table (notes, earlier tables) are kept
        text = path.read_text()
        kept = text.find("\n## ")
        earlier = text[kept + 1:] if kept >= 0 else \
            EARLIER + "\n\n" + text.split("\n", 1)[1].lstrip("\n")
    text = "\n".join(lines) + "\n\n" + earlier
    print(text)
    path.write_text(text)


if __name__ == "__main__":
    main()
