"""Benchmark: the fixed-pattern sparse LU (``rodnet.sparse_lu.StaticPatternLU``) of this tree
against an older revision, on the net's Newton matrices and in an implicit run.

Two measurements, each with both trees in child processes (``python -P`` with the tree on
``PYTHONPATH``; the old revision is extracted with ``git archive``), interleaved:

- *Matrices*: the iteration matrices of ``linear_solvers.py`` (``GA`` and ``BE`` forms at
  t = 0.5 s of an explicit reference deployment, rigid knots; built once and cached by that
  script's ``build_case``). Per matrix: the numeric factorisation of a matrix whose pattern
  was analysed on another one (t = 0.49 s), the solve, the smallest time of ``--repeats``
  rounds of 20 (factorisation) and 50 (solve) calls, and the residual ``|A x - b|_inf /
  |b|_inf`` of a random ``b``.
- *Runs*: the reference deployment with Cosserat threads, pinned and rigid knots, two elements
  per thread and default settings (BDF2, adaptive steps) for ``--seconds`` (default 0.3)
  simulated: CPU seconds of the run, steps, Newton iterations, factorisations and the largest
  mouth area, ``--rounds`` rounds (default 2), the least CPU time kept. One thread each
  (``NUMBA_NUM_THREADS=1``). These time the whole tree: every change between the two
  revisions, not the LU alone.

Usage, from the repository root::

    .venv/bin/python validation/benchmarks/static_lu.py --old 1d37d98

Writes ``results/static_lu.md``.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parents[1]
sys.path.insert(0, str(HERE))

from linear_solvers import CASES, build_case  # noqa: E402

FORMS = ("GA", "BE")
CACHE = Path(tempfile.gettempdir()) / "rodnet_linear_solvers"

MATRIX_CHILD = r"""
import json, sys, time
import numpy as np, scipy.sparse as sp
from rodnet.sparse_lu import StaticPatternLU
path, forms, repeats = sys.argv[1], sys.argv[2].split(","), int(sys.argv[3])
data = np.load(path)
def matrix(key):
    return sp.csr_matrix((data[key + "__data"], data[key + "__indices"], data[key + "__indptr"]),
                         shape=tuple(data[key + "__shape"]))
rows = {}
for form in forms:
    A, A_prev = matrix(form), matrix(form + "_prev")
    lu = StaticPatternLU(A_prev)
    assert lu.factorize(A)
    b = np.random.default_rng(0).standard_normal(A.shape[0])
    x = lu.solve(b)
    factor = solve = float("inf")
    for _ in range(repeats):
        t = time.perf_counter()
        for _ in range(20):
            lu.factorize(A)
        factor = min(factor, (time.perf_counter() - t) / 20)
        t = time.perf_counter()
        for _ in range(50):
            lu.solve(b)
        solve = min(solve, (time.perf_counter() - t) / 50)
    rows[form] = {"factor_ms": 1e3 * factor, "solve_ms": 1e3 * solve, "n": A.shape[0],
                  "entries": int(lu.factor_entries),
                  "residual": float(np.abs(A @ x - b).max() / np.abs(b).max())}
print(json.dumps(rows))
"""

RUN_CHILD = r"""
import json, sys, tempfile, time
from rodnet.data import reference_scene_text
from rodnet.run import run
from rodnet.scene import scene_from_toml
seconds, knots = sys.argv[1], sys.argv[2]
overrides = ["model.type=cosserat", "model.knots=" + knots, "model.elements_per_thread=2",
             "simulation.duration=" + seconds, "output.vtk=false", "output.picture=false",
             "output.plot=false"]
cpu = time.process_time()
r = run(scene_from_toml(reference_scene_text(), overrides), tempfile.mkdtemp(), progress=False)
cpu = time.process_time() - cpu
s = r.summary
print(json.dumps({"cpu": cpu, "status": s["status"], "steps": s["steps"],
                  "iterations": s["newton_iterations"], "factorizations": s["factorizations"],
                  "area": float(r.arrays["mouth_area"].max())}))
"""


def child(code: str, args: list[str], tree: Path) -> dict:
    env = {**os.environ, "PYTHONPATH": str(tree), "NUMBA_NUM_THREADS": "1",
           "OPENBLAS_NUM_THREADS": "1", "OMP_NUM_THREADS": "1"}
    done = subprocess.run([sys.executable, "-P", "-c", code, *args], capture_output=True,
                          text=True, env=env)
    if done.returncode != 0:
        raise RuntimeError(done.stderr.strip()[-2000:])
    return json.loads(done.stdout.strip().splitlines()[-1])


def extract(revision: str, into: Path) -> Path:
    """The tree of ``revision`` (``git archive``) in ``into``."""
    archive = subprocess.run(["git", "-C", str(ROOT), "archive", revision], check=True,
                             capture_output=True).stdout
    into.mkdir(parents=True, exist_ok=True)
    subprocess.run(["tar", "-x", "-C", str(into)], input=archive, check=True)
    return into


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--old", required=True, help="the git revision to compare with")
    parser.add_argument("--cases", nargs="+", choices=list(CASES), default=list(CASES))
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--seconds", type=float, default=0.3)
    parser.add_argument("--rounds", type=int, default=2)
    parser.add_argument("--output", type=Path, default=HERE / "results" / "static_lu.md")
    args = parser.parse_args()
    old_rev = subprocess.run(["git", "-C", str(ROOT), "rev-parse", "--short", args.old],
                             check=True, capture_output=True, text=True).stdout.strip()
    trees = {"old": extract(args.old, Path(tempfile.mkdtemp(prefix="rodnet-old-"))),
             "new": ROOT}
    for name in args.cases:
        build_case(name, CACHE)
    # a first call per tree compiles its kernels into the tree's cache (not timed)
    for tree in trees.values():
        child(MATRIX_CHILD, [str(CACHE / f"{args.cases[0]}.npz"), "GA", "1"], tree)
    lines = [
        "# The fixed-pattern sparse LU: 3 x 3 blocks against scalar entries",
        "",
        f"Written by `validation/benchmarks/static_lu.py --old {args.old}`: old = {old_rev}, "
        "new = this tree. One thread. Times are the least of the repeats; the machine is "
        "shared, so the ratios (old / new, measured in one run) are what to compare.",
        "",
        "## Numeric factorisation and solve on the net's iteration matrices",
        "",
        "| case | form | unknowns | factor entries old / new | factor ms old | factor ms new "
        "| old / new | solve ms old | solve ms new | old / new | residual old | residual new |",
        "|---|---|---:|---|---:|---:|---:|---:|---:|---:|---:|---:|",
    ]
    for name in args.cases:
        path = str(CACHE / f"{name}.npz")
        got = {k: child(MATRIX_CHILD, [path, ",".join(FORMS), str(args.repeats)], tree)
               for k, tree in trees.items()}
        for form in FORMS:
            o, n = got["old"][form], got["new"][form]
            lines.append(
                f"| {CASES[name][0]} | {form} | {n['n']:,} | {o['entries']:,} / "
                f"{n['entries']:,} | {o['factor_ms']:.2f} | {n['factor_ms']:.2f} | "
                f"{o['factor_ms'] / n['factor_ms']:.2f} | {o['solve_ms']:.3f} | "
                f"{n['solve_ms']:.3f} | {o['solve_ms'] / n['solve_ms']:.2f} | "
                f"{o['residual']:.1e} | {n['residual']:.1e} |")
        print("\n".join(lines[-len(FORMS):]), flush=True)
    lines += [
        "",
        f"## The Cosserat net at default settings, first {args.seconds:g} s",
        "",
        "| knots | tree | status | steps | Newton iterations | factorisations | CPU s (least of "
        f"{args.rounds}) | CPU ms per iteration | largest mouth area m^2 |",
        "|---|---|---|---:|---:|---:|---:|---:|---:|",
    ]
    ratios = []
    for knots in ("pinned", "rigid"):
        runs: dict[str, list[dict]] = {"old": [], "new": []}
        for _ in range(args.rounds):
            for k, tree in trees.items():
                runs[k].append(child(RUN_CHILD, [str(args.seconds), knots], tree))
                print(knots, k, runs[k][-1], flush=True)
        best = {k: min(rows, key=lambda row: row["cpu"]) for k, rows in runs.items()}
        for k, r in best.items():
            lines.append(f"| {knots} | {k} | {r['status']} | {r['steps']:,} | "
                         f"{r['iterations']:,} | {r['factorizations']:,} | {r['cpu']:.1f} | "
                         f"{1e3 * r['cpu'] / r['iterations']:.1f} | {r['area']:.3f} |")
        per_iteration = (best["old"]["cpu"] / best["old"]["iterations"]) / \
            (best["new"]["cpu"] / best["new"]["iterations"])
        ratios.append(f"{knots} knots: CPU time old / new {best['old']['cpu'] / best['new']['cpu']:.2f}, "
                      f"per Newton iteration {per_iteration:.2f}")
    lines += ["", "; ".join(ratios) + "."]
    text = "\n".join(lines) + "\n"
    args.output.write_text(text)
    print(text)


if __name__ == "__main__":
    main()
