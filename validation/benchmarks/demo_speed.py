"""Benchmark: the wall and CPU time of the whole ``rodnet demo`` (the Cosserat run, the lumped
reference, their pictures, the movie, the comparison), on both cores and on one.

Each source tree (a git revision of this repository extracted with ``git archive``, or this
working tree) runs ``python -m rodnet demo -o OUT --quiet`` in a child process with that tree
first on ``PYTHONPATH`` and the Python of this process (its packages), after a short run of the
same demo (``simulation.duration=0.02``) that compiles the tree's kernels into its numba cache,
so that every measured run is warm. ``--cpus 0`` runs it under ``taskset -c 0`` with
``--threads 1`` (one core: the machine with a single core; numba would otherwise start two
threads on it), ``--cpus 0,1`` on both cores as the demo chooses.

Per run: the wall time, the CPU time (user + system) of the child and every process it waited
for (the lumped run's child, the rendering), the 1-minute load average before and after (the
machine may be shared: wall times grow with its load, CPU times hardly), the Cosserat run's
integration time and steps and the lumped run's integration time from their ``summary.json``,
and the largest mouth areas (every revision must compute the same numbers). Writes
``results/demo_speed.md``.

Usage, from the repository root::

    python validation/benchmarks/demo_speed.py --rev main --rev HEAD --cpus 0,1 --cpus 0
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parents[1]
sys.path.insert(0, str(HERE))
from cold_start import extract, read_rows  # noqa: E402  (git archive of a revision)


def tree_of(rev: str, into: Path) -> Path:
    """The tree of ``rev`` (a git revision; ``.`` this working tree) under ``into``."""
    return ROOT if rev == "." else extract(rev, into)


def children_cpu() -> float:
    """CPU seconds (user + system) of the processes this one has waited for, theirs included."""
    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


def demo(tree: Path, out: Path, cpus: str, overrides: list[str]) -> dict:
    """One ``rodnet demo`` of ``tree`` into ``out`` on the cores ``cpus``; its measurements."""
    command = [sys.executable, "-m", "rodnet", "demo", "-o", str(out), "--quiet"]
    command += [a for o in overrides for a in ("--set", o)]
    if len(cpus.split(",")) == 1:
        command = ["taskset", "-c", cpus, *command, "--threads", "1"]
    env = {**os.environ, "PYTHONPATH": str(tree)}
    load = os.getloadavg()[0]
    cpu0, start = children_cpu(), time.perf_counter()
    done = subprocess.run(command, env=env, cwd=out.parent, capture_output=True, text=True)
    wall, cpu = time.perf_counter() - start, children_cpu() - cpu0
    if done.returncode != 0:
        raise RuntimeError(f"rodnet demo failed ({done.returncode}): {done.stderr[-2000:]}")
    rods = json.loads((out / "summary.json").read_text())
    lumped = json.loads((out / "lumped" / "summary.json").read_text())
    return {"wall": wall, "cpu": cpu, "load": load, "load_after": os.getloadavg()[0],
            "rods_wall": rods["wall_time_s"], "rods_steps": rods["steps"],
            "rods_threads": rods["threads"], "lumped_wall": lumped["wall_time_s"],
            "rods_area": rods["metrics"]["max_mouth_area"],
            "lumped_area": lumped["metrics"]["max_mouth_area"],
            "movie": (out / "deployment.mp4").is_file(),
            "comparison": (out / "comparison.png").is_file()}


def table(rows: list[dict]) -> str:
    lines = ["| revision | cores | load before / after | wall [s] | CPU [s] | Cosserat run "
             "[s] (steps, threads) | lumped run [s] | max mouth area Cosserat / lumped [m^2] "
             "| movie, comparison |",
             "|---|---|---|---:|---:|---:|---:|---:|---|"]
    for r in rows:
        lines.append(
            f"| {r['rev']} ({r['commit']}) | {r['cpus']} | {r['load']:.2f} / "
            f"{r['load_after']:.2f} | {r['wall']:.1f} | {r['cpu']:.1f} | {r['rods_wall']:.1f} "
            f"({r['rods_steps']}, {r['rods_threads']}) | {r['lumped_wall']:.2f} | "
            f"{r['rods_area']:.3f} / {r['lumped_area']:.3f} | "
            f"{'yes' if r['movie'] else 'no'}, {'yes' if r['comparison'] else 'no'} |")
    return "\n".join(lines)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rev", action="append", required=True,
                        help="git revision, or . for this working tree (repeat)")
    parser.add_argument("--cpus", action="append", default=None,
                        help="cores as taskset -c takes them: 0,1 (both, the default) or 0")
    parser.add_argument("--repeat", type=int, default=1, help="runs of each (default 1)")
    parser.add_argument("--set", dest="overrides", action="append", default=[],
                        metavar="KEY=VALUE", help="rodnet demo --set (repeatable)")
    parser.add_argument("--rows", type=Path, default=None,
                        help="JSON lines of earlier measurements to add to the table")
    parser.add_argument("-o", "--output", type=Path, default=HERE / "results" / "demo_speed.md")
    args = parser.parse_args()
    rows = read_rows(args.rows)
    with tempfile.TemporaryDirectory(prefix="rodnet-demo-speed-") as work:
        for k, rev in enumerate(args.rev):
            tree = tree_of(rev, Path(work) / f"src-{k}")
            commit = subprocess.run(["git", "-C", str(ROOT), "rev-parse", "--short",
                                     "HEAD" if rev == "." else rev], check=True,
                                    capture_output=True, text=True).stdout.strip()
            demo(tree, Path(work) / f"warm-{k}", "0,1", [*args.overrides,
                                                          "simulation.duration=0.02"])
            for cpus in args.cpus or ["0,1"]:
                for n in range(args.repeat):
                    row = {"rev": rev, "commit": commit, "cpus": cpus,
                           **demo(tree, Path(work) / f"out-{k}-{cpus}-{n}", cpus,
                                  args.overrides)}
                    print(json.dumps(row), flush=True)
                    rows.append(row)
    text = table(rows)
    print(text)
    args.output.parent.mkdir(parents=True, exist_ok=True)
    args.output.write_text("# Wall and CPU time of `rodnet demo`\n\nWritten by "
                           "`validation/benchmarks/demo_speed.py` (warm kernels; the load "
                           "average of the shared machine beside each run).\n\n" + text + "\n")


if __name__ == "__main__":
    sys.exit(main())
