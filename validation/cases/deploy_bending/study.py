"""The bending study: the reference deployment without bending, with a braided thread's bending
stiffness and with the solid section's, for rigid and for pinned knots.

Every variant is the built-in reference deployment (``rodnet demo``) with overrides; the threads
are Cosserat rod elements (``elements_per_thread`` below), integrated by generalized-alpha with
the local error control. "No bending" is the cable model (bending and torsion off: the lumped
physics with implicit integration). The braided thread keeps the solid section's axial
stiffness but only ``BRAIDED`` of its bending and torsional stiffness (a braid's fibres slide on
each other in bending; the fraction is a documented assumption, not a measurement).

Writes everything into ``out/`` beside this script (not kept in git): the runs ``out/<variant>/``
(a rerun with ``--reuse`` reads them instead of running again), the table ``out/results.md`` and
the figures ``out/bending_*.png``; with ``--explicit``, into ``out_explicit_n<n>/`` instead: the
runs, ``results_explicit_n<n>.md`` and ``bending_explicit_n<n>_*.png``. Only with ``--publish``
are the tracked copies written too: the table beside this script (``results.md`` or
``results_explicit_n<n>.md``) and the figures under ``docs/img/`` (``bending_*.png`` or
``bending_explicit_n<n>_*.png``).
The two ``dt_max 1e-4`` variants repeat the rigid-knot runs without the error control (steps of
at most 0.1 ms, halved only when Newton's method fails). Every variant has a wall-time limit
(``--limit``); a run that reaches it is interrupted like Ctrl-C and keeps its frames.

With ``--explicit`` every variant runs with the explicit integrator instead (rods with scaled
rotary inertia, FORMULATION.md §9b; the cables as the lumped model), and the ``dt_max`` variants,
which are about implicit step control, are left out.

Usage, from the repository root, with one BLAS thread:
``OPENBLAS_NUM_THREADS=1 .venv/bin/python validation/cases/deploy_bending/study.py [--n 1]
[--tolerance 1e-4] [--explicit] [--duration 3] [--limit 900] [--only NAME] [--reuse]
[--publish]``.
"""

from __future__ import annotations

import argparse
import json
import math
import shutil
import signal
import time
from pathlib import Path

import numpy as np

from rodnet.cli import demo_scene_text
from rodnet.run import RunResult, run
from rodnet.scene import scene_from_toml

HERE = Path(__file__).parent
IMG = HERE.parents[2] / "docs" / "img"     # the published figures (``--publish`` only)
BRAIDED = 0.01
E, G, D = 7.0e10, 7.0e10 / (2 * 1.36), 1.0e-3     # the reference Kevlar thread
SOLID_EI, SOLID_GJ = E * math.pi * D**4 / 64, G * math.pi * D**4 / 32
FIXED = ("simulation.dt=1e-4", "simulation.dt_max=1e-4")
INSTANTS = (0.5, 1.3, 3.0)                           # s, the net shapes shown
COLOURS = {"no bending": "k", "braided, rigid knots": "tab:orange",
           "braided, pinned knots": "tab:blue", "solid, rigid knots": "tab:red",
           "solid, pinned knots": "tab:green", "braided, rigid knots, dt_max 1e-4": "tab:purple",
           "solid, rigid knots, dt_max 1e-4": "tab:brown"}


def variants() -> dict[str, tuple[str, ...]]:
    """Name -> overrides of every variant."""
    braided = (f"materials[0].bending_stiffness={BRAIDED * SOLID_EI:.6g}",
               f"materials[0].torsional_stiffness={BRAIDED * SOLID_GJ:.6g}")
    return {
        "no bending": ("model.bending=false", "model.torsion=false", "model.knots=pinned"),
        "braided, rigid knots": ("model.knots=rigid", *braided),
        "braided, pinned knots": ("model.knots=pinned", *braided),
        "solid, rigid knots": ("model.knots=rigid",),
        "solid, pinned knots": ("model.knots=pinned",),
        # the rigid-knot variants once more with steps of at most 0.1 ms that are only halved
        # when Newton's method fails (no error control), as in docs/rod_model.md
        "braided, rigid knots, dt_max 1e-4": ("model.knots=rigid", *braided, *FIXED),
        "solid, rigid knots, dt_max 1e-4": ("model.knots=rigid", *FIXED),
    }


OUT = HERE / "out"
"""Where the runs, the table and the figures go: ``out/`` (implicit) or ``out_explicit_n<n>/``
(``--explicit``)."""
PREFIX = "bending_"
"""File-name prefix of the figures: ``bending_`` or ``bending_explicit_n<n>_``."""


def folder_of(name: str) -> Path:
    return OUT / name.replace(", ", "_").replace(" ", "_")


def _interrupt(signum: int, frame: object) -> None:
    raise KeyboardInterrupt  # the run keeps its frames and says it was interrupted


def run_variant(name: str, overrides: tuple[str, ...], n: int, tolerance: float,
                duration: float, limit: float, explicit: bool = False) -> tuple[RunResult, float]:
    """Run one variant, interrupted (as Ctrl-C) after ``limit`` s of wall time; returns the
    result and the wall time [s] including the model build."""
    control = () if any(o.startswith("simulation.dt_max") for o in overrides) else \
        (f"simulation.error_tolerance={tolerance:g}",)
    stepping = ("simulation.integrator=explicit",) if explicit else \
        ("simulation.integrator=generalized-alpha", "simulation.adaptive=true", *control)
    common = ("model.type=cosserat", f"model.elements_per_thread={n}", *stepping,
              f"simulation.duration={duration:g}",
              "output.vtk=false", "output.picture=false", "output.plot=false")
    scene = scene_from_toml(demo_scene_text(), (*common, *overrides))
    folder = folder_of(name)
    start = time.perf_counter()
    signal.signal(signal.SIGALRM, _interrupt)
    signal.alarm(max(1, int(limit)))
    try:
        result = run(scene, folder, progress=None)
    finally:
        signal.alarm(0)
    wall = time.perf_counter() - start
    (folder / "study.json").write_text(json.dumps({"wall_s": wall, "limit_s": limit,
                                                   "overrides": [*common, *overrides]}))
    return result, wall


def load_variant(name: str) -> tuple[RunResult, float] | None:
    """The stored run of a variant, or None when it has not been run."""
    folder = folder_of(name)
    if not (folder / "study.json").is_file():
        return None
    summary = json.loads((folder / "summary.json").read_text())
    with np.load(folder / "result.npz") as data:
        arrays = {k: data[k] for k in data.files}
    wall = json.loads((folder / "study.json").read_text())["wall_s"]
    return RunResult(summary["status"], summary["message"], folder, summary, arrays), wall


def figures(results: dict[str, RunResult]) -> list[Path]:
    """Draw the figures into :data:`OUT`; returns the files written."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (a1, a2, a3) = plt.subplots(3, 1, figsize=(7.5, 9.5), sharex=True)
    zoom = a1.inset_axes((0.06, 0.45, 0.3, 0.45))
    base = results.get("no bending")
    for name, r in results.items():
        t = r.arrays["time"]
        style = dict(color=COLOURS.get(name), lw=1.2 if "pinned" in name or name == "no bending" else 2.0,
                     ls="--" if "pinned" in name else "-")
        stopped = "" if r.status == "ok" else f" (ends at {t[-1]:.2f} s)"
        a1.plot(t, r.arrays["mouth_area"], label=name + stopped, **style)
        zoom.plot(t, r.arrays["mouth_area"], **style)
        a2.plot(t, r.arrays["distance"], **style)
        if base is not None and r is not base:
            k = min(len(t), len(base.arrays["time"]))
            a3.plot(t[:k], r.arrays["mouth_area"][:k] - base.arrays["mouth_area"][:k], **style)
    zoom.set_xlim(0.0, 0.16)
    zoom.set_ylim(0.0, 30.0)
    zoom.set_title("first 0.16 s", fontsize=7)
    zoom.tick_params(labelsize=6)
    zoom.grid(alpha=0.3)
    a1.set_ylabel("mouth area [m$^2$]")
    a2.set_ylabel("distance travelled [m]")
    a3.set_ylabel("mouth area minus that of\nthe run without bending [m$^2$]")
    a3.set_xlabel("time [s]")
    a1.legend(fontsize=7, loc="upper right")
    for a in (a1, a2, a3):
        a.grid(alpha=0.3)
    fig.suptitle("Reference deployment (21 x 21 knots, 1 mm Kevlar, 20 m/s):\n"
                 "threads without bending, with 1 % of the solid EI (braided) and with the solid EI",
                 fontsize=10)
    fig.tight_layout()
    fig.savefig(OUT / f"{PREFIX}histories.png", dpi=110)
    plt.close(fig)
    shapes = _shapes(results, plt)
    _tensions(results, plt)
    return [OUT / f"{PREFIX}histories.png", *shapes, OUT / f"{PREFIX}tension.png"]


def _shapes(results: dict[str, RunResult], plt) -> list[Path]:
    """The net at ``INSTANTS``, one row per variant that got that far (3-D line plots); returns
    the file written (none when no variant reached the first instant)."""
    from mpl_toolkits.mplot3d.art3d import Line3DCollection

    shown = [n for n, r in results.items() if r.arrays["time"][-1] >= INSTANTS[0] - 1e-9]
    if not shown:
        return []
    fig = plt.figure(figsize=(11, 3.6 * len(shown)))
    for i, name in enumerate(shown):
        r = results[name]
        for j, when in enumerate(INSTANTS):
            ax = fig.add_subplot(len(shown), 3, 3 * i + j + 1, projection="3d")
            if r.arrays["time"][-1] < when - 1e-9:
                ax.set_title(f"{name}: stopped at {r.arrays['time'][-1]:.2f} s", fontsize=8)
                ax.set_axis_off()
                continue
            k = int(np.argmin(np.abs(r.arrays["time"] - when)))
            x = r.arrays["positions"][k]
            ax.add_collection3d(Line3DCollection(x[r.arrays["segments"]], colors=COLOURS.get(name, "k"),
                                                 linewidths=0.4))
            half = 0.5 * float(np.ptp(x, axis=0).max()) + 0.5    # one scale on all three axes
            mid = 0.5 * (x.min(axis=0) + x.max(axis=0))
            ax.set_xlim(mid[0] - half, mid[0] + half)
            ax.set_ylim(mid[1] - half, mid[1] + half)
            ax.set_zlim(mid[2] - half, mid[2] + half)
            ax.set_box_aspect((1, 1, 1))
            ax.view_init(elev=20, azim=-60)
            ax.set_xlabel("x [m]", fontsize=7)
            ax.set_ylabel("y [m]", fontsize=7)
            ax.set_zlabel("z [m]", fontsize=7)
            ax.tick_params(labelsize=6)
            ax.set_title(f"{name}, t = {r.arrays['time'][k]:.2f} s, "
                         f"area {r.arrays['mouth_area'][k]:.0f} m$^2$", fontsize=8)
    fig.suptitle("Net shape (knots, threads, corner masses); shooting direction z", fontsize=10)
    fig.tight_layout()
    fig.savefig(OUT / f"{PREFIX}shapes.png", dpi=100)
    plt.close(fig)
    return [OUT / f"{PREFIX}shapes.png"]


def _tensions(results: dict[str, RunResult], plt) -> None:
    """Snap loads: the largest tension in the corner threads and in the mesh threads."""
    fig, axes = plt.subplots(2, 1, figsize=(7.5, 6.5), sharex=True)
    for name, r in results.items():
        tension, t = r.arrays["tension"], r.arrays["time"]
        corner = _corner_elements(r)
        mesh = np.setdiff1d(np.arange(tension.shape[1]), corner)
        style = dict(color=COLOURS.get(name), ls="--" if "pinned" in name else "-", lw=1.1)
        axes[0].plot(t, tension[:, corner].max(axis=1), label=name, **style)
        axes[1].plot(t, tension[:, mesh].max(axis=1), **style)
    axes[0].set_ylabel("largest corner-thread\ntension [N]")
    axes[1].set_ylabel("largest mesh-thread\ntension [N]")
    axes[1].set_xlabel("time [s]")
    axes[0].legend(fontsize=8)
    for a in axes:
        a.grid(alpha=0.3)
    fig.suptitle("Tension histories at the saved frames (every 10 ms)", fontsize=10)
    fig.tight_layout()
    fig.savefig(OUT / f"{PREFIX}tension.png", dpi=110)
    plt.close(fig)


def element_rotation(r: RunResult) -> np.ndarray | None:
    """Largest change, over the elements, of the relative rotation between an element's two end
    triads since the start [rad] per frame, ``(F,)``; None without one rotation per node
    (cables, pinned knots: ``rotations`` gives only the first element end at a node)."""
    if "rotations" not in r.arrays or "rigid" not in str(r.summary["scene"]["model"].get("knots")):
        return None
    q, seg = r.arrays["rotations"], r.arrays["segments"]
    rel = _quat_mul(_quat_conj(q[:, seg[:, 0]]), q[:, seg[:, 1]])      # (F, E, 4)
    change = _quat_mul(_quat_conj(rel[:1]), rel)
    return (2.0 * np.arccos(np.clip(np.abs(change[..., 0]), 0.0, 1.0))).max(axis=1)


def _quat_conj(q: np.ndarray) -> np.ndarray:
    return q * np.array([1.0, -1.0, -1.0, -1.0])


def _quat_mul(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    w1, v1, w2, v2 = a[..., :1], a[..., 1:], b[..., :1], b[..., 1:]
    return np.concatenate([w1 * w2 - (v1 * v2).sum(-1, keepdims=True),
                           w1 * v2 + w2 * v1 + np.cross(v1, v2)], axis=-1)


def _corner_elements(r: RunResult) -> np.ndarray:
    """Elements that touch a corner mass or belong to the chain of a corner thread (the last
    elements of the structure: corner threads come after the mesh threads)."""
    corners = [r.summary["nodes"][f"net:corner:{i}"] for i in range(4)]
    segments = r.arrays["segments"]
    return np.flatnonzero(np.isin(segments, corners).any(axis=1))


def _limit(name: str) -> str:
    """The wall-time limit a stored variant ran with ("-": none recorded)."""
    stored = folder_of(name) / "study.json"
    limit = json.loads(stored.read_text()).get("limit_s") if stored.is_file() else None
    return "-" if limit is None else f"{limit:.0f}"


def _fmt(value: float | None, digits: int) -> str:
    return "-" if value is None or not math.isfinite(value) else f"{value:.{digits}f}"


def table(results: dict[str, RunResult], walls: dict[str, float]) -> str:
    lines = ["| variant | status | simulated s | max mouth area m^2 | time of max s | "
             "distance at max m | max tension N | steps | Newton its | wall s | limit s | "
             "largest element rotation over the frames rad |",
             "|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for name, r in results.items():
        m, s, rot = r.summary["metrics"], r.summary, element_rotation(r)
        status = "completed" if r.status == "ok" else \
            "time limit" if r.message.startswith("interrupted") else "stopped"
        lines.append(f"| {name} | {status} | {s['simulated_time_s']:.2f} | "
                     f"{_fmt(m.get('max_mouth_area'), 2)} | {_fmt(m.get('time_of_max_mouth_area'), 2)} | "
                     f"{_fmt(m.get('distance_at_max_mouth_area'), 2)} | {_fmt(m.get('max_tension'), 1)} | "
                     f"{s['steps']} | {s['newton_iterations']} | {walls[name]:.0f} | {_limit(name)} | "
                     f"{_fmt(None if rot is None else float(rot.max()), 2)} |")
    stops = [f"- {name}: {r.message}" for name, r in results.items() if r.status != "ok"]
    if stops:
        lines += ["", "Runs that did not reach the end (their metrics cover only the time they "
                  "reached; \"interrupted\" means the study's wall-time limit):", *stops]
    return "\n".join(lines) + "\n"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--n", type=int, default=1, help="elements per thread")
    parser.add_argument("--tolerance", type=float, default=1e-4, help="error_tolerance [m]")
    parser.add_argument("--duration", type=float, default=3.0)
    parser.add_argument("--only", default=None, help="only the variants whose name contains this")
    parser.add_argument("--limit", type=float, default=900.0, help="wall seconds per variant")
    parser.add_argument("--reuse", action="store_true", help="read variants already in out/ "
                        "(out_explicit_n<n>/ with --explicit)")
    parser.add_argument("--explicit", action="store_true", help="the explicit integrator")
    parser.add_argument("--publish", action="store_true",
                        help="also write the tracked table beside this script and the figures "
                             "under docs/img/ (default: only out/ or out_explicit_n<n>/)")
    args = parser.parse_args()
    global OUT, PREFIX
    if args.explicit:
        OUT, PREFIX = HERE / f"out_explicit_n{args.n}", f"bending_explicit_n{args.n}_"
    results, walls = {}, {}
    for name, overrides in variants().items():
        if (args.only and args.only not in name) or (args.explicit and "dt_max" in name):
            continue
        stored = load_variant(name) if args.reuse else None
        if stored is None:
            print(f"deploy_bending: {name} ...", flush=True)
            stored = run_variant(name, overrides, args.n, args.tolerance, args.duration, args.limit,
                                 args.explicit)
        results[name], walls[name] = stored
        r = results[name]
        print(f"  {name}: {r.status} at t = {r.summary['simulated_time_s']:.3f} s in {walls[name]:.0f} s "
              f"{r.message} {r.summary['metrics']}", flush=True)
    text = table(results, walls)
    stepping = ("the explicit integrator (rods: scaled rotary inertia, FORMULATION.md §9b; no "
                "bending: the lumped model), explicit_safety 0.5" if args.explicit else
                f"generalized-alpha (rho_inf 0.7) with error_tolerance = {args.tolerance:g} m "
                "(variants named dt_max: no error control)")
    table_name = "results.md" if not args.explicit else f"results_explicit_n{args.n}.md"
    OUT.mkdir(parents=True, exist_ok=True)
    (OUT / table_name).write_text(
        f"# Bending study\n\nn = {args.n} element(s) per thread, {stepping}, "
        f"{args.duration:g} s simulated, one BLAS thread; wall time includes building the model; "
        "limit: the wall-time limit the run had (-: none; such runs marked \"time limit\" were "
        "interrupted by hand, see docs/bending.md).\n\n" + text)
    print(text)
    written = [OUT / table_name, *figures(results)]
    print(f"deploy_bending: results written to {OUT}/: " + ", ".join(p.name for p in written))
    if args.publish:
        published = {written[0]: HERE / table_name, **{p: IMG / p.name for p in written[1:]}}
        for source, target in published.items():
            target.parent.mkdir(parents=True, exist_ok=True)
            shutil.copyfile(source, target)
        print("deploy_bending: published (tracked files rewritten): "
              + ", ".join(str(p) for p in published.values()))
    else:
        print("deploy_bending: tracked files left unchanged (rerun with --publish to rewrite them)")


if __name__ == "__main__":
    main()
