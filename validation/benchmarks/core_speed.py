"""Benchmark: this rodnet against an older source tree on the same runs, as ratios.

Four runs: the lumped reference deployment (``rodnet demo``, 3 s), the same under a gravity
ramped over its 3 s (every node's weight a load with a time factor), the explicit rod net (the
reference deployment with Cosserat threads, two elements per thread, pinned knots, 0.5 s) and the
thread benchmark's 1.5 m nylon thread (20 elements, generalized-alpha at a fixed 2 ms, 1 s,
``thread_gravity.py``). Each version runs each case in a child process of its own (one thread,
``NUMBA_NUM_THREADS=1``, compiled kernels warmed by a first run), alternating old and new,
``--repeats`` times; the integration wall time (``summary.json`` ``wall_time_s``) is compared,
smallest of the repeats and the median of the per-repeat ratios (the machine is shared: a
ratio taken from runs next to each other is the steadier figure). The largest mouth area or tip
position of both versions is printed too: they must be equal.

Usage, from the repository root: ``python validation/benchmarks/core_speed.py --old ../old
[--repeats 5]`` (``--old``: a source tree of the older rodnet, e.g. a ``git worktree``).
Writes ``results/core_speed.md``.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

HERE = Path(__file__).parent
sys.path.insert(0, str(HERE))
from thread_gravity import SCENE as THREAD  # noqa: E402

CHILD = r"""
import json, sys
from rodnet.run import run
from rodnet.scene import scene_from_toml
text, overrides, out = sys.argv[1], json.loads(sys.argv[2]), sys.argv[3]
r = run(scene_from_toml(text, overrides), out, progress=False)
value = r.summary["metrics"].get("max_mouth_area")
if value is None:
    value = r.arrays["positions"][-1, -1].tolist()
print(json.dumps({"wall": r.summary["wall_time_s"], "steps": r.summary["steps"], "value": value,
                  "status": r.status}))
"""


def demo_text() -> str:
    from rodnet.data import reference_scene_text

    return reference_scene_text()


CASES = {
    "lumped demo (21 x 21, 3 s)": (demo_text, ["output.vtk=false"]),
    "lumped demo under a gravity ramp over its 3 s": (demo_text, [
        "output.vtk=false", "simulation.gravity=[0.0, 0.0, -9.81]", "simulation.gravity_ramp=3.0"]),
    "explicit rods n = 2, pinned (21 x 21, 0.5 s)": (demo_text, [
        "output.vtk=false", "model.type=cosserat", "model.elements_per_thread=2",
        "model.knots=pinned", "simulation.integrator=explicit", "simulation.duration=0.5"]),
    "thread, generalized-alpha dt 2 ms (1 s)": (
        lambda: THREAD.format(duration=1.0, dt=2e-3, integrator="generalized-alpha",
                              rho_inf=0.7, elements=20), []),
}


def once(source: Path | None, text: str, overrides: list[str], out: str) -> dict:
    env = dict(os.environ, NUMBA_NUM_THREADS="1", OPENBLAS_NUM_THREADS="1")
    if source is not None:
        env["PYTHONPATH"] = str(source)
    # -P: the working directory does not shadow the tree on PYTHONPATH
    done = subprocess.run([sys.executable, "-P", "-c", CHILD, text, json.dumps(overrides), out],
                          env=env, capture_output=True, text=True)
    if done.returncode != 0:
        raise RuntimeError(done.stderr[-2000:])
    return json.loads(done.stdout.strip().splitlines()[-1])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--old", type=Path, required=True)
    parser.add_argument("--repeats", type=int, default=5)
    args = parser.parse_args()
    versions = {"old": args.old.resolve(), "new": HERE.parents[1]}
    lines = ["| run | old wall [s] | new wall [s] | new / old (median of pairs) | steps | "
             "same result |", "|---|---|---|---|---|---|"]
    with tempfile.TemporaryDirectory(prefix="rodnet-core-") as tmp:
        for name, (text_of, overrides) in CASES.items():
            text = text_of()
            for source in versions.values():
                once(source, text, overrides, tmp)            # compile and cache
            walls = {k: [] for k in versions}
            results = {}
            for _ in range(args.repeats):
                for key, source in versions.items():
                    r = once(source, text, overrides, tmp)
                    walls[key].append(r["wall"])
                    results[key] = r
            ratios = [n / o for n, o in zip(walls["new"], walls["old"])]
            same = results["old"]["value"] == results["new"]["value"] and \
                results["old"]["steps"] == results["new"]["steps"]
            lines.append(f"| {name} | {min(walls['old']):.3f} | {min(walls['new']):.3f} | "
                         f"{statistics.median(ratios):.3f} | {results['new']['steps']} | "
                         f"{'yes' if same else 'NO'} |")
            print(lines[-1], flush=True)
    text = ("# Core speed: this rodnet against the older tree\n\n"
            f"{args.repeats} alternating repeats of each run, one thread, integration wall time "
            "(`wall_time_s`); `same result`: equal steps and largest mouth area (tip position "
            "for the thread), bit for bit.\n\n" + "\n".join(lines) + "\n")
    (HERE / "results" / "core_speed.md").write_text(text)
    print(text)


if __name__ == "__main__":
    main()
