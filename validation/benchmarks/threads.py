"""Benchmark: wall and CPU time of the compiled parallel loops, quiet and beside another job.

Explicit Cosserat nets (two elements per thread, rigid knots: the 11 x 11 net and the 21 x 21
reference net, 0.3 s of the reference deployment) are run through the public command line
(``rodnet demo --set ...``) in a child process, once per thread setting, on a quiet machine and
beside one and beside two busy-loop processes. The child's wall time
and CPU time (user + system, from ``resource.getrusage``) are measured around the whole process;
the integration wall time (``summary.json`` ``wall_time_s``) is given too.

Settings: ``--threads 1``, ``--threads 2`` and the default (one thread below
``rodnet.kernels.threads.PARALLEL_FROM`` elements, every core above), with rodnet's wait policy
(``GOMP_SPINCOUNT`` 1000); and, as the old behaviour, two threads with GNU OpenMP's default
spinning (``GOMP_SPINCOUNT`` 300000). With ``--old PATH`` (a source tree of an older rodnet) its
default run is added. Prints a Markdown table and writes ``results/threads.md``.

Usage, from the repository root: ``python validation/benchmarks/threads.py [--old ../old]``
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

HERE = Path(__file__).parent
NETS = {"11 x 11": 11, "21 x 21": 21}
BASE = ["model.type=cosserat", "model.elements_per_thread=2", "simulation.integrator=explicit",
        "simulation.duration=0.3", "output.vtk=false", "output.picture=false",
        "output.plot=false"]
HOG = "import time\nend = time.time() + 3600\nwhile time.time() < end: pass\n"


def child(ns: int, args: list[str], env: dict[str, str], out: Path) -> dict[str, float]:
    """One ``rodnet demo`` run in a child process: its wall and CPU seconds and the
    integration wall time."""
    sets = [a for s in BASE + [f"net.nodes_per_side={ns}"] for a in ("--set", s)]
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    start = time.perf_counter()
    # -P: the working directory does not shadow the tree on PYTHONPATH
    done = subprocess.run([sys.executable, "-P", "-m", "rodnet", "demo", "--quick", "-o", str(out),
                           "--quiet",
                           *sets, *args], env=env, capture_output=True, text=True)
    wall = time.perf_counter() - start
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if done.returncode != 0:
        raise RuntimeError(done.stderr[-2000:])
    summary = json.loads((out / "summary.json").read_text())
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return {"wall": wall, "cpu": cpu, "integration": summary["wall_time_s"],
            "threads": summary.get("threads", 0)}


def settings(old: Path | None) -> dict[str, tuple[list[str], dict[str, str]]]:
    """Name -> (extra command-line arguments, environment) of every setting measured."""
    env = {k: v for k, v in os.environ.items() if k not in ("GOMP_SPINCOUNT", "NUMBA_NUM_THREADS")}
    out = {"1 thread": (["--threads", "1"], env),
           "2 threads": (["--threads", "2"], env),
           "default": ([], env),
           "2 threads, OpenMP's default spinning": (["--threads", "2"],
                                                     {**env, "GOMP_SPINCOUNT": "300000"})}
    if old is not None:
        out["old rodnet (default)"] = ([], {**env, "PYTHONPATH": str(old)})
    return out


CROSSOVER = (3, 5, 7, 9, 11, 15, 21)
"""Knots per side of the nets of the crossover table (2 Ns (Ns - 1) + 4 threads, 2 elements
each: 32 to 1688 elements)."""


def crossover(tmp: Path) -> list[str]:
    """Markdown rows: integration wall time per step with one and two threads, quiet."""
    env = {k: v for k, v in os.environ.items() if k != "NUMBA_NUM_THREADS"}
    rows = []
    for ns in CROSSOVER:
        per_step = []
        for threads in ("1", "2"):
            extra = ["--threads", threads, "--set", "simulation.duration=0.1"]
            child(ns, extra, env, tmp / "warm")
            best = min(child(ns, extra, env, tmp / "c")["integration"] for _ in range(2))
            steps = json.loads((tmp / "c" / "summary.json").read_text())["steps"]
            per_step.append(1e6 * best / steps)
        elements = 2 * (2 * ns * (ns - 1) + 4)
        rows.append(f"| {ns} x {ns} | {elements} | {per_step[0]:.1f} | {per_step[1]:.1f} | "
                    f"{per_step[0] / per_step[1]:.2f} |")
        print(rows[-1], flush=True)
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--old", type=Path, default=None, help="source tree of an older rodnet")
    args = parser.parse_args()
    rows = []
    with tempfile.TemporaryDirectory(prefix="rodnet-threads-") as tmp:
        cross = crossover(Path(tmp))
        for net, ns in NETS.items():
            for name, (extra, env) in settings(args.old).items():
                child(ns, extra, env, Path(tmp) / "warm")  # compiled kernels in the cache
                measured = [child(ns, extra, env, Path(tmp) / "q")]
                for n_hogs in (1, 2):
                    hogs = [subprocess.Popen([sys.executable, "-c", HOG]) for _ in range(n_hogs)]
                    try:
                        time.sleep(0.5)
                        measured.append(child(ns, extra, env, Path(tmp) / "l"))
                    finally:
                        for hog in hogs:
                            hog.kill()
                            hog.wait()
                rows.append((net, name, measured))
                print(net, name, measured, flush=True)
    lines = ["| net | setting | threads | quiet: wall / CPU [s] | one busy process: wall / CPU [s] "
             "| two busy processes: wall / CPU [s] |", "|---|---|---|---|---|---|"]
    for net, name, measured in rows:
        cells = " | ".join(f"{m['wall']:.1f} / {m['cpu']:.1f}" for m in measured)
        lines.append(f"| {net} | {name} | {measured[0]['threads'] or '-'} | {cells} |")
    text = ("# Threads of the compiled loops: quiet and beside busy processes\n\n"
            "Explicit Cosserat nets, two elements per thread, rigid knots, 0.3 s of the reference "
            "deployment; wall and CPU seconds of the whole `rodnet demo` process (start-up "
            "included), on a 2-core machine: quiet, beside one busy-loop process, and beside "
            "two (both cores taken).\n\n"
            + "\n".join(lines) + "\n\n## Where two threads pay\n\n"
            "Integration wall time per explicit step (best of two 0.1 s runs, quiet), one and "
            "two threads; speed-up = one / two.\n\n"
            "| net | elements | 1 thread [us/step] | 2 threads [us/step] | speed-up |\n"
            "|---|---|---|---|---|\n" + "\n".join(cross) + "\n")
    (HERE / "results" / "threads.md").write_text(text)
    print(text)


if __name__ == "__main__":
    main()
