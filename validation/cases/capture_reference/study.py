"""The capture study: the reference net shot at a tumbling SL-8-like upper stage.

The net is the built-in reference deployment (``rodnet demo``, lumped model, explicit); the target
is a free cylinder of 2.4 m diameter, 6.5 m length and 1400 kg whose centre is 15 m down-range,
its axis across the shooting direction (world x), tumbling end over end at 2 deg/s (about world
y), with friction 0.3, for 6 s. The same capture runs with the target as an STL file of the same
cylinder (64 facets around, written here with trimesh). Two more cylinder runs, their radius
smaller by the STL's faceting error (the facets' inscribed radius ``R cos(pi/64)``) and by half
of it, measure how far a change of the target of that size moves the capture. A third pair of
runs measures what contact costs while the target is far: the 3 s reference deployment without a
body and with the cylinder 100 m down-range.

Writes everything into ``out/`` beside this script (not kept in git): the runs, their scenes, the
STL, ``results.md`` (the tables) and the figures ``capture_shapes.png`` and
``capture_history.png``. Only with ``--publish`` does it also write the tracked copies:
``results.md`` beside this script and ``docs/img/capture_shapes.png``,
``docs/img/capture_history.png``. Usage, from the repository root, with one BLAS thread:
``OPENBLAS_NUM_THREADS=1 .venv/bin/python validation/cases/capture_reference/study.py
[--duration 6] [--repeats 3] [--publish]``.
"""

from __future__ import annotations

import argparse
import shutil
import time
from pathlib import Path
from typing import Any

import numpy as np

from rodnet.cli import demo_scene_text
from rodnet.contact.surfaces import surface_triangles
from rodnet.io.recorder import Recorder
from rodnet.kernels import so3
from rodnet.run import RunResult, prepare, run
from rodnet.scene import load_scene, scene_from_toml

HERE = Path(__file__).parent
OUT = HERE / "out"                         # everything the study writes (not kept in git)
IMG = HERE.parents[2] / "docs" / "img"     # the published figures (``--publish`` only)
RADIUS, LENGTH, MASS = 1.2, 6.5, 1400.0
SECTIONS = 64                              # facets around the STL cylinder
FACETING = RADIUS * (1.0 - np.cos(np.pi / SECTIONS))   # m: the facets' largest distance to it
INSTANTS = (1.2, 1.6, 2.5, 4.0, 6.0)      # s, the net shapes shown
NEAR = 0.5                                 # m: a knot this close to the surface is "on" the target

CONTACT = """
[contact]
stiffness = 1.0e4
damping = 2.0
friction = 0.3
"""


def body_table(shape: str, distance: float, radius: float = RADIUS) -> str:
    """The ``[[bodies]]`` table of the target: a cylinder primitive of ``radius`` [m] or the STL
    mesh."""
    diameter = float(2 * radius)
    geometry = (f'shape = "cylinder"\nsize = [{diameter!r}, {diameter!r}, {LENGTH}]'
                if shape == "cylinder" else 'shape = "mesh"\nfile = "sl8.stl"')
    return f"""
[[bodies]]
name = "sl8"
{geometry}
mass = {MASS}
position = [0.0, 0.0, {distance}]
orientation_deg = [0.0, 90.0, 0.0]
angular_velocity_deg = [0.0, 2.0, 0.0]
"""


def scene_text(shape: str | None, distance: float = 15.0, radius: float = RADIUS) -> str:
    """The reference deployment, with the target (``shape`` "cylinder" of ``radius`` [m] or
    "mesh") or without."""
    text = demo_scene_text().replace("picture = true", "picture = false") \
        .replace("plot = true", "plot = false")
    return text if shape is None else text + body_table(shape, distance, radius) + CONTACT


def write_stl() -> Path:
    """The target as a closed STL cylinder (axis z, centred), 64 facets around."""
    import trimesh

    OUT.mkdir(parents=True, exist_ok=True)
    path = OUT / "sl8.stl"
    trimesh.creation.cylinder(radius=RADIUS, height=LENGTH, sections=SECTIONS).export(path)
    return path


class FrameTimer:
    """Wraps the run's recorder to add up the time spent saving frames."""

    def __init__(self) -> None:
        self.seconds = 0.0
        self._original = Recorder.__call__

    def __enter__(self) -> FrameTimer:
        timer, original = self, self._original

        def timed(recorder: Recorder, t: float, state: Any) -> None:
            start = time.perf_counter()
            try:
                original(recorder, t, state)
            finally:
                timer.seconds += time.perf_counter() - start

        Recorder.__call__ = timed  # type: ignore[method-assign]
        return self

    def __exit__(self, *exc: object) -> None:
        Recorder.__call__ = self._original  # type: ignore[method-assign]


def capture(shape: str, duration: float, vtk: bool, radius: float = RADIUS,
            label: str | None = None) -> tuple[RunResult, float, float]:
    """Run the capture with the target as ``shape`` (a cylinder of ``radius`` [m]); returns the
    result, the wall time of the run [s] and the part of it spent saving frames [s]. ``label``
    names the run's folder (default: ``shape``)."""
    folder = OUT / f"capture_{label or shape}"
    folder.mkdir(parents=True, exist_ok=True)
    scene_file = OUT / f"capture_{label or shape}.toml"
    scene_file.write_text(scene_text(shape, radius=radius))
    scene = load_scene(scene_file, [f"simulation.duration={duration:g}",
                                    "output.frame_interval=0.02", f"output.vtk={str(vtk).lower()}"])
    with FrameTimer() as timer:
        result = run(scene, folder, progress=None)
    assert result.status == "ok", result.message
    return result, float(result.summary["wall_time_s"]), timer.seconds


def deployment_wall(shape: str | None, repeats: int, duration: float) -> tuple[float, int]:
    """Smallest wall time [s] of ``repeats`` runs of the reference deployment (no VTK) with the
    target 100 m away (``shape``) or without it, and the number of steps."""
    walls, steps = [], 0
    for _ in range(repeats):
        scene = scene_from_toml(scene_text(shape, 100.0),
                                [f"simulation.duration={duration:g}", "output.vtk=false"])
        result = run(scene, OUT / f"far_{shape}", progress=None)
        walls.append(float(result.summary["wall_time_s"]))
        steps = int(result.summary["steps"])
    return min(walls), steps


def capture_measures(result: RunResult, shape: str) -> dict[str, np.ndarray]:
    """Per frame: corner masses behind the target, knots near its surface, relative speed."""
    a = result.arrays
    scene = scene_from_toml(scene_text(shape)) if shape == "cylinder" else \
        load_scene(OUT / f"capture_{shape}.toml")
    p_ = prepare(scene)
    model, contact = p_.model, p_.system.contact.bodies
    corners = [result.summary["nodes"][f"net:corner:{i}"] for i in range(4)]
    knots = np.arange(scene.net.nodes_per_side**2)   # knots are numbered first
    p, q = a["body_positions"][:, 0], a["body_rotations"][:, 0]
    behind = a["positions"][:, corners, 2] - p[:, None, 2]
    near = np.zeros(len(a["time"]))
    for f in range(len(a["time"])):
        R = so3.quat_to_matrix(q[f])
        local = (a["positions"][f, knots] - p[f]) @ R
        near[f] = np.mean(contact.shapes[0].query(local).distance < NEAR)
    mass = model.mass
    net_velocity = np.einsum("n,fni->fi", mass, a["velocities"]) / mass.sum()
    relative = np.linalg.norm(net_velocity - a["body_velocities"][:, 0], axis=1)
    return {"corners_behind": (behind > RADIUS).all(axis=1), "least_behind": behind.min(axis=1),
            "knots_near": near, "relative_speed": relative}


def shapes_figure(result: RunResult, path: Path) -> None:
    """Side views (x-z, the tumbling plane; y-z, along the target's axis at t = 0) of the net
    and the target at :data:`INSTANTS`."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.collections import LineCollection
    from scipy.spatial import ConvexHull

    a = result.arrays
    surface = surface_triangles(prepare(scene_from_toml(scene_text("cylinder"))).system
                                .contact.bodies.shapes[0])[0]
    corners = [result.summary["nodes"][f"net:corner:{i}"] for i in range(4)]
    fig, axes = plt.subplots(2, len(INSTANTS), figsize=(3.2 * len(INSTANTS), 6.4), sharey=True)
    for column, instant in enumerate(INSTANTS):
        f = int(np.argmin(np.abs(a["time"] - instant)))
        x = a["positions"][f]
        lines = x[a["segments"]]
        R = so3.quat_to_matrix(a["body_rotations"][f, 0])
        world = a["body_positions"][f, 0] + surface @ R.T
        for row, (i, label) in enumerate(((0, "x"), (1, "y"))):
            ax = axes[row, column]
            ax.add_collection(LineCollection(lines[:, :, [i, 2]], colors="tab:blue", lw=0.4))
            hull = ConvexHull(world[:, [i, 2]])
            ax.fill(*world[hull.vertices][:, [i, 2]].T, color="0.6", alpha=0.8, lw=0)
            ax.plot(*x[corners][:, [i, 2]].T, "ro", ms=3)
            ax.set_aspect("equal")
            ax.set_xlim(-12, 12)
            ax.set_ylim(5, 30)
            ax.set_xlabel(f"{label} [m]")
            if column == 0:
                ax.set_ylabel("z, down-range [m]")
            if row == 0:
                ax.set_title(f"t = {a['time'][f]:.2f} s")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def history_figure(results: dict[str, RunResult], measures: dict[str, dict[str, np.ndarray]],
                   path: Path) -> None:
    """Contact force, target speed and angular velocity, corners behind and knots on the target."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(2, 2, figsize=(11, 7), sharex=True)
    styles = {"cylinder": ("k", "-", "cylinder primitive"), "mesh": ("tab:red", "--", "STL mesh")}
    for shape, result in results.items():
        colour, line, label = styles[shape]
        a, t = result.arrays, result.arrays["time"]
        axes[0, 0].plot(t, a["contact_force"], color=colour, ls=line, lw=0.8, label=label)
        axes[0, 1].plot(t, 100 * a["body_velocities"][:, 0, 2], color=colour, ls=line,
                        label=f"{label}: v_z")
        axes[0, 1].plot(t, 100 * np.linalg.norm(a["body_velocities"][:, 0, :2], axis=1),
                        color=colour, ls=":", label=f"{label}: |v_xy|")
        w = np.degrees(a["body_angular_velocities"][:, 0])
        axes[1, 0].plot(t, w[:, 1], color=colour, ls=line, label=f"{label}: omega_y")
        axes[1, 0].plot(t, np.linalg.norm(w[:, [0, 2]], axis=1), color=colour, ls=":",
                        label=f"{label}: |omega_xz|")
        axes[1, 1].plot(t, measures[shape]["least_behind"], color=colour, ls=line,
                        label=f"{label}: corner mass least behind centre")
        axes[1, 1].plot(t, 10 * measures[shape]["knots_near"], color=colour, ls=":",
                        label=f"{label}: 10 x fraction of knots within {NEAR} m")
    axes[1, 1].axhline(RADIUS, color="0.5", lw=0.5)
    axes[0, 0].set_ylabel("contact force [N] (sum of |point force|)")
    axes[0, 1].set_ylabel("target velocity [cm/s]")
    axes[1, 0].set_ylabel("target angular velocity [deg/s]")
    axes[1, 1].set_ylabel("capture measures [m], [-]")
    for ax in axes.ravel():
        ax.legend(fontsize=7)
    for ax in axes[1]:
        ax.set_xlabel("time [s]")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def table(rows: list[list[str]]) -> str:
    lines = ["| " + " | ".join(rows[0]) + " |", "|" + "---|" * len(rows[0])]
    return "\n".join(lines + ["| " + " | ".join(r) + " |" for r in rows[1:]])


def at(result: RunResult, key: str, instant: float) -> np.ndarray:
    f = int(np.argmin(np.abs(result.arrays["time"] - instant)))
    return result.arrays[key][f]


def publish(files: dict[Path, Path]) -> None:
    """Copy each written file (key) to its tracked place (value)."""
    for source, target in files.items():
        target.parent.mkdir(parents=True, exist_ok=True)
        shutil.copyfile(source, target)


def report_written(name: str, written: list[Path], published: dict[Path, Path] | None) -> None:
    """Print where the results were written and, with ``--publish``, where they were copied."""
    print(f"{name}: results written to {OUT}/: " + ", ".join(p.name for p in written))
    if published:
        print(f"{name}: published (tracked files rewritten): "
              + ", ".join(str(p) for p in published.values()))
    else:
        print(f"{name}: tracked files left unchanged (rerun with --publish to rewrite them)")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--duration", type=float, default=6.0)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--publish", action="store_true",
                        help="also write the tracked results.md beside this script and "
                             "docs/img/capture_shapes.png, docs/img/capture_history.png "
                             "(default: only out/)")
    args = parser.parse_args()
    write_stl()
    results, walls, measures = {}, {}, {}
    for shape in ("cylinder", "mesh"):
        result, wall, frames = capture(shape, args.duration, vtk=shape == "cylinder")
        wall_quiet, frames_quiet = wall, frames
        if shape == "cylinder":  # once more without VTK, for the cost of the loop alone
            _, wall_quiet, frames_quiet = capture(shape, args.duration, vtk=False)
        results[shape] = result
        walls[shape] = (wall, frames, wall_quiet, frames_quiet)
        measures[shape] = capture_measures(result, shape)
        print(shape, walls[shape], result.summary["steps"])
    perturbed = {f"cylinder, radius - {1000 * cut:.2f} mm":
                 capture("cylinder", args.duration, False, RADIUS - cut, f"cut_{i}")[0]
                 for i, cut in enumerate((FACETING / 2, FACETING))}
    free_wall, free_steps = deployment_wall(None, args.repeats, args.duration)
    far_wall, far_steps = deployment_wall("cylinder", args.repeats, 3.0)
    base_wall, base_steps = deployment_wall(None, args.repeats, 3.0)
    OUT.mkdir(parents=True, exist_ok=True)
    shapes_figure(results["cylinder"], OUT / "capture_shapes.png")
    history_figure(results, measures, OUT / "capture_history.png")
    write_results(results, walls, measures, (free_wall, free_steps),
                  (base_wall, base_steps, far_wall, far_steps), args.duration, perturbed)
    written = [OUT / "results.md", OUT / "capture_shapes.png", OUT / "capture_history.png"]
    published = None
    if args.publish:
        published = {written[0]: HERE / "results.md", written[1]: IMG / "capture_shapes.png",
                     written[2]: IMG / "capture_history.png"}
        publish(published)
    report_written("capture study", written, published)


def faceting_table(results: dict[str, RunResult], perturbed: dict[str, RunResult]) -> str:
    """How far from the cylinder run the STL run and the runs in ``perturbed`` (label: result)
    are, at several instants."""
    cyl = results["cylinder"].arrays
    others = {"STL mesh": results["mesh"].arrays,
              **{label: r.arrays for label, r in perturbed.items()}}
    rows = [["difference from the cylinder run", "t [s]", *others]]
    for instant in (1.6, 2.5, 3.0, 4.5, cyl["time"][-1]):
        f = int(np.argmin(np.abs(cyl["time"] - instant)))
        def cells(key: str, scale: float) -> list[str]:
            return [f"{scale * np.linalg.norm(a[key][f, 0] - cyl[key][f, 0]):.3g}"
                    for a in others.values()]
        knots = [np.linalg.norm(a["positions"][f, :441] - cyl["positions"][f, :441], axis=1).mean()
                 for a in others.values()]
        rows += [["target velocity [cm/s]", f"{cyl['time'][f]:.2f}",
                  *cells("body_velocities", 100)],
                 ["target angular velocity [deg/s]", "", *cells("body_angular_velocities",
                                                                180 / np.pi)],
                 ["knot positions, mean [m]", "", *[f"{k:.3g}" for k in knots]]]
    rows.append(["largest contact force [N] (cylinder "
                 f"{cyl['contact_force'].max():.0f})", "",
                 *[f"{a['contact_force'].max():.0f}" for a in others.values()]])
    rows.append([f"friction work [J] (cylinder {cyl['friction_work'][-1]:.1f})", "",
                 *[f"{a['friction_work'][-1]:.1f}" for a in others.values()]])
    return table(rows)


def write_results(results: dict[str, RunResult], walls: dict[str, tuple[float, ...]],
                  measures: dict[str, dict[str, np.ndarray]], free: tuple[float, int],
                  far: tuple[float, int, float, int], duration: float,
                  perturbed: dict[str, RunResult]) -> None:
    """``out/results.md``: the tables of the study (``--publish`` copies it beside the script)."""
    per_step = free[0] / free[1]   # the loop without contact, per step
    rows = [["target", "steps", "smallest step [s]", "wall, no VTK [s]", "of which: frames [s]",
             "loop without contact (est.) [s]", "contact (rest) [s]", "wall with VTK [s]",
             "of which: frames and VTK [s]"]]
    for shape, r in results.items():
        wall, frames, quiet, frames_quiet = walls[shape]
        steps = int(r.summary["steps"])
        loop = per_step * steps
        rows.append([shape, f"{steps}", f"{r.summary['integrator']['dt_min']:.3g}",
                     f"{quiet:.2f}", f"{frames_quiet:.2f}", f"{loop:.2f}",
                     f"{quiet - frames_quiet - loop:.2f}",
                     f"{wall:.2f}" if shape == "cylinder" else "-",
                     f"{frames:.2f}" if shape == "cylinder" else "-"])
    state = [["t [s]", "target", "contact force [N]", "contact points", "v [cm/s]",
              "omega [deg/s]", "corners behind", "knots within 0.5 m"]]
    for instant in INSTANTS:
        for shape, r in results.items():
            f = int(np.argmin(np.abs(r.arrays["time"] - instant)))
            m = measures[shape]
            state.append([f"{r.arrays['time'][f]:.2f}", shape,
                          f"{r.arrays['contact_force'][f]:.1f}", f"{r.arrays['contact_count'][f]}",
                          np.array2string(100 * r.arrays["body_velocities"][f, 0], precision=3),
                          np.array2string(np.degrees(r.arrays["body_angular_velocities"][f, 0]),
                                          precision=3),
                          "yes" if m["corners_behind"][f] else "no",
                          f"{100 * m['knots_near'][f]:.0f} %"])
    cyl, mesh = results["cylinder"].arrays, results["mesh"].arrays
    diff = [["quantity", "cylinder", "STL mesh", "difference"]]
    for key, scale, unit in (("body_velocities", 100, "cm/s"),
                             ("body_angular_velocities", 180 / np.pi, "deg/s"),
                             ("body_positions", 1000, "mm")):
        a, b = scale * cyl[key][-1, 0], scale * mesh[key][-1, 0]
        diff.append([f"{key} at {cyl['time'][-1]:.1f} s [{unit}]", np.array2string(a, precision=4),
                     np.array2string(b, precision=4), f"{np.linalg.norm(a - b):.3g}"])
    for key, label in (("contact_force", "largest contact force [N]"),):
        diff.append([label, f"{cyl[key].max():.1f}", f"{mesh[key].max():.1f}",
                     f"{abs(cyl[key].max() - mesh[key].max()) / cyl[key].max():.1%}"])
    diff.append(["friction work [J]", f"{cyl['friction_work'][-1]:.2f}",
                 f"{mesh['friction_work'][-1]:.2f}",
                 f"{abs(cyl['friction_work'][-1] - mesh['friction_work'][-1]) / cyl['friction_work'][-1]:.1%}"])
    knots = cyl["positions"][-1, :441] - mesh["positions"][-1, :441]
    diff.append(["knot positions at the end: largest / mean distance [mm]", "", "",
                 f"{1000 * np.linalg.norm(knots, axis=1).max():.1f} / "
                 f"{1000 * np.linalg.norm(knots, axis=1).mean():.1f}"])
    base_wall, base_steps, far_wall, far_steps = far
    overhead = [["3 s reference deployment", "steps", "wall [s] (best of repeats)"],
                ["no body", f"{base_steps}", f"{base_wall:.3f}"],
                ["cylinder 100 m down-range", f"{far_steps}", f"{far_wall:.3f}"],
                ["contact overhead", "", f"{far_wall / base_wall - 1:+.1%}"]]
    m = measures["cylinder"]
    text = f"""# Capture study: results

Written by `study.py` ({duration:g} s, frames every 0.02 s). Figures:
`docs/img/capture_shapes.png`, `docs/img/capture_history.png`. Discussion: `docs/capture.md`.

## Wall time and its parts

{table(rows)}

"frames" is the time spent saving frames (frame arrays, energies, the contact totals of the
frame, VTK files when written). "loop without contact" is the capture's number of steps times the
cost per step of the same net's loop without a body (the {duration:g} s reference deployment,
{free[1]} steps in {free[0]:.2f} s); "contact" is the rest: contact forces, the bodies' update,
the broad-phase checks and the shorter steps' extra Python round trips.

## Contact while the target is far

{table(overhead)}

## The target and the capture over time (capture measures in `docs/capture.md`)

{table(state)}

At the end ({results['cylinder'].arrays['time'][-1]:.1f} s, cylinder): all four corner masses
behind the target's centre by more than its radius: {"yes" if m['corners_behind'][-1] else "no"}
(since t = {results['cylinder'].arrays['time'][np.argmax(m['corners_behind'])]:.2f} s, and
{"on every frame since" if m['corners_behind'][np.argmax(m['corners_behind']):].all() else "not on every frame since"});
knots within {NEAR} m of the surface: {100 * m['knots_near'][-1]:.0f} %; net centre of mass
relative to the target: {100 * m['relative_speed'][-1]:.1f} cm/s.

## Cylinder primitive against the STL file of the same cylinder ({SECTIONS} facets)

{table(diff)}

## The STL's differences against those of a cylinder changed by the faceting error

The STL's facets lie between the cylinder's radius and {1000 * FACETING:.2f} mm inside it.

{faceting_table(results, perturbed)}
"""
    OUT.mkdir(parents=True, exist_ok=True)
    (OUT / "results.md").write_text(text)
    print(text)


if __name__ == "__main__":
    main()
