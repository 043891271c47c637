"""Benchmark: sparse direct solvers on the Newton iteration matrices of the reference net.

What it measures. The reference deployment (``rodnet demo``'s scene) is run explicitly for
0.5 s (the net deployed and partly taut); at the frames t = 0.49 s and t = 0.5 s the system
prepared for generalized-alpha assembles ``system.iteration_matrix`` (h = 1e-3) in three forms:

- ``GA``: ``diag(M) + 0.6 h C + 0.3 h^2 K``, the generalized-alpha matrix up to scaling
  (non-symmetric);
- ``BE``: ``diag(M) / h + C + h K``, backward Euler (non-symmetric);
- ``IP``: ``(S + S^T) / 2`` of ``diag(M) / h^2 + C / h + K``, the Hessian of the incremental
  potential (symmetric; it is BE's symmetric part divided by h);

and ``GA-sym``, the symmetric part ``(A + A^T) / 2`` of GA. Cases: Cosserat nets with rigid
knots, 21 x 21 knots at 1, 2 and 4 elements per thread and 41 x 41 at 2, and cable threads
(``model.bending = false``, ``model.torsion = false``, 2 elements per thread: 3 DOF per node).

Solvers, all timed in one process, interleaved (every repeat runs every solver once, in turn),
the smallest of ``--repeats`` (default 5) with ``time.perf_counter``:

- ``SuperLU``: ``scipy.sparse.linalg.splu(A.tocsc(), permc_spec="MMD_AT_PLUS_A",
  diag_pivot_thresh=0.0, options={"SymmetricMode": True})`` as rodnet calls it (no reuse of
  the analysis: every factorisation re-orders);
- ``StaticLU``: ``rodnet.sparse_lu.StaticPatternLU``: first = analysis + numeric, repeat =
  ``factorize`` of another matrix of the pattern;
- ``PARDISO-11`` (pypardiso, MKL, real non-symmetric) on A; first = phase 12, repeat = phase 11
  once on the other matrix then phase 22 (numeric only); solve = phase 33 (MKL's default
  iparm: METIS, matching and scaling, pivot perturbation, two refinement steps). ``PARDISO-2``
  (SPD) and ``PARDISO-(-2)`` (symmetric indefinite, Bunch-Kaufman within supernodes and pivot
  perturbation) on the upper triangle of a symmetric matrix, the same phases. pypardiso's
  public ``factorize``/``solve`` cannot reuse an analysis (a matrix that differs from its
  stored copy is analysed again, phase 12/13), so the phases are called through the
  wrapper's private ``_mkl_pardiso`` handle;
- ``CHOLMOD-simp`` / ``CHOLMOD-super`` (scikit-sparse): first = ``cholesky(A, mode=...)``,
  analysis = ``analyze(A, mode=...)``, repeat = ``F.cholesky_inplace(A)`` after an analysis of
  the other matrix (symbolic reuse), symmetric matrices only. Simplicial computes LDL'
  without pivoting and so also factorises an indefinite matrix (it raises nothing);
  supernodal computes LL' and raises ``CholmodNotPositiveDefiniteError`` unless the matrix is
  positive definite;
- ``CHOLMOD-sym+IR`` on a non-symmetric A: the CHOLMOD factor of A's symmetric part used in
  iterative refinement ``x += F(b - A x)`` until ``|A x - b| / |b| <= 1e-12``: solve time and
  the number of refinement steps.

"Repeat" is the cost of one factorisation inside Newton's method once the pattern is known.
rodnet's current default (``LinearSolver`` in ``rodnet/integrate/newton.py``) is SuperLU the
first time a pattern comes and ``StaticPatternLU``'s numeric pass once it repeats: the ratios
are to SuperLU (first factorisation) and to StaticLU (repeat factorisation, solve). Also per
matrix: the entries of the factors (LU: L + U; CHOLMOD simplicial: L with D on its diagonal;
supernodal: L with the supernodes' padding; PARDISO: its ``iparm(18)``), the residual ``|A x - b| / |b|`` of one solve with a
random ``b`` (also after the numeric-only refactorisation), and for the symmetric matrices
whether they are positive definite (CHOLMOD's LL'), their number of negative eigenvalues (the
negative pivots of LDL', Sylvester's law) and their smallest eigenvalue relative to the
largest diagonal entry (bisection on the inertia of ``S - s I``).

Threads: ``--threads`` (default 1) sets OPENBLAS_NUM_THREADS, MKL_NUM_THREADS, OMP_NUM_THREADS
and NUMBA_NUM_THREADS before numpy is imported; ``--two-thread-case`` (default: the largest
case run) is measured again in a child process with 2 threads, on the cached matrices.

Usage, from the repository root (needs the optional solvers: ``apt-get install -y
libsuitesparse-dev && .venv/bin/pip install scikit-sparse==0.4.16 pypardiso``; a solver that is
not installed is left out)::

    .venv/bin/python validation/benchmarks/linear_solvers.py   # every case, ~15 min (2 cores)
    .venv/bin/python validation/benchmarks/linear_solvers.py --cases net21-n2 cable21-n2 \\
        --forms GA IP --repeats 3 --no-two-thread

The assembled matrices are cached (``--cache``, default a folder in the temporary directory),
so that a second run skips the explicit deployments. Prints Markdown and writes it to
``results/linear_solvers.md`` (``--output``).
"""

from __future__ import annotations

import argparse
import gc
import json
import os
import platform
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).parent
ROOT = HERE.parents[1]

CASES = {
    # name: (label, overrides)
    "net21-n1": ("Cosserat net 21 x 21, n = 1", ["model.elements_per_thread=1"]),
    "net21-n2": ("Cosserat net 21 x 21, n = 2", ["model.elements_per_thread=2"]),
    "net21-n4": ("Cosserat net 21 x 21, n = 4", ["model.elements_per_thread=4"]),
    "net41-n2": ("Cosserat net 41 x 41, n = 2", ["model.elements_per_thread=2",
                                                  "net.nodes_per_side=41"]),
    "cable21-n2": ("cable threads 21 x 21, n = 2", ["model.elements_per_thread=2",
                                                    "model.bending=false", "model.torsion=false"]),
}
COMMON = ["model.type=cosserat", "model.knots=rigid", "simulation.duration=0.5",
          "simulation.integrator=explicit", "output.vtk=false", "output.picture=false",
          "output.plot=false"]
FORMS = ("GA", "GA-sym", "BE", "IP")
H = 1e-3
T_LATE, T_PREV = 0.5, 0.49


# ------------------------------------------------------------------------------------ matrices

def build_case(name: str, cache: Path) -> dict:
    """The case's matrices (CSR) at T_LATE (``A``) and T_PREV (``A_prev``, same pattern), from
    the cache or by an explicit run; plus facts about the run."""
    import numpy as np
    import scipy.sparse as sp

    path = cache / f"{name}.npz"
    meta_path = cache / f"{name}.json"
    if path.exists() and meta_path.exists():
        data = np.load(path)
        mats = {}
        for key in {k.rsplit("__", 1)[0] for k in data.files}:
            mats[key] = sp.csr_matrix((data[key + "__data"], data[key + "__indices"],
                                       data[key + "__indptr"]),
                                      shape=tuple(data[key + "__shape"]))
        return {"matrices": mats, **json.loads(meta_path.read_text())}

    from rodnet.data import reference_scene_text
    from rodnet.integrate.explicit import integrate_explicit
    from rodnet.run import prepare
    from rodnet.scene import scene_from_toml

    text = reference_scene_text()
    overrides = COMMON + CASES[name][1]
    p = prepare(scene_from_toml(text, overrides + ["simulation.integrator=explicit"]))
    frames = {}

    def keep(t: float, state) -> None:
        for target in (T_PREV, T_LATE):
            if abs(t - target) < 1e-9:
                frames[target] = (state.q.copy(), state.v.copy())

    start = time.perf_counter()
    integrate_explicit(p.system, p.state, p.times, keep)
    explicit_wall = time.perf_counter() - start
    implicit = prepare(scene_from_toml(text, overrides
                                       + ["simulation.integrator=generalized-alpha"]))
    system = implicit.system
    mass = system.dof_mass[system.free]
    forms = {"GA": (mass, 0.6 * H, 0.3 * H * H), "BE": (mass / H, 1.0, H),
             "IP": (mass / H**2, 1.0 / H, 1.0)}
    mats, kinds = {}, set()
    assembly = []
    for suffix, t in (("", T_LATE), ("_prev", T_PREV)):
        q, v = frames[t]
        for form, (diagonal, a, b) in forms.items():
            start = time.perf_counter()
            _, S = system.iteration_matrix(q, v, t, dq=np.zeros(system.n_dof),
                                           diagonal=diagonal, a=a, b=b)
            assembly.append(time.perf_counter() - start)
            kinds.add(type(S).__name__)
            if not sp.issparse(S):  # a BandedMatrix or dense array: small structures only
                S = sp.csr_matrix(S.toarray() if hasattr(S, "toarray") else S)
            S = sp.csr_matrix(S)
            S.sort_indices()
            if form == "IP":
                S = symmetric_part(S)
            mats[form + suffix] = S
            if form == "GA":
                mats["GA-sym" + suffix] = symmetric_part(S)
    rotation = np.zeros(system.n_dof, bool)
    rotation[system.rotation_dofs()] = True
    mats["rotation_mask"] = sp.csr_matrix(rotation[system.free].astype(float)[None, :])
    meta = {"n_dof": int(mats["GA"].shape[0]), "n_free": int(system.free.sum()),
            "explicit_wall_s": explicit_wall, "assembly_ms": 1e3 * min(assembly),
            "matrix_kinds": sorted(kinds),
            "asymmetry": float(sp.linalg.norm(mats["GA"] - mats["GA"].T)
                               / sp.linalg.norm(mats["GA"])),
            "asymmetry_BE": float(sp.linalg.norm(mats["BE"] - mats["BE"].T)
                                  / sp.linalg.norm(mats["BE"]))}
    cache.mkdir(parents=True, exist_ok=True)
    arrays = {}
    for key, m in mats.items():
        arrays.update({key + "__data": m.data, key + "__indices": m.indices,
                       key + "__indptr": m.indptr, key + "__shape": np.array(m.shape)})
    np.savez(path, **arrays)
    meta_path.write_text(json.dumps(meta))
    return {"matrices": mats, **meta}


def symmetric_part(A):
    """``(A + A^T) / 2`` with A's pattern, explicit zeros kept (a slack thread's entries are
    stored zeros: scipy's sum would drop them and change the pattern from step to step)."""
    import scipy.sparse as sp

    A = sp.csr_matrix(A)
    A.sort_indices()
    T = A.T.tocsr()
    T.sort_indices()
    if not same_pattern(A, T):
        raise ValueError("the iteration matrix is not structurally symmetric")
    return sp.csr_matrix(((A.data + T.data) * 0.5, A.indices.copy(), A.indptr.copy()),
                         shape=A.shape)


def same_pattern(A, B) -> bool:
    import numpy as np

    return np.array_equal(A.indptr, B.indptr) and np.array_equal(A.indices, B.indices)


# ------------------------------------------------------------------------------------- solvers

class Solver:
    """One candidate: ``first(A)`` (analysis + numeric), ``prepare(A_prev)`` (analysis only,
    once per repeat, untimed when ``reuse``), ``refactor(A)`` (numeric only), ``solve(b)``."""

    name = ""
    reuse = False
    symmetric_only = False

    def reset(self) -> None:
        """Untimed clean-up before ``first`` and ``analyse``."""

    def first(self, A) -> None: ...
    def analyse(self, A) -> None: ...
    def refactor(self, A) -> None: ...
    def solve(self, b): ...
    def factor_entries(self) -> int | None: return None
    def close(self) -> None: ...


class SuperLU(Solver):
    name = "SuperLU"

    def first(self, A) -> None:
        import scipy.sparse.linalg as spla

        self.lu = spla.splu(A.tocsc(), permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0,
                            options={"SymmetricMode": True})

    refactor = first

    def solve(self, b):
        return self.lu.solve(b)

    def factor_entries(self) -> int:
        return int(self.lu.nnz)


class StaticLU(Solver):
    name = "StaticLU"
    reuse = True

    def first(self, A) -> None:
        from rodnet.sparse_lu import StaticPatternLU

        self.lu = StaticPatternLU(A)
        if not self.lu.factorize(A):
            raise RuntimeError("StaticPatternLU: (nearly) zero pivot")

    def analyse(self, A) -> None:
        from rodnet.sparse_lu import StaticPatternLU

        self.lu = StaticPatternLU(A)

    def refactor(self, A) -> None:
        if not self.lu.factorize(A):
            raise RuntimeError("StaticPatternLU: (nearly) zero pivot")

    def solve(self, b):
        return self.lu.solve(b)

    def factor_entries(self) -> int:
        return int(self.lu.factor_entries)


class Cholmod(Solver):
    """scikit-sparse's CHOLMOD on a symmetric matrix, handed over as CSC without a copy (the CSR
    arrays of a symmetric matrix are its CSC arrays). ``simplicial`` computes LDL' (no
    pivoting: it factorises an indefinite matrix too, unless a pivot is zero), ``supernodal``
    LL' (it refuses a matrix that is not positive definite)."""

    reuse = True
    symmetric_only = True

    def __init__(self, mode: str) -> None:
        self.mode = mode
        self.name = "CHOLMOD-" + {"simplicial": "simp", "supernodal": "super"}[mode]

    @staticmethod
    def _csc(A):
        import scipy.sparse as sp

        return sp.csc_matrix((A.data, A.indices, A.indptr), shape=A.shape)

    def first(self, A) -> None:
        from sksparse.cholmod import cholesky

        self.F = cholesky(self._csc(A), mode=self.mode)

    def analyse(self, A) -> None:
        from sksparse.cholmod import analyze

        self.F = analyze(self._csc(A), mode=self.mode)

    def refactor(self, A) -> None:
        self.F.cholesky_inplace(self._csc(A))

    def solve(self, b):
        return self.F(b)

    def factor_entries(self) -> int:
        F = self.F.copy()   # simplicial: LDL' (no conversion); supernodal: LL'
        return int((F.LD() if self.mode == "simplicial" else F.L()).nnz)


class Pardiso(Solver):
    """MKL PARDISO through pypardiso's ctypes binding, phase by phase: pypardiso's public
    ``factorize``/``solve`` re-analyse every matrix that differs from its stored copy (phase
    12/13), so the numeric-only phase 22 is reached through the wrapper's ``_mkl_pardiso``
    handle, with the 1-based index arrays (and, for the symmetric types, the positions of the
    upper triangle) kept from the analysis, as a caller that reuses it would. Every ``iparm``
    at MKL's default for the matrix type (``iparm(1) = 0``): METIS ordering, for mtype 11
    scaling and weighted matching, pivot perturbation, up to two steps of iterative refinement
    in every solve."""

    reuse = True

    def __init__(self, mtype: int) -> None:
        self.mtype = mtype
        self.name = f"PARDISO-{mtype}" if mtype > 0 else f"PARDISO-({mtype})"
        self.symmetric_only = mtype in (2, -2)
        self.ps = None

    def _pattern(self, A) -> None:
        import numpy as np

        if self.mtype in (2, -2):
            rows = np.repeat(np.arange(A.shape[0]), np.diff(A.indptr))
            self.keep = A.indices >= rows
            indptr = np.concatenate([[0], np.cumsum(np.bincount(rows[self.keep],
                                                                minlength=A.shape[0]))])
            indices = A.indices[self.keep]
        else:
            self.keep = None
            indptr, indices = A.indptr, A.indices
        self.ia = (indptr + 1).astype(np.int32)
        self.ja = (indices + 1).astype(np.int32)
        self.n = A.shape[0]

    def _values(self, A):
        import numpy as np

        return np.ascontiguousarray(A.data if self.keep is None else A.data[self.keep])

    def _call(self, phase: int, data, b=None):
        import ctypes

        import numpy as np

        if b is None:
            b = np.zeros(self.n)
        x = np.zeros_like(b)
        error = ctypes.c_int32(0)
        i32, f64 = ctypes.POINTER(ctypes.c_int32), ctypes.POINTER(ctypes.c_double)
        ps = self.ps
        ps._mkl_pardiso(ps.pt.ctypes.data_as(ctypes.POINTER(ps._pt_type[0])),
                        ctypes.byref(ctypes.c_int32(1)), ctypes.byref(ctypes.c_int32(1)),
                        ctypes.byref(ctypes.c_int32(self.mtype)),
                        ctypes.byref(ctypes.c_int32(phase)), ctypes.byref(ctypes.c_int32(self.n)),
                        data.ctypes.data_as(f64), self.ia.ctypes.data_as(i32),
                        self.ja.ctypes.data_as(i32), ps.perm.ctypes.data_as(i32),
                        ctypes.byref(ctypes.c_int32(1)), ps.iparm.ctypes.data_as(i32),
                        ctypes.byref(ctypes.c_int32(0)), b.ctypes.data_as(f64),
                        x.ctypes.data_as(f64), ctypes.byref(error))
        if error.value != 0:
            from pypardiso.pardiso_wrapper import PyPardisoError

            raise PyPardisoError(error.value)
        return x

    def reset(self) -> None:
        """Release PARDISO's memory (phase -1) and keep the handle: making a PyPardisoSolver
        looks the MKL library up, which is no part of a factorisation."""
        if self.ps is None:
            from pypardiso import PyPardisoSolver

            self.ps = PyPardisoSolver(mtype=self.mtype)
            self.ps.iparm[:] = 0   # iparm(1) = 0: MKL's defaults for this mtype
        elif getattr(self, "n", None) is not None:
            self._call(-1, self._values_or_empty())

    def _values_or_empty(self):
        import numpy as np

        return getattr(self, "data", np.zeros(1))

    def first(self, A) -> None:
        self._pattern(A)
        self.data = self._values(A)
        self._call(12, self.data)

    def analyse(self, A) -> None:
        self._pattern(A)
        self.data = self._values(A)
        self._call(11, self.data)

    def refactor(self, A) -> None:
        self.data = self._values(A)
        self._call(22, self.data)

    def solve(self, b):
        import numpy as np

        return self._call(33, self.data, np.ascontiguousarray(b, dtype=float))

    def factor_entries(self) -> int:
        return int(self.ps.iparm[17])

    def note(self) -> str:
        return (f"{int(self.ps.iparm[13])} perturbed pivots, {int(self.ps.iparm[6])} "
                "refinement steps")

    def close(self) -> None:
        if self.ps is not None:
            self.reset()
            self.ps = None
            self.n = None


def available_solvers() -> tuple[list[Solver], dict[str, str]]:
    """The candidates whose libraries import, and the library versions."""
    import numpy as np
    import scipy
    import numba

    versions = {"python": platform.python_version(), "numpy": np.__version__,
                "scipy": scipy.__version__, "numba": numba.__version__}
    solvers: list[Solver] = [SuperLU(), StaticLU()]
    try:
        import sksparse
        from importlib.metadata import version

        import sksparse.cholmod  # noqa: F401

        versions["scikit-sparse"] = version("scikit-sparse")
        versions["SuiteSparse (Debian libcholmod)"] = _deb_version("libcholmod3")
        solvers += [Cholmod("simplicial"), Cholmod("supernodal")]
    except ImportError:
        print("scikit-sparse not installed: CHOLMOD left out", file=sys.stderr)
    try:
        from importlib.metadata import version

        import pypardiso  # noqa: F401

        versions["pypardiso"] = version("pypardiso")
        versions["mkl"] = version("mkl")
        solvers += [Pardiso(11), Pardiso(2), Pardiso(-2)]
    except ImportError:
        print("pypardiso not installed: PARDISO left out", file=sys.stderr)
    return solvers, versions


def _deb_version(package: str) -> str:
    try:
        out = subprocess.run(["dpkg-query", "-W", "-f=${Version}", package],
                             capture_output=True, text=True)
        return out.stdout.strip() or "?"
    except OSError:
        return "?"


# ---------------------------------------------------------------------------------- measuring

def timed(fn, *args) -> float:
    start = time.perf_counter()
    fn(*args)
    return time.perf_counter() - start


def measure(matrix_name: str, A, A_prev, solvers: list[Solver], repeats: int, rng) -> list[dict]:
    """Rows of one matrix: every applicable solver, interleaved over the repeats."""
    import numpy as np

    symmetric = matrix_name in ("GA-sym", "IP")
    if not same_pattern(A, A_prev):   # no reuse across the two frames: analyse A itself
        A_prev = A
    chosen = [s for s in solvers if symmetric or not s.symmetric_only]
    b = rng.standard_normal(A.shape[0])
    nb = np.linalg.norm(b)
    best = {s.name: {"first": np.inf, "analyse": np.inf, "refactor": np.inf, "solve": np.inf}
            for s in chosen}
    failed: dict[str, str] = {}
    residual, entries, extra = {}, {}, {}
    for s in chosen:  # warm-up (compilation, library loading); also the residual and fill
        try:
            s.reset()
            s.first(A)
            x = s.solve(b)
            residual[s.name] = float(np.linalg.norm(A @ x - b) / nb)
            entries[s.name] = s.factor_entries()
            if isinstance(s, Pardiso):
                extra[s.name] = s.note()
        except Exception as error:  # noqa: BLE001 - reported in the table
            failed[s.name] = f"{type(error).__name__}: {error}"[:120]
    for _ in range(repeats):
        for s in chosen:
            if s.name in failed:
                continue
            gc.collect()
            r = best[s.name]
            s.reset()
            r["first"] = min(r["first"], timed(s.first, A))
            r["solve"] = min(r["solve"], timed(s.solve, b))
            if s.reuse:
                s.reset()
                r["analyse"] = min(r["analyse"], timed(s.analyse, A_prev))
                s.refactor(A_prev)
                r["refactor"] = min(r["refactor"], timed(s.refactor, A))
            else:
                r["refactor"] = r["first"]
    rows = []
    for s in chosen:
        row = {"matrix": matrix_name, "solver": s.name}
        if s.name in failed:
            row["failed"] = failed[s.name]
        else:
            row.update({k: 1e3 * v for k, v in best[s.name].items()})
            if not s.reuse:
                row["analyse"] = None
            row.update(residual=residual[s.name], entries=entries[s.name],
                       note=extra.get(s.name, ""))
            if s.reuse:  # the residual after a numeric-only refactorisation too
                s.reset()
                s.analyse(A_prev)
                s.refactor(A_prev)
                s.refactor(A)
                x = s.solve(b)
                row["residual_reuse"] = float(np.linalg.norm(A @ x - b) / nb)
        rows.append(row)
        s.close()
    return rows


def refinement_row(matrix_name: str, A, A_sym, repeats: int, rng) -> dict | None:
    """CHOLMOD (simplicial) of the symmetric part as the solver of the non-symmetric A, with
    iterative refinement to 1e-12."""
    import numpy as np

    try:
        from sksparse.cholmod import CholmodNotPositiveDefiniteError, cholesky
    except ImportError:
        return None
    b = rng.standard_normal(A.shape[0])
    nb = np.linalg.norm(b)
    try:
        F = cholesky(A_sym.tocsc(), mode="simplicial")
    except CholmodNotPositiveDefiniteError as error:
        return {"matrix": matrix_name, "solver": "CHOLMOD-sym+IR", "failed": str(error)[:100]}

    def solve():
        x = F(b)
        for k in range(50):
            r = b - A @ x
            norm = np.linalg.norm(r)
            if norm <= 1e-12 * nb or norm > 1e3 * nb:
                return x, k
            x += F(r)
        return x, 50

    x, steps = solve()
    residual = float(np.linalg.norm(A @ x - b) / nb)
    if residual > 1e-12:
        return {"matrix": matrix_name, "solver": "CHOLMOD-sym+IR",
                "failed": f"refinement diverges: residual {residual:.0e} after {steps} steps"}
    t = min(timed(solve) for _ in range(repeats))
    return {"matrix": matrix_name, "solver": "CHOLMOD-sym+IR", "solve": 1e3 * t,
            "residual": residual, "note": f"{steps} refinement steps"}


def definiteness(S, rotation) -> dict:
    """Whether the symmetric S is positive definite: CHOLMOD's LL' (supernodal) refuses it
    otherwise. Its inertia from LDL' factors (CHOLMOD simplicial, no pivoting: P (S - s I) P^T
    = L D L^T is a congruence, so by Sylvester's law the negative entries of D count the
    eigenvalues of S below s): the number of negative eigenvalues, how many of those pivots sit
    on rotation DOFs, and the smallest eigenvalue bracketed by bisection on s, relative to the
    largest diagonal entry (for a positive definite S, bracketed from above 0)."""
    import numpy as np

    try:
        from sksparse.cholmod import CholmodNotPositiveDefiniteError, analyze, cholesky
    except ImportError:
        return {}
    dmax = float(np.abs(S.diagonal()).max())
    csc = S.tocsc()
    out: dict = {"n": S.shape[0]}
    try:
        cholesky(csc, mode="supernodal")
        out["pd"] = True
    except CholmodNotPositiveDefiniteError:
        out["pd"] = False
    F = analyze(csc, mode="simplicial")

    def below(shift: float) -> tuple[int, np.ndarray]:
        """Eigenvalues of S below shift * dmax, and the DOFs of the negative pivots."""
        F.cholesky_inplace(csc, beta=-shift * dmax)
        D = F.D()
        negative = np.flatnonzero(D < 0)
        return len(negative), F.P()[negative]

    count, dofs = below(0.0)
    out["negative"] = int(count)
    out["negative_rotation"] = int(rotation[dofs].sum())
    out["rotation_dofs"] = int(rotation.sum())
    # bracket lambda_min / dmax in [lo, hi]: no eigenvalue below lo, at least one below hi
    if count:
        lo = -1.0
        while below(lo)[0]:
            lo *= 2.0
        while below(lo / 10.0)[0] == 0:   # powers of ten towards 0 (count(0) > 0 stops it)
            lo /= 10.0
        hi = lo / 10.0
    else:
        hi = 1e-14
        while below(hi)[0] == 0 and hi < 4.0:
            hi *= 10.0
        lo = hi / 10.0
    for _ in range(8):   # geometric bisection: the bracket to a factor 10^(1/256)
        mid = -np.sqrt(lo * hi) if hi < 0 else np.sqrt(lo * hi)
        if below(mid)[0]:
            hi = mid
        else:
            lo = mid
    out["lambda_min"] = (float(lo), float(hi))
    return out


# ------------------------------------------------------------------------------------ reporting

def fmt(x, digits=3) -> str:
    if x is None:
        return "-"
    if isinstance(x, float):
        if x != x or x == float("inf"):
            return "-"
        if x >= 100:
            return f"{x:.0f}"
        if x >= 10:
            return f"{x:.1f}"
        return f"{x:.{digits - 1}f}" if x >= 1 else f"{x:.{digits}f}"
    return str(x)


def ratio(x, ref) -> str:
    if x is None or ref is None or not ref or x != x or x == float("inf"):
        return ""
    return f" ({x / ref:.2f})"


def case_table(label: str, info: dict, rows: list[dict], threads: int) -> list[str]:
    lines = [f"### {label}: {info['n_dof']:,} DOF, threads = {threads}", ""]
    lines.append(f"nnz(A) = {info['nnz']:,} stored, {info['nonzero']:,} of them nonzero "
                 f"(slack threads store zeros); pattern of t = {T_PREV} s and t = {T_LATE} s "
                 f"{'the same' if info['same_pattern'] else 'DIFFERENT'}; "
                 f"|A - A^T|_F / |A|_F: GA {info['asymmetry']:.1e}, "
                 f"BE {info['asymmetry_BE']:.1e}; assembly {info['assembly_ms']:.1f} ms; "
                 f"explicit run to 0.5 s: {info['explicit_wall_s']:.0f} s.")
    lines.append("")
    for key, d in info["definite"].items():
        if not d:
            continue
        lo, hi = d["lambda_min"]
        bracket = f"[{lo:.2e}, {hi:.2e}]"
        if d["pd"]:
            lines.append(f"- {key}: positive definite; smallest eigenvalue / max diag in "
                         f"{bracket}.")
        else:
            lines.append(f"- {key}: NOT positive definite: {d['negative']} negative eigenvalues "
                         f"(by the LDL' pivots; {d['negative_rotation']} of those pivots on "
                         f"rotation DOFs, which are {d['rotation_dofs']} of {d['n']}); the "
                         f"smallest eigenvalue / max diag in {bracket}.")
    lines += ["", "| matrix | solver | first factor, ms (/ SuperLU) | analysis, ms | repeat "
              "factor, ms (/ StaticLU) | solve, ms (/ StaticLU) | factor + solve, ms "
              "(/ StaticLU) | factor entries | residual (after reuse) | note |",
              "|---|---|---|---|---|---|---|---|---|---|"]
    by_matrix: dict[str, list[dict]] = {}
    for r in rows:
        by_matrix.setdefault(r["matrix"], []).append(r)
    for matrix, rs in by_matrix.items():
        ref = {r["solver"]: r for r in rs if "failed" not in r}
        slu, slu_first = ref.get("StaticLU", {}), ref.get("SuperLU", {}).get("first")
        slu_fs = (slu["refactor"] + slu["solve"]) if slu else None
        for r in rs:
            if "failed" in r:
                lines.append(f"| {matrix} | {r['solver']} | failed: {r['failed']} "
                             "| | | | | | | |")
                continue
            fs = (r["refactor"] + r["solve"]) if r.get("refactor") is not None else None
            res = f"{r['residual']:.1e}"
            if "residual_reuse" in r:
                res += f" ({r['residual_reuse']:.1e})"
            ent = f"{r['entries']:,}" if r.get("entries") else "-"
            lines.append(
                f"| {matrix} | {r['solver']} | {fmt(r.get('first'))}"
                f"{ratio(r.get('first'), slu_first)} | {fmt(r.get('analyse'))} | "
                f"{fmt(r.get('refactor'))}{ratio(r.get('refactor'), slu.get('refactor'))} | "
                f"{fmt(r.get('solve'))}{ratio(r.get('solve'), slu.get('solve'))} | "
                f"{fmt(fs)}{ratio(fs, slu_fs)} | {ent} | {res} | {r.get('note', '')} |")
    return lines + [""]


def machine() -> str:
    cpu = "?"
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    blas = "?"
    try:
        blas = os.path.realpath("/etc/alternatives/libblas.so.3-x86_64-linux-gnu")
    except OSError:
        pass
    return (f"{cpu}, {os.cpu_count()} cores, {platform.platform()}; system BLAS (used by "
            f"CHOLMOD): {blas}")


# ---------------------------------------------------------------------------------------- main

def run_cases(args) -> tuple[list[str], dict]:
    import numpy as np

    solvers, versions = available_solvers()
    rng = np.random.default_rng(1)
    lines: list[str] = []
    summary: dict = {}
    for name in args.cases:
        label = CASES[name][0]
        start = time.perf_counter()
        case = build_case(name, args.cache)
        mats = case["matrices"]
        info = {k: v for k, v in case.items() if k != "matrices"}
        info["nnz"] = int(mats["GA"].nnz)
        info["nonzero"] = int(mats["GA"].count_nonzero())
        info["same_pattern"] = all(same_pattern(mats[f], mats[f + "_prev"]) for f in FORMS)
        info["definite"] = {}
        rotation = mats["rotation_mask"].toarray().ravel() > 0.5
        if not args.no_definiteness and ("GA-sym" in args.forms or "GA" in args.forms):
            info["definite"]["GA-sym"] = definiteness(mats["GA-sym"], rotation)
        if not args.no_definiteness and ("IP" in args.forms or "BE" in args.forms):
            info["definite"]["IP (= BE-sym / h)"] = definiteness(mats["IP"], rotation)
        print(f"{name}: {info['n_dof']} DOF, matrices in {time.perf_counter() - start:.0f} s",
              file=sys.stderr, flush=True)
        rows = []
        for form in FORMS:
            if form not in args.forms:
                continue
            rows += measure(form, mats[form], mats[form + "_prev"], solvers, args.repeats, rng)
            if form in ("GA", "BE"):
                sym = mats["GA-sym"] if form == "GA" else mats["IP"] * H
                row = refinement_row(form, mats[form], sym, args.repeats, rng)
                if row:
                    rows.append(row)
            print(f"  {form} done", file=sys.stderr, flush=True)
        lines += case_table(label, info, rows, args.threads)
        summary[name] = {"info": info, "rows": rows}
    return lines, {"versions": versions, "cases": summary}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cases", nargs="+", choices=list(CASES), default=list(CASES))
    parser.add_argument("--forms", nargs="+", choices=FORMS, default=list(FORMS))
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--threads", type=int, default=1)
    parser.add_argument("--two-thread-case", choices=list(CASES), default=None,
                        help="case measured again with 2 threads (default: the largest run)")
    parser.add_argument("--no-two-thread", action="store_true")
    parser.add_argument("--no-definiteness", action="store_true",
                        help="skip the inertia of the symmetric matrices")
    parser.add_argument("--cache", type=Path,
                        default=Path(tempfile.gettempdir()) / "rodnet_linear_solvers")
    parser.add_argument("--output", type=Path, default=HERE / "results" / "linear_solvers.md")
    parser.add_argument("--json", type=Path, default=None, help="also write the raw rows")
    args = parser.parse_args()
    for var in ("OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "OMP_NUM_THREADS",
                "NUMBA_NUM_THREADS"):
        os.environ[var] = str(args.threads)
    sys.path.insert(0, str(ROOT))

    lines, raw = run_cases(args)
    versions = raw["versions"]
    if not args.no_two_thread and args.threads == 1:
        order = ["cable21-n2", "net21-n1", "net21-n2", "net21-n4", "net41-n2"]
        largest = args.two_thread_case or max(args.cases, key=order.index)
        with tempfile.TemporaryDirectory() as tmp:
            out = Path(tmp) / "two.md"
            child = [sys.executable, __file__, "--cases", largest, "--forms", *args.forms,
                     "--repeats", str(args.repeats), "--threads", "2", "--cache",
                     str(args.cache), "--no-two-thread", "--no-definiteness", "--output", str(out)]
            done = subprocess.run(child, capture_output=True, text=True)
            lines += ["## Two threads (OPENBLAS, MKL, OMP, NUMBA_NUM_THREADS = 2)", ""]
            if done.returncode == 0:
                lines += out.read_text().split("## Results\n", 1)[1].strip().splitlines()
                lines += [""]
            else:
                lines += [f"Two-thread run failed: {done.stderr[-500:]}", ""]
    head = ["# Sparse direct solvers on the net's Newton iteration matrices", "",
            f"Written by `validation/benchmarks/linear_solvers.py` "
            f"({time.strftime('%Y-%m-%d')}), repeats {args.repeats}, smallest time of the "
            f"repeats, solvers interleaved in one process.", "",
            f"Machine: {machine()}.", "",
            "Libraries: " + ", ".join(f"{k} {v}" for k, v in versions.items()) + ".", "",
            "Matrices (h = 1e-3, at t = 0.5 s of an explicit deployment; repeat = a second "
            "matrix of the pattern, t = 0.49 s, analysed first): GA = diag(M) + 0.6 h C + "
            "0.3 h^2 K; GA-sym = (GA + GA^T)/2; BE = diag(M)/h + C + h K; IP = sym(diag(M)/h^2 "
            "+ C/h + K). Ratios: first factorisation to SuperLU, repeat factorisation and solve "
            "to StaticLU (rodnet's default: SuperLU for a new pattern, StaticPatternLU once it "
            "repeats). Factor entries: L + U for the LUs, L (with D, LDL') for CHOLMOD "
            "simplicial, L with supernode padding for supernodal, iparm(18) for PARDISO. "
            "PARDISO: MKL's default iparm, phase 12 first, 11 then 22 repeat, 33 solve (two "
            "refinement steps by default). CHOLMOD-simp is LDL' without pivoting: it factorises "
            "indefinite matrices too; CHOLMOD-super (LL') and PARDISO-2 refuse them. "
            "CHOLMOD-sym+IR: CHOLMOD (simplicial) of the symmetric part with iterative "
            "refinement on the non-symmetric matrix, to a residual of 1e-12.", "",
            f"Threads = {args.threads} (OPENBLAS_NUM_THREADS, MKL_NUM_THREADS, OMP_NUM_THREADS, "
            f"NUMBA_NUM_THREADS).", "", "## Results", ""]
    text = "\n".join(head + lines)
    print(text)
    args.output.parent.mkdir(parents=True, exist_ok=True)
    args.output.write_text(text)
    if args.json:
        args.json.write_text(json.dumps(raw, indent=1, default=str))


if __name__ == "__main__":
    main()
