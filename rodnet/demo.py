"""``rodnet demo``: the reference deployment with Cosserat threads and the lumped reference side
by side.

The mission's model, Cosserat threads with bending and torsion, runs into the output directory;
the lumped-parameter reference of tether-net studies runs into its ``lumped/`` folder; then
``comparison.png`` draws both histories and their difference (:mod:`rodnet.viz.compare`) and the
console gets a table of both runs' metrics. ``rodnet demo --quick`` runs the reference scene
alone (lumped unless ``--set`` says otherwise), into the output directory.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from rodnet.data import reference_scene_text
from rodnet.scene import Scene, scene_from_toml

ROD_SETTINGS = ("model.type=cosserat", "model.elements_per_thread=2", "model.knots=pinned",
                "simulation.integrator=explicit")
"""The demo's Cosserat run: two rod elements per thread with bending and torsion, pinned knots,
explicit with the scaled rotary inertia: on the reference deployment the integrator that reaches
the converged largest mouth area in the least time (implicit BDF2 at its defaults took about
7,200 steps and 47,000 Newton iterations: validation/benchmarks/implicit_deployment.py)."""

LUMPED_FOLDER = "lumped"
"""Sub-folder of the output directory that holds the lumped reference run."""


def demo_scenes(overrides: list[str], quick: bool) -> list[tuple[str, Scene, str]]:
    """The demo's runs as ``(label, scene, sub-folder)``, every scene built and checked before
    any runs. The user's ``--set`` overrides apply to each run, after the demo's own settings,
    except ``model.*`` keys, which change only the Cosserat run (the reference stays lumped);
    ``quick``: the reference scene alone with every override."""
    text = reference_scene_text()
    if quick:
        return [("reference", scene_from_toml(text, overrides, source="rodnet demo"), "")]
    shared = [o for o in overrides if not o.strip().startswith("model.")]
    lumped = ("lumped reference", scene_from_toml(text, shared, source="rodnet demo"), "")
    rods = scene_from_toml(text, [*ROD_SETTINGS, *overrides], source="rodnet demo (Cosserat threads)")
    return [("Cosserat threads", rods, ""), (lumped[0], lumped[1], LUMPED_FOLDER)]


def metrics_table(labels: tuple[str, str], summaries: tuple[dict[str, Any], dict[str, Any]]) -> str:
    """A console table of the metrics both runs report, with the first run's difference from
    the second in percent of the second."""
    first, second = (s["metrics"] for s in summaries)
    keys = [k for k in first if k in second and isinstance(first[k], (int, float))]
    width = max((len(k) for k in keys), default=10)
    lines = [f"  {'':{width}s} {labels[0]:>18s} {labels[1]:>18s} {'difference':>11s}"]
    for k in keys:
        a, b = float(first[k]), float(second[k])
        diff = f"{100.0 * (a - b) / abs(b):+.2f} %" if b != 0.0 else "-"
        lines.append(f"  {k:{width}s} {a:18.6g} {b:18.6g} {diff:>11s}")
    return "\n".join(lines)


def write_comparison(directory: Path, labels: tuple[str, str]) -> list[str]:
    """``comparison.png`` of the run in ``directory`` against the one in its lumped folder;
    returns warnings (no matplotlib, unreadable results) instead of raising."""
    try:
        from rodnet.viz.compare import compare_runs, plot_comparison

        comparison = compare_runs(directory, directory / LUMPED_FOLDER, labels)
        plot_comparison(comparison, directory / "comparison.png")
    except ImportError as exc:
        return [f"no comparison.png: {exc} (install the viz extra)"]
    except (OSError, ValueError) as exc:
        return [f"no comparison.png: {exc}"]
    return []
