"""Benchmark: signed distance of query points to a triangle mesh, the query contact makes.

Compares rodnet's own hierarchy (``rodnet.contact.mesh.TriangleMesh.query``: signed distance,
normal, closest point and normal derivative), with and without a ``max_distance`` cut-off,
against libigl's ``signed_distance`` (pseudonormal sign; ``pip install libigl``) and trimesh's
``proximity.signed_distance`` (needs ``rtree``), when those are importable. Meshes of 1e3 to 1e4
triangles, 1e3 and 1e4 points either uniform in the bounding box grown by 10 % ("box") or within
about 1 % of the size from the surface ("near", where contact happens). Best of 3 (trimesh: 1),
milliseconds; the last column is the largest difference in distance from the first other method
available (a sign error would show as twice the distance).

Usage: ``python validation/benchmarks/contact_mesh_distance.py [--quick]``
"""

from __future__ import annotations

import importlib.util
import sys
import time
from pathlib import Path

import numpy as np
import trimesh

from rodnet.contact.mesh import TriangleMesh

HERE = Path(__file__).parent


def best_of(func, repeats: int) -> tuple[float, object]:
    times, result = [], None
    for _ in range(repeats):
        start = time.perf_counter()
        result = func()
        times.append(time.perf_counter() - start)
    return 1e3 * min(times), result


def meshes() -> dict[str, trimesh.Trimesh]:
    return {
        "icosphere": trimesh.creation.icosphere(subdivisions=3, radius=1.0),
        "icosphere ": trimesh.creation.icosphere(subdivisions=4, radius=1.0),
        "cylinder": trimesh.creation.cylinder(radius=1.0, height=3.0, sections=1024),
        "torus": trimesh.creation.torus(major_radius=1.0, minor_radius=0.3, major_sections=128,
                                        minor_sections=40),
    }


def main(quick: bool = False) -> str:
    have_igl = importlib.util.find_spec("igl") is not None
    have_rtree = importlib.util.find_spec("rtree") is not None
    if have_igl:
        import igl
    rng = np.random.default_rng(0)
    rows = ["| mesh | triangles | points | where | rodnet build | rodnet | rodnet, max_distance 5 % | "
            "libigl | trimesh | max abs difference [m] |", "|" + "---|" * 10]
    sizes = (1000,) if quick else (1000, 10000)
    for name, tm in meshes().items():
        start = time.perf_counter()
        mesh = TriangleMesh(tm.vertices, tm.faces, name)
        build = 1e3 * (time.perf_counter() - start)
        V, F = np.asarray(mesh.vertices), np.asarray(mesh.faces)
        lo, hi = mesh.bounds
        size = float((hi - lo).max())
        mesh.query(np.zeros((1, 3)))  # compile or load the compiled query
        for n in sizes:
            for where in ("box", "near"):
                if where == "box":
                    points = rng.uniform(lo - 0.1 * (hi - lo), hi + 0.1 * (hi - lo), (n, 3))
                else:
                    points = tm.sample(n, seed=1) + rng.normal(scale=0.01 * size, size=(n, 3))
                t_own, q = best_of(lambda: mesh.query(points), 3)
                t_cut, _ = best_of(lambda: mesh.query(points, max_distance=0.05 * size), 3)
                reference, cells = None, []
                if have_igl:
                    t_igl, out = best_of(lambda: igl.signed_distance(
                        points, V, F, sign_type=igl.SIGNED_DISTANCE_TYPE_PSEUDONORMAL), 3)
                    reference = out[0]
                    cells.append(f"{t_igl:.1f}")
                else:
                    cells.append("n/a")
                if have_rtree and not quick:
                    t_tm, out = best_of(lambda: trimesh.proximity.signed_distance(tm, points), 1)
                    reference = -out if reference is None else reference
                    cells.append(f"{t_tm:.0f}")
                else:
                    cells.append("n/a")
                diff = "n/a" if reference is None else f"{np.abs(q.distance - reference).max():.1e}"
                rows.append(f"| {name.strip()} | {len(F)} | {n} | {where} | {build:.0f} | {t_own:.1f} | "
                            f"{t_cut:.1f} | {' | '.join(cells)} | {diff} |")
    return "\n".join(rows)


if __name__ == "__main__":
    table = main(quick="--quick" in sys.argv)
    print(table)
    if "--quick" not in sys.argv:
        (HERE / "results").mkdir(exist_ok=True)
        (HERE / "results" / "contact_mesh_distance.md").write_text(
            "# Mesh signed distance: rodnet hierarchy vs libigl vs trimesh (ms, best of 3)\n\n"
            + table + "\n")
