"""Benchmark: the reference deployment with the lumped model.

Each case runs in its own process (so peak memory is that case's) through the public API with the
built-in scene and ``--set``-style overrides; VTK and pictures are off so the table measures the
simulation. Prints a Markdown table and writes it to ``results/deploy_lumped.md``.

Usage: ``python validation/benchmarks/deploy_lumped.py [--quick]``
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np

HERE = Path(__file__).parent
CHILD = r"""
import json, resource, sys, tempfile, time
start = time.perf_counter()
from rodnet.cli import demo_scene_text
from rodnet.run import run
from rodnet.scene import scene_from_toml
overrides = json.loads(sys.argv[1]) + ["output.vtk=false", "output.picture=false", "output.plot=false"]
out = tempfile.mkdtemp(prefix="rodnet-bench-")
r = run(scene_from_toml(demo_scene_text(), overrides), out, progress=False)
total = time.perf_counter() - start
print(json.dumps({"summary": {k: r.summary[k] for k in ("status", "wall_time_s", "steps", "metrics", "integrator")},
                  "process_wall_s": total, "peak_rss_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024,
                  "npz": out + "/result.npz"}))
"""


def run_case(overrides: list[str]) -> dict:
    done = subprocess.run([sys.executable, "-c", CHILD, json.dumps(overrides)], capture_output=True,
                          text=True, check=True)
    return json.loads(done.stdout.strip().splitlines()[-1])


def main(quick: bool = False) -> str:
    cases = [("explicit, n = 1", ["model.elements_per_thread=1"]),
             ("explicit, n = 2", ["model.elements_per_thread=2"]),
             ("explicit, n = 4", ["model.elements_per_thread=4"]),
             ("explicit, n = 1, safety 0.25", ["model.elements_per_thread=1", "simulation.explicit_safety=0.25"])]
    if not quick:
        cases.append(("rk45 rtol 1e-6, n = 1", ["simulation.integrator=rk45"]))
    run_case(cases[0][1])  # fills the compiled-kernel cache so no case pays the compilation
    rows, results = [], {}
    for name, overrides in cases:
        res = run_case(overrides)
        results[name] = res
        s, m = res["summary"], res["summary"]["metrics"]
        rows.append(f"| {name} | {s['steps']} | {s['wall_time_s']:.2f} | {res['process_wall_s']:.2f} | "
                    f"{res['peak_rss_mb']:.0f} | {m['max_mouth_area']:.2f} | {m['time_of_max_mouth_area']:.2f} | "
                    f"{m['distance_at_max_mouth_area']:.3f} | {m['max_tension']:.0f} | {m['max_tension_at_frames']:.0f} |")
    table = ["| case | steps | integration wall s | process wall s | peak RSS MB | max mouth area m^2 | "
             "time of max s | distance at max m | max tension N | max tension at frames N |",
             "|---|---|---|---|---|---|---|---|---|---|", *rows]
    if "rk45 rtol 1e-6, n = 1" in results:
        a = np.load(results["explicit, n = 1"]["npz"])
        b = np.load(results["rk45 rtol 1e-6, n = 1"]["npz"])
        diff = np.abs(a["mouth_area"] - b["mouth_area"]).max() / a["mouth_area"].max()
        table += ["", f"Explicit (n = 1, safety 0.5) against RK45 (rtol 1e-6): largest mouth-area difference "
                      f"over all {len(a['time'])} frames = {100 * diff:.3f} % of the max mouth area "
                      f"(criterion 0.5 %)."]
    text = "\n".join(table)
    (HERE / "results").mkdir(exist_ok=True)
    (HERE / "results" / "deploy_lumped.md").write_text(
        "# Reference deployment, lumped model\n\n" + text + "\n")
    return text


if __name__ == "__main__":
    print(main(quick="--quick" in sys.argv))
