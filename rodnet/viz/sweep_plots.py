"""Plots of a sweep: each metric against each varied key, ``sweep_<metric>.png`` (matplotlib,
Agg), one panel per varied key.

In a panel the completed runs (status ``"ok"``) are points of the metric against the key. Runs
that share the values of every other varied key are joined by a line (a grid's rows; the legend
gives those values) when there are at most :data:`MAX_LINES` such lines; otherwise (a Latin
hypercube, a large grid) the points stand alone. Keys with values other than numbers (an
integrator's name, ``true``/``false``) are placed at evenly spaced ticks.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

MAX_LINES = 8
"""At most this many lines per panel, else points only."""

SKIPPED = ("index", "status", "message", "wall_time_s", "steps")
"""Columns that are neither varied keys nor metrics of the runs' ``summary.json``."""


def metrics(rows: list[dict[str, Any]], keys: list[str]) -> list[str]:
    """The metric columns of ``rows`` (numbers, neither varied keys nor :data:`SKIPPED`), in
    order of appearance."""
    found: list[str] = []
    for r in rows:
        found += [c for c, v in r.items() if c not in (*SKIPPED, *keys, *found) and _number(v)]
    return found


def _number(value: Any) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool)


def plot_sweep(directory: Path, keys: list[str], rows: list[dict[str, Any]]) -> list[str]:
    """Write ``directory/sweep_<metric>.png`` for every metric of the completed rows.

    Returns
    -------
    warnings : list of str
        Why the plots were not drawn (matplotlib is missing; no run completed).
    """
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        return ["matplotlib is not installed: the sweep's plots (sweep_<metric>.png) are "
                "skipped; install it (pip install matplotlib, or the [viz] extra) and run the "
                "sweep again to draw them"]
    ok = [r for r in rows if r.get("status") == "ok"]
    if not ok:
        return ["no run completed: the sweep's plots are skipped"]
    for metric in metrics(ok, keys):
        fig, axes = plt.subplots(1, len(keys), figsize=(4.2 * len(keys), 3.4), squeeze=False)
        for ax, key in zip(axes[0], keys):
            _panel(ax, ok, keys, key, metric)
        fig.tight_layout()
        fig.savefig(directory / f"sweep_{metric}.png", dpi=110)
        plt.close(fig)
    return []


def _panel(ax: Any, rows: list[dict[str, Any]], keys: list[str], key: str, metric: str) -> None:
    """``metric`` against ``key``: a line per combination of the other keys, or points."""
    values = [r[key] for r in rows]
    numeric = all(_number(v) for v in values)
    labels = sorted({_text(v) for v in values}) if not numeric else []

    def x(value: Any) -> float:
        return float(value) if numeric else float(labels.index(_text(value)))

    others = [k for k in keys if k != key]
    groups: dict[str, list[dict[str, Any]]] = {}
    for r in rows:
        groups.setdefault(json.dumps([r[k] for k in others]), []).append(r)
    lines = len(groups) <= MAX_LINES and any(len(g) > 1 for g in groups.values())
    for group in groups.values() if lines else [rows]:
        group = sorted(group, key=lambda r: x(r[key]))
        label = ", ".join(f"{k} = {_text(group[0][k])}" for k in others) if lines else None
        ax.plot([x(r[key]) for r in group], [r[metric] for r in group],
                "o-" if lines else "o", ms=4, label=label or None)
    if not numeric:
        ax.set_xticks(range(len(labels)), labels)
    ax.set_xlabel(key)
    ax.set_ylabel(metric)
    ax.grid(alpha=0.3)
    if lines and others:
        ax.legend(fontsize=7)


def _text(value: Any) -> str:
    """A value as a label (floats to 4 digits: a Latin-hypercube sample has 16)."""
    if isinstance(value, float):
        return f"{value:.4g}"
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, (list, tuple)):
        return json.dumps(list(value))
    return str(value)
