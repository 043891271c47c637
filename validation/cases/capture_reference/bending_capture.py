"""The capture study with and without bending: the tumbling SL-8 target of ``study.py`` caught by
the reference net with threads of Cosserat rods (bending and torsion) and as cables.

Four variants of the same scene (``study.scene_text("cylinder")``: the reference deployment, the
free 1400 kg cylinder 15 m down-range tumbling at 2 deg/s, friction 0.3), all with the explicit
integrator (free bodies move with it only):

- ``lumped n=1``: the lumped model with one segment per thread (the study's own run);
- ``cables n=2``: Cosserat threads without bending and torsion, two elements per thread (the
  lumped model's equations at the rods' resolution: the "no bending" case);
- ``rods n=2 pinned`` and ``rods n=2 rigid``: Cosserat threads with the solid Kevlar section's
  bending and torsion, two elements per thread, pinned or rigid knots, rotary inertia raised
  (FORMULATION C49).

Everything goes into ``out/`` beside this script (not in git): each run is stored in
``out/bending_<variant>/`` and reused on a rerun; the report is ``out/bending_capture.md`` and the
figure ``out/capture_bending.png``. Only with ``--publish`` are the tracked copies written too:
``bending_capture.md`` beside this script and ``docs/img/capture_bending.png``. Usage, from the
repository root: ``OPENBLAS_NUM_THREADS=1 .venv/bin/python
validation/cases/capture_reference/bending_capture.py [--duration 6] [--only VARIANT] [--report]
[--publish]`` (``--report`` writes the report from the stored runs only).
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

HERE = Path(__file__).parent
sys.path.insert(0, str(HERE))

from study import (INSTANTS, NEAR, OUT, RADIUS, publish, report_written,  # noqa: E402
                   scene_text, table)

from rodnet.kernels import so3  # noqa: E402
from rodnet.run import prepare, run  # noqa: E402
from rodnet.scene import scene_from_toml  # noqa: E402

IMG = HERE.parents[2] / "docs" / "img"     # the published figure (``--publish`` only)
ROD = ("model.type=cosserat", "model.elements_per_thread=2", "simulation.integrator=explicit")
VARIANTS = {
    "lumped n=1": (),
    "cables n=2": ROD + ("model.bending=false", "model.torsion=false"),
    "rods n=2 pinned": ROD + ("model.knots=pinned",),
    "rods n=2 rigid": ROD + ("model.knots=rigid",),
    "rods n=4 pinned": ("model.type=cosserat", "model.elements_per_thread=4",
                        "simulation.integrator=explicit", "model.knots=pinned"),
}
STYLE = {"lumped n=1": ("0.5", "-"), "cables n=2": ("k", "-"), "rods n=2 pinned": ("tab:blue", "-"),
         "rods n=2 rigid": ("tab:red", "--"), "rods n=4 pinned": ("tab:green", "-")}


def folder(variant: str) -> Path:
    return OUT / ("bending_" + variant.replace(" ", "_").replace("=", ""))


def overrides(variant: str, duration: float) -> list[str]:
    return [*VARIANTS[variant], f"simulation.duration={duration:g}", "output.frame_interval=0.02",
            "output.vtk=false"]


def run_variant(variant: str, duration: float) -> None:
    """Run one variant and store it (a failed run is stored too, with its frames)."""
    out = folder(variant)
    out.mkdir(parents=True, exist_ok=True)
    result = run(scene_from_toml(scene_text("cylinder"), overrides(variant, duration)), out,
                 progress=None)
    print(variant, result.status, result.message, result.summary.get("wall_time_s"))


def load(variant: str) -> tuple[dict, dict]:
    """The stored summary and arrays of a variant."""
    out = folder(variant)
    summary = json.loads((out / "summary.json").read_text())
    with np.load(out / "result.npz", allow_pickle=False) as data:
        arrays = {key: data[key] for key in data.files}
    return summary, arrays


def measures(variant: str, summary: dict, a: dict, duration: float) -> dict[str, np.ndarray]:
    """Per frame: the least distance a corner mass is behind the target's centre, the fraction
    of knots within ``NEAR`` of its surface, and the net's centre-of-mass speed relative to it."""
    p = prepare(scene_from_toml(scene_text("cylinder"), overrides(variant, duration)))
    shape = p.system.contact.bodies.shapes[0]
    corners = [summary["nodes"][f"net:corner:{i}"] for i in range(4)]
    knots = np.arange(p.scene.net.nodes_per_side**2)   # knots are numbered first
    centre, q = a["body_positions"][:, 0], a["body_rotations"][:, 0]
    behind = a["positions"][:, corners, 2] - centre[:, None, 2]
    near = np.array([np.mean(shape.query((a["positions"][f, knots] - centre[f])
                                         @ so3.quat_to_matrix(q[f])).distance < NEAR)
                     for f in range(len(a["time"]))])
    net_velocity = np.einsum("n,fni->fi", p.mass, a["velocities"]) / p.mass.sum()
    return {"least_behind": behind.min(axis=1), "knots_near": near,
            "relative_speed": np.linalg.norm(net_velocity - a["body_velocities"][:, 0], axis=1)}


def figure(data: dict[str, tuple[dict, dict, dict]], path: Path) -> None:
    """Contact force, target speed, target spin and the capture measures of every variant."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(2, 2, figsize=(11, 7), sharex=True)
    for variant, (_, a, m) in data.items():
        colour, line = STYLE[variant]
        t = a["time"]
        axes[0, 0].plot(t, a["contact_force"], color=colour, ls=line, lw=0.8, label=variant)
        axes[0, 1].plot(t, 100 * a["body_velocities"][:, 0, 2], color=colour, ls=line,
                        label=variant)
        w = np.degrees(a["body_angular_velocities"][:, 0])
        axes[1, 0].plot(t, w[:, 1], color=colour, ls=line, label=f"{variant}: omega_y")
        axes[1, 1].plot(t, m["least_behind"], color=colour, ls=line, label=variant)
        axes[1, 1].plot(t, 10 * m["knots_near"], color=colour, ls=":", lw=0.8)
    axes[1, 1].axhline(RADIUS, color="0.5", lw=0.5)
    axes[0, 0].set_ylabel("contact force [N] (sum of |point force|)")
    axes[0, 1].set_ylabel("target velocity down-range [cm/s]")
    axes[1, 0].set_ylabel("target tumbling rate [deg/s]")
    axes[1, 1].set_ylabel(f"corner mass least behind centre [m];\ndotted: 10 x knots within {NEAR} m")
    for ax in axes.ravel():
        ax.legend(fontsize=7)
    for ax in axes[1]:
        ax.set_xlabel("time [s]")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def report(duration: float) -> tuple[str, list[Path]]:
    """Write ``out/bending_capture.md`` and ``out/capture_bending.png`` from the stored runs;
    returns the report's text and the files written."""
    data = {}
    for variant in VARIANTS:
        if (folder(variant) / "summary.json").is_file():
            summary, a = load(variant)
            data[variant] = (summary, a, measures(variant, summary, a, duration))
    rows = [["variant", "status", "wall [s]", "steps", "smallest step [s]", "rotary inertia x",
             "largest contact force [N]", "friction work [J]", "largest thread tension [N]",
             "corners behind from [s]", "at the end: v [cm/s]", "omega [deg/s]",
             "knots within 0.5 m", "net relative speed [cm/s]"]]
    for variant, (s, a, m) in data.items():
        behind = m["least_behind"] > RADIUS
        since = f"{a['time'][np.argmax(behind)]:.2f}" if behind.any() else "never"
        integrator = s["integrator"]
        ok = s["status"] == "ok"   # a failed run's step statistics include its diverging steps
        rows.append([variant, s["status"] + ("" if ok else f" at {a['time'][-1]:.2f} s"),
                     f"{s['wall_time_s']:.0f}", f"{s['steps']}",
                     f"{integrator['dt_min']:.3g}" if ok else "-",
                     f"{integrator.get('rotary_inertia_scale') or 1:.3g}",
                     f"{a['contact_force'].max():.0f}", f"{a['friction_work'][-1]:.1f}",
                     f"{s['metrics']['max_tension']:.0f}" if ok else "-",
                     since, np.array2string(100 * a["body_velocities"][-1, 0], precision=2),
                     np.array2string(np.degrees(a["body_angular_velocities"][-1, 0]), precision=2),
                     f"{100 * m['knots_near'][-1]:.0f} %", f"{100 * m['relative_speed'][-1]:.1f}"])
    # the window every variant reached: compare with and without bending on equal terms
    common = min(a["time"][-1] for _, a, _ in data.values())
    window = [["variant", f"largest contact force to {common:.2f} s [N]",
               f"friction work at {common:.2f} s [J]",
               f"largest thread tension at the frames to {common:.2f} s [N]",
               f"target v at {common:.2f} s [cm/s]", "omega [deg/s]", "knots within 0.5 m"]]
    for variant, (s_, a, m) in data.items():
        f = int(np.searchsorted(a["time"], common - 1e-9))
        window.append([variant, f"{a['contact_force'][:f + 1].max():.0f}",
                       f"{a['friction_work'][f]:.1f}", f"{a['tension'][:f + 1].max():.0f}",
                       np.array2string(100 * a["body_velocities"][f, 0], precision=2),
                       np.array2string(np.degrees(a["body_angular_velocities"][f, 0]), precision=2),
                       f"{100 * m['knots_near'][f]:.0f} %"])
    state = [["t [s]", *data]]
    for instant in INSTANTS:
        row = [f"{instant:.1f}"]
        for variant, (_, a, m) in data.items():
            f = int(np.argmin(np.abs(a["time"] - instant)))
            row.append(f"{a['contact_force'][f]:.0f} N, v_z {100 * a['body_velocities'][f, 0, 2]:.2f} cm/s, "
                       f"{100 * m['knots_near'][f]:.0f} % near" if abs(a["time"][f] - instant) < 0.011
                       else "-")
        state.append(row)
    written = []
    OUT.mkdir(parents=True, exist_ok=True)
    if data:
        figure(data, OUT / "capture_bending.png")
        written.append(OUT / "capture_bending.png")
    text = f"""# Capture with and without bending: results

Written by `bending_capture.py` ({duration:g} s, frames every 0.02 s, explicit integrator,
wall times on the shared 2-core machine). Figure: `docs/img/capture_bending.png`. Discussion:
`docs/capture.md`.

{table(rows)}

"corners behind from": the first frame at which all four corner masses are behind the target's
centre by more than its radius. "largest thread tension": over every step (not shown for a run
that failed: its step statistics include the diverging steps). A failed run's other columns are
those of its last saved frame.

## Up to {common:.2f} s, the time every variant reached

{table(window)}

## Over time (contact force, target velocity down-range, knots within {NEAR} m)

{table(state)}
"""
    (OUT / "bending_capture.md").write_text(text)
    return text, [OUT / "bending_capture.md", *written]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--duration", type=float, default=6.0)
    parser.add_argument("--only", choices=list(VARIANTS), action="append")
    parser.add_argument("--report", action="store_true", help="only write the report")
    parser.add_argument("--publish", action="store_true",
                        help="also write the tracked bending_capture.md beside this script and "
                             "docs/img/capture_bending.png (default: only out/)")
    args = parser.parse_args()
    if not args.report:
        for variant in args.only or VARIANTS:
            if not (folder(variant) / "summary.json").is_file():
                run_variant(variant, args.duration)
    text, written = report(args.duration)
    print(text)
    published = None
    if args.publish:
        tracked = {"bending_capture.md": HERE / "bending_capture.md",
                   "capture_bending.png": IMG / "capture_bending.png"}
        published = {p: tracked[p.name] for p in written}
        publish(published)
    report_written("bending capture", written, published)


if __name__ == "__main__":
    main()
