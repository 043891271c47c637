"""Benchmark: the cold start of ``rodnet demo``, the first run after installing, against a warm run.

For each source tree (git revisions of this repository, extracted with ``git archive``) and each
kind of install, rodnet is installed without its dependencies into a prepared virtual
environment (one made with ``python3 -m venv VENV && VENV/bin/pip install -e '.[viz]'``, which
holds numpy, scipy, numba, pyvista and the rest):

- ``editable``: ``pip install -e SOURCE`` as the README does; every ``__pycache__`` under the
  package is deleted first (a fresh clone: no byte code and no numba kernels);
- ``installed``: ``pip install SOURCE`` into site-packages (pip writes the byte code, not the
  kernels); numba's kernel files (``*.nbi``, ``*.nbc``) are deleted after installing;
- ``editable+compile``: ``editable``, then ``rodnet compile`` as the README's set-up runs it
  (the kernels of the demo and of small rod runs compiled ahead of time into the cache beside
  the sources); its wall and CPU seconds are the column ``compile at install``.

``NUMBA_CACHE_DIR`` is removed from the environment, so numba caches beside the sources as it
does for a user. Then ``rodnet demo -o OUT`` (the reference deployment with Cosserat threads and
the lumped reference, their VTK frames, pictures and movie; ``--set`` shortens it, e.g.
``simulation.duration=0.1``: compiling does not depend on the duration) runs twice in a child
process: cold (the first run after installing) and warm. The child is the ``rodnet`` command's
own entry point (``rodnet.cli.main``) with timers around it, read from the outside as wall
times since the child was started and as CPU times (user + system) of the child and of its
subprocesses (rendering, and the lumped run where it runs in one). The phases are those of the
first (Cosserat) run:

- ``import``: ``import rodnet.cli`` done (interpreter start included);
- ``first frame``: the first frame interval (0.01 s) computed: compiling or loading the
  explicit loop, and the scene's set-up before it;
- ``run``: the simulation done (results written);
- ``render``: the pictures' subprocess (``rodnet.viz.figures``: pyvista, VTK, matplotlib);
- ``total``: the process ended (both runs, their pictures, the comparison).

The machine is shared: wall times grow with its load (the 1-minute load average is printed with
each run); the CPU times are what the run itself cost. Writes ``results/cold_start.md``.

Usage, from the repository root (VENV prepared as above)::

    python validation/benchmarks/cold_start.py --venv VENV --rev main --rev HEAD \\
        --set simulation.duration=0.1
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parents[1]

DRIVER = r"""
import json, os, resource, sys, time
marks = {}
def mark(name):
    self = resource.getrusage(resource.RUSAGE_SELF)
    kids = resource.getrusage(resource.RUSAGE_CHILDREN)
    # the first of each: the Cosserat run's phases, not the lumped run's after it
    marks.setdefault(name, (time.time(), self.ru_utime + self.ru_stime,
                            kids.ru_utime + kids.ru_stime))
import rodnet.cli
mark("import")
import rodnet.viz.figures as figures
runner = sys.modules["rodnet.run"]  # the module (rodnet.run is also the package's function)
explicit = runner.integrate_explicit
def integrate_explicit(system, state, times, on_frame, *args, **kwargs):
    frames = [0]
    def on_frame_marked(t, s):
        on_frame(t, s)
        frames[0] += 1
        if frames[0] == 2:
            mark("first frame")
    return explicit(system, state, times, on_frame_marked, *args, **kwargs)
runner.integrate_explicit = integrate_explicit
render = figures.render_in_subprocess
def render_marked(*args, **kwargs):
    mark("run")
    try:
        return render(*args, **kwargs)
    finally:
        mark("render")
figures.render_in_subprocess = render_marked
try:
    status = rodnet.cli.main(sys.argv[2:])
finally:
    mark("total")
    with open(sys.argv[1], "w") as f:
        json.dump(marks, f)
sys.exit(status)
"""

PHASES = ("import", "first frame", "run", "render", "total")


def _python(venv: Path) -> Path:
    return venv / "bin" / "python"


def extract(rev: str, into: Path) -> Path:
    """The tree of ``rev`` (a git revision of this repository) under ``into``."""
    into.mkdir(parents=True)
    archive = subprocess.run(["git", "-C", str(ROOT), "archive", rev], check=True,
                             capture_output=True).stdout
    subprocess.run(["tar", "-x", "-C", str(into)], input=archive, check=True)
    return into


def read_rows(path: Path | None) -> list[dict]:
    """Earlier measurements: the JSON lines of ``path`` (none without a path)."""
    if path is None:
        return []
    return [json.loads(line) for line in path.read_text().splitlines() if line.strip()]


def install(venv: Path, source: Path, mode: str) -> Path:
    """Install ``source`` into ``venv`` (``editable`` or ``installed``) without dependencies and
    remove what a fresh install would not have; returns the package folder that runs."""
    pip = [str(_python(venv)), "-m", "pip", "install", "-q", "--no-deps", "--force-reinstall"]
    subprocess.run([*pip[:3], "uninstall", "-q", "-y", "rodnet"], check=False)
    purelib = subprocess.run([str(_python(venv)), "-c",
                              "import sysconfig; print(sysconfig.get_paths()['purelib'])"],
                             check=True, capture_output=True, text=True).stdout.strip()
    # pip leaves the kernel files of an earlier install (not in its record) in a bare folder
    shutil.rmtree(Path(purelib) / "rodnet", ignore_errors=True)
    if mode == "editable":
        for cache in (source / "rodnet").rglob("__pycache__"):
            shutil.rmtree(cache)
        subprocess.run([*pip, "-e", str(source)], check=True)
    else:
        subprocess.run([*pip, str(source)], check=True)
    where = subprocess.run([str(_python(venv)), "-c",
                            "import rodnet.kernels, pathlib; "
                            "print(pathlib.Path(rodnet.kernels.__file__).parents[1])"],
                           check=True, capture_output=True, text=True, cwd=tempfile.gettempdir())
    package = Path(where.stdout.strip())
    for kernel in [*package.rglob("*.nbi"), *package.rglob("*.nbc"),
                   *package.rglob("rodnet-kernels.sha256")]:
        kernel.unlink()
    return package


def run_demo(venv: Path, out: Path, overrides: list[str] = []
             ) -> dict[str, tuple[float, float, float]]:
    """One ``rodnet demo -o out`` (with ``--set`` of each of ``overrides``) in a child process:
    per phase, (wall s since the start, CPU s of the child, CPU s of its subprocesses)."""
    env = {k: v for k, v in os.environ.items() if k not in ("NUMBA_CACHE_DIR", "PYTHONPATH")}
    marks_file = out.with_suffix(".json")
    start = time.time()
    done = subprocess.run([str(_python(venv)), "-c", DRIVER, str(marks_file), "demo", "-o",
                           str(out), "--quiet", *(a for o in overrides for a in ("--set", o))],
                          env=env, cwd=out.parent, capture_output=True,
                          text=True)
    if done.returncode != 0:
        raise RuntimeError(f"rodnet demo failed: {done.stderr[-2000:]}")
    marks = json.loads(marks_file.read_text())
    return {k: (w - start, cpu, kids) for k, (w, cpu, kids) in marks.items()}


def precompile(venv: Path, cwd: Path) -> tuple[float, float]:
    """``rodnet compile`` in a child process: its wall and CPU seconds (its workers included)."""
    env = {k: v for k, v in os.environ.items() if k not in ("NUMBA_CACHE_DIR", "PYTHONPATH")}
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    start = time.time()
    subprocess.run([str(_python(venv)), "-m", "rodnet", "compile"], env=env, cwd=cwd, check=True,
                   capture_output=True)
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime + after.ru_stime) - (before.ru_utime + before.ru_stime)
    return time.time() - start, cpu


def measure(venv: Path, revs: list[str], modes: list[str], work: Path,
            overrides: list[str] = []) -> list[dict]:
    rows = []
    for rev in revs:
        source = extract(rev, work / f"src-{len(rows)}")
        commit = subprocess.run(["git", "-C", str(ROOT), "rev-parse", "--short", rev],
                                check=True, capture_output=True, text=True).stdout.strip()
        for mode in modes:
            package = install(venv, source, mode.split("+")[0])
            compiled = precompile(venv, work) if mode.endswith("+compile") else None
            for run in ("cold", "warm"):
                load = os.getloadavg()[0]
                marks = run_demo(venv, work / f"out-{commit}-{mode}-{run}", overrides)
                kernels = len(list(package.rglob("*.nbi")))
                row = {"rev": rev, "commit": commit, "mode": mode, "run": run, "load": load,
                       "set": overrides,
                       "kernels": kernels, "marks": marks, "compile": compiled}
                print(json.dumps(row), flush=True)
                rows.append(row)
    return rows


def _cell(marks: dict, phase: str, previous: str | None) -> str:
    """``wall (cpu)`` of a phase: from the start for import and total, else since the phase
    before."""
    w, cpu, kids = marks[phase]
    if phase == "render":
        w0, _, kids0 = marks["run"]
        return f"{w - w0:.1f} ({kids - kids0:.1f})"
    if previous is None:
        return f"{w:.1f} ({cpu + kids:.1f})"
    w0, cpu0, _ = marks[previous]
    return f"{w - w0:.1f} ({cpu - cpu0:.1f})"


def table(rows: list[dict]) -> str:
    lines = ["| revision | install | run | load | kernel files | import | first frame | run "
             "after it | render | total | cold - warm | compile at install |",
             "|---|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|"]
    warm = {(r["commit"], r["mode"]): r["marks"] for r in rows if r["run"] == "warm"}
    for r in rows:
        m = r["marks"]
        cells = [_cell(m, "import", None), _cell(m, "first frame", "import"),
                 _cell(m, "run", "first frame"), _cell(m, "render", None),
                 _cell(m, "total", None)]
        extra = ""
        if r["run"] == "cold":
            w = warm[(r["commit"], r["mode"])]
            extra = (f"{m['total'][0] - w['total'][0]:.1f} "
                     f"({sum(m['total'][1:]) - sum(w['total'][1:]):.1f})")
        compiled = r.get("compile")
        at_install = f"{compiled[0]:.1f} ({compiled[1]:.1f})" if compiled and r["run"] == "cold" \
            else ""
        lines.append(f"| {r['rev']} ({r['commit']}) | {r['mode']} | {r['run']} | {r['load']:.1f} "
                     f"| {r['kernels']} | " + " | ".join(cells) + f" | {extra} | {at_install} |")
    return "\n".join(lines)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--venv", type=Path, required=True,
                        help="virtual environment with rodnet's dependencies ('.[viz]')")
    parser.add_argument("--rev", action="append", required=True, help="git revision (repeat)")
    parser.add_argument("--mode", action="append",
                        choices=("editable", "installed", "editable+compile"),
                        help="kinds of install (default: both)")
    parser.add_argument("--set", dest="overrides", action="append", default=[],
                        metavar="KEY=VALUE", help="rodnet demo --set (repeatable), e.g. "
                        "simulation.duration=0.1: compiling does not depend on the duration")
    parser.add_argument("--rows", type=Path, default=None,
                        help="JSON lines of earlier measurements to add to the table")
    parser.add_argument("-o", "--output", type=Path, default=HERE / "results" / "cold_start.md")
    args = parser.parse_args()
    rows = read_rows(args.rows)
    with tempfile.TemporaryDirectory(prefix="rodnet-cold-") as work:
        rows += measure(args.venv.resolve(), args.rev, args.mode or ["editable", "installed"],
                        Path(work), args.overrides)
    text = table(rows)
    print(text)
    args.output.parent.mkdir(parents=True, exist_ok=True)
    args.output.write_text("# Cold start of `rodnet demo`\n\nWritten by "
                           "`validation/benchmarks/cold_start.py`.\n\n" + text + "\n")


if __name__ == "__main__":
    sys.exit(main())
