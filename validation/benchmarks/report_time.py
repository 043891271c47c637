"""Benchmark: how long the quick validation report takes, ``rodnet validate --report DIR`` (the
cases not marked slow, no pytest run), as a user runs it: a new Python process each time.

Reports per repeat the wall time, the CPU time of the process (user + system, from
``resource.getrusage(RUSAGE_CHILDREN)``), the report's own ``wall_time_s`` (from the first case
to the written page, without the imports) and the machine's load average before the run. On a
machine shared with other work the wall time grows with the load; the CPU time hardly does.
The compiled kernels are cached by the runs before (a first run after a change of the kernels
adds their compilation). Writes ``results/report_time.md``.

Usage: ``python validation/benchmarks/report_time.py [--repeats N]``
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).parent
ROOT = HERE.parents[1]


def one_run(folder: Path) -> dict[str, float]:
    """Build the quick report into ``folder``; wall, CPU and report times [s], load average."""
    load = os.getloadavg()[0]
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    start = time.perf_counter()
    done = subprocess.run([sys.executable, "-m", "rodnet", "validate", "--cases",
                           str(ROOT / "validation" / "cases"), "--report", str(folder),
                           "-o", str(folder / "md")], capture_output=True, text=True, cwd=ROOT)
    wall = time.perf_counter() - start
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if done.returncode != 0:
        raise SystemExit(f"rodnet validate --report failed:\n{done.stdout}\n{done.stderr}")
    header = json.loads((folder / "report.json").read_text())["header"]
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return {"wall": wall, "cpu": cpu, "report": header["wall_time_s"], "load": load,
            "cases": header["verdict"]["cases_run"], "checks": header["verdict"]["checks_total"]}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args()
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for i in range(args.repeats):
            rows.append(one_run(Path(tmp) / f"r{i}"))
            print(rows[-1], flush=True)
    lines = ["# Time to build the quick validation report", "",
             f"`rodnet validate --report DIR` on {os.cpu_count()} cores "
             f"({platform.processor() or platform.machine()}), Python {platform.python_version()}; "
             f"{rows[0]['cases']} cases, {rows[0]['checks']} checks.", "",
             "| run | wall s | CPU s (user + system) | report's own wall s | load average before |",
             "|---|---|---|---|---|"]
    lines += [f"| {i + 1} | {r['wall']:.1f} | {r['cpu']:.1f} | {r['report']:.1f} | {r['load']:.1f} |"
              for i, r in enumerate(rows)]
    lines += ["", "The report's own wall time runs from the first case to the written page; the "
              "rest of the wall time is starting Python and importing rodnet, NumPy, SciPy, "
              "Numba and Matplotlib."]
    out = HERE / "results" / "report_time.md"
    out.write_text("\n".join(lines) + "\n")
    print(f"written {out}")


if __name__ == "__main__":
    main()
