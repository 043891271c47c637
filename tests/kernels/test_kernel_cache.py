"""The compiled-kernel cache is dropped when any source the kernels are built from changes."""

from __future__ import annotations

from pathlib import Path

import pytest

from rodnet.kernels import cache


def _cache_files(folder: Path) -> list[Path]:
    files = [folder / "a.step-10.py311.nbi", folder / "a.step-10.py311.1.nbc",
             folder / "b.force-3.py311.nbi", folder / "b.force-3.py311.1.nbc"]
    for f in files:
        f.write_bytes(b"compiled")
    return files


def test_an_edit_of_one_source_drops_the_kernels_of_all(tmp_path: Path) -> None:
    """``a`` calls ``b``: numba would keep ``a``'s machine code after an edit of ``b`` alone."""
    a, b = tmp_path / "a.py", tmp_path / "b.py"
    a.write_text("from b import force\n")
    b.write_text("STIFFNESS = 1.0\n")
    folder = tmp_path / "__pycache__"
    folder.mkdir()
    other = folder / "other.kernel-1.py311.nbi"   # not one of the sources: never touched
    other.write_bytes(b"compiled")
    pyc = folder / "a.cpython-311.pyc"
    pyc.write_bytes(b"bytecode")

    first = _cache_files(folder)
    assert sorted(cache.refresh([a, b], [folder])) == sorted(first)   # no stamp yet: stale
    assert (folder / cache.STAMP).read_text().strip() == cache.digest([a, b])

    kept = _cache_files(folder)
    assert cache.refresh([a, b], [folder]) == []                      # sources unchanged
    assert all(f.exists() for f in kept)

    b.write_text("STIFFNESS = 2.0\n")                                  # edit b only
    assert sorted(cache.refresh([a, b], [folder])) == sorted(kept)    # a's kernels go too
    assert not any(f.exists() for f in kept)
    assert other.exists() and pyc.exists()


def test_the_package_sources_cover_the_modules_with_kernels() -> None:
    """Every module that compiles with ``cache=True`` is among the stamped sources."""
    package = cache.PACKAGE
    compiled = {p for p in package.rglob("*.py") if "cache=True" in p.read_text()}
    assert compiled, "no cached kernels found"
    assert compiled <= set(cache.SOURCES), sorted(str(p) for p in compiled - set(cache.SOURCES))


CACHE_ORDER_SCRIPT = """
import sys
import numpy as np
from rodnet.run import run
from rodnet.scene import scene_from_toml
integrator, out = sys.argv[1], sys.argv[2]
rod = '''
[simulation]
duration = 0.02
gravity = [0.0, 0.0, -9.81]
integrator = "INTEGRATOR"
[[materials]]
name = "kevlar"
density = 1440.0
youngs_modulus = 7.0e10
poisson_ratio = 0.36
diameter = 1.0e-3
viscosity = 2.0e6
[[rods]]
name = "thread"
material = "kevlar"
points = [[0.0, 0.0, 0.0], [0.5, 0.0, 0.0]]
elements = 6
[[supports]]
node = "thread:start"
fix = "clamp"
[output]
vtk = false
frame_interval = 0.01
'''
net = '''
[simulation]
duration = 0.02
integrator = "INTEGRATOR"
[model]
type = "cosserat"
elements_per_thread = 2
[[materials]]
name = "kevlar"
density = 1440.0
youngs_modulus = 7.0e10
poisson_ratio = 0.36
diameter = 1.0e-3
viscosity = 2.0e6
[net]
material = "kevlar"
nodes_per_side = 3
[output]
vtk = false
frame_interval = 0.01
'''
for name, text in (("rod", rod), ("net", net)):
    r = run(scene_from_toml(text.replace("INTEGRATOR", integrator)), f"{out}/{name}",
            progress=False)
    assert r.status == "ok", r.message
"""


@pytest.mark.slow  # about 140 s: compiles every kernel twice from an empty cache
def test_cached_kernels_load_in_any_order(tmp_path: Path) -> None:
    """numba's cache of a compiled function that calls a ``parallel=True`` function loaded from
    the cache is broken (numba issues 4807, 8578: it segfaulted the second implicit run after an
    explicit one). Explicit, then implicit twice, in processes sharing one fresh cache: every
    run exits 0 and gives the results of a run from an empty cache, for a rod and a net."""
    import os
    import subprocess
    import sys

    import numpy as np

    def run_in_process(integrator: str, out: Path, cache_dir: Path) -> None:
        env = dict(os.environ, NUMBA_CACHE_DIR=str(cache_dir))
        done = subprocess.run([sys.executable, "-c", CACHE_ORDER_SCRIPT, integrator, str(out)],
                              env=env, capture_output=True, text=True, timeout=600)
        assert done.returncode == 0, (integrator, done.returncode, done.stderr[-2000:])

    shared = tmp_path / "shared-cache"
    for k, integrator in enumerate(("explicit", "generalized-alpha", "generalized-alpha")):
        run_in_process(integrator, tmp_path / f"run{k}", shared)
    run_in_process("generalized-alpha", tmp_path / "fresh", tmp_path / "empty-cache")
    for name in ("rod", "net"):
        fresh = np.load(tmp_path / "fresh" / name / "result.npz")
        for k in (1, 2):
            cached = np.load(tmp_path / f"run{k}" / name / "result.npz")
            for key in ("positions", "velocities", "rotations", "tension"):
                np.testing.assert_array_equal(cached[key], fresh[key], err_msg=f"{name} {key}")


def _compiled_functions() -> dict[str, tuple[str, bool, set[str]]]:
    """``module.function`` -> (module, parallel, names it calls) of every numba-compiled
    function of the package, read from the sources."""
    import ast

    found: dict[str, tuple[str, bool, set[str]]] = {}
    for path in sorted(cache.PACKAGE.rglob("*.py")):
        tree = ast.parse(path.read_text())
        for node in ast.walk(tree):   # nested ones too: a loop built in a closure (explicit._loop)
            if not isinstance(node, ast.FunctionDef):
                continue
            for dec in node.decorator_list:
                call = dec if isinstance(dec, ast.Call) else None
                target = call.func if call else dec
                if not (isinstance(target, ast.Attribute) and target.attr in ("njit", "jit")):
                    continue
                # parallel=True or parallel=<options> (threads.PRANGE_ONLY)
                parallel = any(k.arg == "parallel" and not (isinstance(k.value, ast.Constant)
                                                            and not k.value.value)
                               for k in (call.keywords if call else []))
                calls = {c.func.id if isinstance(c.func, ast.Name) else c.func.attr
                         for c in ast.walk(node) if isinstance(c, ast.Call)
                         and isinstance(c.func, (ast.Name, ast.Attribute))}
                found[f"{path.stem}.{node.name}"] = (path.stem, parallel, calls)
    return found


def test_no_compiled_function_calls_a_parallel_one() -> None:
    """The rule that keeps the cache sound: a ``parallel=True`` function is an entry point,
    called from Python only; loops shared by several entry points are ``inline="always"``
    functions, whose ``prange`` becomes the caller's own."""
    functions = _compiled_functions()
    parallel = {key.split(".", 1)[1] for key, (_, par, _) in functions.items() if par}
    assert parallel, "no parallel kernels found"
    offenders = sorted(f"{key} calls {sorted(calls & parallel)}"
                       for key, (_, _, calls) in functions.items() if calls & parallel)
    assert not offenders, offenders
