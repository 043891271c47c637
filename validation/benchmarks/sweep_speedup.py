"""Benchmark: the worked sweep of docs/sweeps.md with one and with two local dask workers.

The sweep is the built-in reference deployment (21 x 21 lumped net, 3 s) over launch speed
15, 20, 25, 30 m/s times launch angle 35, 45, 55 degrees, twelve runs without VTK frames or
pictures, run through the command line (``rodnet sweep ... --workers N``) in a child process;
its wall time is measured around the whole command (planning and checking the runs, starting
the cluster, the runs, the table and the plots). Also given: the sum of the runs' own wall times
(``wall_time_s`` of sweep.csv: when two runs share the cores badly, each gets slower) and the
load average before and after (the machine is shared: other jobs take cores too). Settings run
alternately, ``--repeat`` times each. Writes ``results/sweep_speedup.md`` with the sweep's table
of the last two-worker run; ``--plots DIR`` copies two of its plots there (docs/img).

Usage, from the repository root: ``python validation/benchmarks/sweep_speedup.py [--repeat 2]
[--plots docs/img]``
"""

from __future__ import annotations

import argparse
import csv
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).parent
ROOT = HERE.parents[1]
VARY = ["net.launch_speed=15,20,25,30", "net.launch_angle_deg=35,45,55"]
SETS = ["output.vtk=false", "output.picture=false", "output.plot=false"]
PLOTS = ("max_mouth_area", "max_tension")
"""The plots ``--plots`` copies."""
COLUMNS = [("net.launch_speed", "launch speed [m/s]", "{:g}"),
           ("net.launch_angle_deg", "launch angle [deg]", "{:g}"), ("status", "status", "{}"),
           ("max_mouth_area", "largest mouth area [m^2]", "{:.2f}"),
           ("time_of_max_mouth_area", "at [s]", "{:.2f}"),
           ("distance_at_max_mouth_area", "distance then [m]", "{:.2f}"),
           ("max_tension", "largest tension [N]", "{:.1f}"), ("steps", "steps", "{:.0f}"),
           ("wall_time_s", "run wall time [s]", "{:.2f}")]


def sweep(scene: Path, out: Path, workers: int) -> dict[str, float]:
    """One ``rodnet sweep`` in a child process: its wall time, the runs' summed wall time and
    the load averages (1 min) before and after."""
    args = [sys.executable, "-m", "rodnet", "sweep", str(scene), "-o", str(out), "--quiet",
            "--workers", str(workers), *[a for v in VARY for a in ("--vary", v)],
            *[a for s in SETS for a in ("--set", s)]]
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    load = os.getloadavg()[0]
    start = time.perf_counter()
    done = subprocess.run(args, capture_output=True, text=True, env=env)
    wall = time.perf_counter() - start
    if done.returncode != 0:
        raise RuntimeError(done.stderr[-2000:])
    rows = table(out)
    return {"wall": wall, "runs": sum(float(r["wall_time_s"]) for r in rows),
            "load_before": load, "load_after": os.getloadavg()[0], "n": len(rows)}


def table(out: Path) -> list[dict[str, str]]:
    with (out / "sweep.csv").open() as f:
        return list(csv.DictReader(f))


def markdown(rows: list[dict[str, str]]) -> str:
    """The sweep's table in Markdown."""
    head = "| " + " | ".join(c[1] for c in COLUMNS) + " |\n"
    head += "|" + "---|" * len(COLUMNS) + "\n"
    body = ""
    for r in rows:
        cells = [fmt.format(float(r[k]) if fmt != "{}" else r[k]) for k, _, fmt in COLUMNS]
        body += "| " + " | ".join(cells) + " |\n"
    return head + body


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=1, help="sweeps per setting (alternating)")
    parser.add_argument("--plots", type=Path, default=None, help="copy sweep_*.png here")
    args = parser.parse_args()
    sys.path.insert(0, str(ROOT))
    from rodnet.data import reference_scene_text

    work = Path(tempfile.mkdtemp(prefix="rodnet-sweep-speedup-"))
    scene = work / "reference.toml"
    scene.write_text(reference_scene_text())
    results: dict[int, list[dict[str, float]]] = {1: [], 2: []}
    for i in range(args.repeat):
        for workers in (1, 2):
            out = work / f"w{workers}_{i}"
            results[workers].append(sweep(scene, out, workers))
            r = results[workers][-1]
            print(f"{workers} worker(s): {r['wall']:.1f} s wall, runs {r['runs']:.1f} s, "
                  f"load {r['load_before']:.2f} -> {r['load_after']:.2f}", flush=True)
    best = {w: min(r["wall"] for r in rs) for w, rs in results.items()}
    lines = ["# The worked sweep with one and two local workers", "",
             f"`python validation/benchmarks/sweep_speedup.py --repeat {args.repeat}`: the "
             "reference deployment (21 x 21 lumped net, 3 s), launch speed 15, 20, 25, 30 m/s "
             "times launch angle 35, 45, 55 degrees, 12 runs, no VTK frames or pictures, "
             "`rodnet sweep --workers N` timed around the whole command. Run on a shared 2-core "
             "machine; the load average (1 min, `os.getloadavg()`) says how busy it was with "
             "other jobs.", "",
             "| workers | sweep wall time [s] | sum of the runs' wall times [s] | load before | "
             "load after |", "|---|---|---|---|---|"]
    for workers, rs in results.items():
        for r in rs:
            lines.append(f"| {workers} | {r['wall']:.1f} | {r['runs']:.1f} | "
                         f"{r['load_before']:.2f} | {r['load_after']:.2f} |")
    lines += ["", f"Speed-up of two workers over one (best of each): "
              f"**{best[1] / best[2]:.2f}** ({best[1]:.1f} s / {best[2]:.1f} s).", ""]
    busy = max(max(r["load_before"], r["load_after"]) for rs in results.values() for r in rs)
    if busy > (os.cpu_count() or 1):
        lines += [f"The load average reached {busy:.2f} on {os.cpu_count()} cores: other jobs "
                  "kept the cores busy, so the workers competed with them, and this speed-up "
                  "says more of that load than of the sweep.", ""]
    lines += ["The sweep's table (the last two-worker sweep):", "",
              markdown(table(work / f"w2_{args.repeat - 1}"))]
    text = "\n".join(lines)
    print(text)
    (HERE / "results" / "sweep_speedup.md").write_text(text)
    if args.plots is not None:
        for metric in PLOTS:
            png = work / f"w2_{args.repeat - 1}" / f"sweep_{metric}.png"
            shutil.copy(png, args.plots / png.name)
    shutil.rmtree(work)


if __name__ == "__main__":
    main()
