"""A reduced capture with the implicit rod models: bending and torsion against cables.

The full capture (``study.py``: the 21 x 21 reference net and a free 1400 kg target) is out of
reach of the implicit Cosserat models in minutes, and free bodies run with the explicit
integrator only. This study shrinks it: a 7 x 7 Kevlar net (0.5 m mesh, 0.2 kg corner masses at
10 m/s, 45 degrees, packed to 0.3 of its size) shot at a fixed cylinder of 0.6 m diameter and
1.6 m length whose centre is 2.5 m down-range, its axis across the shot, friction 0.3, for
``--duration`` s. Two variants, both generalized-alpha (rho_inf = 0, error-controlled adaptive
steps): Cosserat threads with bending and torsion (pinned knots) and cable threads (bending and
torsion off). The runs go to a temporary folder; the table is written to
``out/bending_results.md`` beside this script (not in git), and only with ``--publish`` also to the
tracked ``bending_results.md`` beside this script.

Usage, from the repository root: ``OPENBLAS_NUM_THREADS=1 .venv/bin/python
validation/cases/capture_reference/bending_study.py [--duration 0.8] [--publish]``.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path

import numpy as np

HERE = Path(__file__).parent
sys.path.insert(0, str(HERE))

from study import OUT, publish, report_written  # noqa: E402

from rodnet.run import RunResult, run  # noqa: E402
from rodnet.scene import scene_from_toml  # noqa: E402

RADIUS, LENGTH, DISTANCE = 0.3, 1.6, 2.5

SCENE = f"""
[simulation]
type = "dynamic"
duration = 0.8
integrator = "generalized-alpha"
rho_inf = 0.0
adaptive = true
dt = 1.0e-4
error_tolerance = 1.0e-4
gravity = [0.0, 0.0, 0.0]

[model]
type = "cosserat"
elements_per_thread = 1
axial = "tension-only"
knots = "pinned"

[[materials]]
name = "kevlar"
density = 1440.0
youngs_modulus = 7.0e10
poisson_ratio = 0.36
diameter = 1.0e-3
viscosity = 2.0e6

[net]
layout = "square"
nodes_per_side = 7
mesh_length = 0.5
material = "kevlar"
center = [0.0, 0.0, 0.0]
direction = [0.0, 0.0, 1.0]
packing = 0.3
knot_mass = 0.0
corner_mass = 0.2
corner_thread_length = 0.5
launch_speed = 10.0
launch_angle_deg = 45.0

[[bodies]]
name = "target"
shape = "cylinder"
size = [{2 * RADIUS}, {2 * RADIUS}, {LENGTH}]
position = [0.0, 0.0, {DISTANCE}]
orientation_deg = [0.0, 90.0, 0.0]
fixed = true

[contact]
stiffness = 1.0e4
damping = 2.0
friction = 0.3

[output]
frame_interval = 0.01
vtk = false
picture = false
plot = false
"""
VARIANTS = {"cable threads (no bending)": ("model.bending=false", "model.torsion=false"),
            "bending and torsion, pinned knots": ("model.bending=true", "model.torsion=true")}


def measures(r: RunResult) -> dict[str, float]:
    """Capture measures at the last frame and over the run."""
    x = r.arrays["positions"]
    corners = np.asarray(list(r.summary["nodes"].values()))  # selector -> node
    names = list(r.summary["nodes"].keys())
    corner_nodes = [corners[i] for i, n in enumerate(names) if "corner" in n]
    local = x[-1] - np.array([0.0, 0.0, DISTANCE])
    radial = np.hypot(local[:, 1], local[:, 2])     # distance from the target's axis (x)
    near = (radial < RADIUS + 0.1) & (np.abs(local[:, 0]) < 0.5 * LENGTH + 0.1)
    behind = x[-1, corner_nodes, 2] > DISTANCE + RADIUS
    return {"max contact force [N]": float(r.arrays["contact_force"].max()),
            "max contact points": int(r.arrays["contact_count"].max()),
            "corners behind the target at the end": f"{int(behind.sum())} of {len(behind)}",
            "nodes within 0.1 m of the surface at the end": f"{near.mean():.0%}",
            "friction work [J]": float(r.arrays["friction_work"][-1]),
            "steps": int(r.summary["steps"]), "Newton iterations": int(r.summary["newton_iterations"]),
            "rejected steps": int(r.summary["rejected_steps"]),
            "smallest step [s]": float(r.summary["integrator"]["dt_min"] or np.nan),
            "wall [s]": float(r.summary["wall_time_s"]), "status": r.status,
            "simulated [s]": float(r.arrays["time"][-1])}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--duration", type=float, default=0.8)
    parser.add_argument("--publish", action="store_true",
                        help="also write the tracked bending_results.md beside this script "
                             "(default: only out/bending_results.md)")
    args = parser.parse_args()
    rows: dict[str, dict[str, float]] = {}
    for name, overrides in VARIANTS.items():
        scene = scene_from_toml(SCENE, [f"simulation.duration={args.duration:g}", *overrides])
        with tempfile.TemporaryDirectory() as out:
            r = run(scene, out, progress=False)
        rows[name] = measures(r)
        print(name, rows[name], flush=True)
    keys = list(next(iter(rows.values())))
    lines = ["# Reduced capture: bending and torsion against cable threads", "",
             f"Written by `bending_study.py` ({args.duration:g} s simulated; one BLAS thread). "
             "Discussion: `docs/capture.md`.", "",
             "| quantity | " + " | ".join(rows) + " |", "|---|" + "---|" * len(rows)]
    for key in keys:
        cells = [f"{v:.4g}" if isinstance(v, float) else str(v) for v in (rows[n][key] for n in rows)]
        lines.append(f"| {key} | " + " | ".join(cells) + " |")
    OUT.mkdir(parents=True, exist_ok=True)
    (OUT / "bending_results.md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))
    published = {OUT / "bending_results.md": HERE / "bending_results.md"} if args.publish else None
    if published:
        publish(published)
    report_written("reduced bending capture", [OUT / "bending_results.md"], published)


if __name__ == "__main__":
    main()
