"""The report's pictures as PNG bytes (matplotlib's Agg canvas; no window, no global backend):
a case's curves against its reference, the errors of a refinement, and the checks of a case
that declares no figure."""

from __future__ import annotations

import io
from typing import Any

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from matplotlib.ticker import NullLocator

from rodnet.report.curves import Curves
from rodnet.report.refinement import Refinement
from rodnet.report.spec import HISTORY_X, SHAPE_X
from rodnet.validate import CheckResult

COLORS = ("tab:blue", "tab:orange", "tab:green", "tab:red")
DPI = 100


def _png(figure: Figure) -> bytes:
    FigureCanvasAgg(figure)
    buffer = io.BytesIO()
    figure.savefig(buffer, format="png", dpi=DPI)
    return buffer.getvalue()


def _draw_checks(ax: Any, curves: Curves, color: dict[str, str], offset: bool) -> None:
    """The checks as expected values with tolerance bars (``offset``: less the reference)."""
    for i, m in enumerate(curves.marks):
        centre = m.expected - m.reference if offset else m.expected
        ax.errorbar([m.x], [centre], yerr=[m.tolerance], fmt="s", mfc="none", ms=8, capsize=4,
                    color=color[m.component], label="check: expected +- tolerance" if i == 0 else None)


def _draw_bands(ax: Any, curves: Curves) -> None:
    for i, band in enumerate(curves.bands):
        ax.axhline(band.expected, color="black", lw=1.2, ls="--", label=f"expected {band.label}")
        ax.axhspan(band.expected - band.tolerance, band.expected + band.tolerance, color="0.6",
                   alpha=0.35, label="tolerance" if i == 0 else None)


def _finish(ax: Any, ylabel: str, legend: bool = True) -> None:
    ax.set_ylabel(ylabel)
    ax.grid(alpha=0.3)
    if legend:
        ax.legend(fontsize=8, loc="best")


def curves_figure(curves: Curves, title: str) -> bytes:
    """rodnet's curves against the reference. Below them, where a reference curve exists, their
    difference, with each check's tolerance about the expected value less the reference; where
    metric checks are drawn as bands, the same curves zoomed on the bands."""
    spec = curves.spec
    rows = 2 if curves.ref_at_x is not None or curves.bands else 1
    figure = Figure(figsize=(7.5, 5.2 if rows == 2 else 4.0), layout="constrained")
    axes = figure.subplots(rows, 1, sharex=True, squeeze=False,
                           height_ratios=[3, 2] if rows == 2 else [1])[:, 0]
    color = {c: COLORS[i % len(COLORS)] for i, c in enumerate(spec.components)}
    style = "-" if len(curves.x) > 60 else "o-"
    for k, ax in enumerate(axes[:1] if curves.ref_at_x is not None else axes):
        for c in spec.components:
            ax.plot(curves.x, curves.y[c], style, ms=4, color=color[c],
                    label=f"rodnet {c}" if spec.quantity != "series" else "rodnet")
            if curves.ref_y is not None and curves.ref_x is not None:
                ax.plot(curves.ref_x, curves.ref_y[c], "--", color="black", lw=1.2,
                        label="reference" if c == spec.components[0] else None)
        _draw_bands(ax, curves)
        _draw_checks(ax, curves, color, offset=False)
        _finish(ax, spec.ylabel, legend=k == 0)
    axes[0].set_title(title)
    if curves.ref_at_x is not None and rows == 2:
        low = axes[1]
        for c in spec.components:
            low.plot(curves.x, curves.y[c] - curves.ref_at_x[c], style, ms=4, color=color[c],
                     label=f"rodnet {c} - reference")
        low.axhline(0.0, color="black", lw=0.8)
        _draw_checks(low, curves, color, offset=True)
        _finish(low, "rodnet - reference")
    elif rows == 2:
        low = min(b.expected - 2.5 * b.tolerance for b in curves.bands)
        high = max(b.expected + 1.5 * b.tolerance for b in curves.bands)
        axes[1].set_ylim(low, high)
        axes[1].set_ylabel(f"{spec.ylabel}\n(zoomed)")
    axes[-1].set_xlabel({**HISTORY_X, **SHAPE_X}[spec.x])
    return _png(figure)


def refinement_figure(refinement: Refinement, title: str) -> bytes:
    """The error against the varied value on log axes, with the slope of the expected order."""
    spec = refinement.spec
    values, errors = np.asarray(spec.values, float), np.asarray(refinement.errors, float)
    figure = Figure(figsize=(6.0, 4.0), layout="constrained")
    ax = figure.subplots()
    ok = np.isfinite(errors) & (errors > 0)
    ax.loglog(values[ok], errors[ok], "o-", label=f"|rodnet - expected|: {refinement.label}")
    if spec.expected_order is not None and ok.any():
        last = np.flatnonzero(ok)[-1]
        sign = -1.0 if spec.scale == "count" else 1.0
        slope = errors[last] * (values / values[last]) ** (sign * spec.expected_order)
        ax.loglog(values, slope, "--", color="black", lw=1,
                  label=f"order {spec.expected_order:g}")
    ax.set_xticks(values, [f"{v:g}" for v in values])
    ax.xaxis.set_minor_locator(NullLocator())
    ax.set_xlabel(spec.key)
    ax.set_ylabel("error")
    ax.set_title(title)
    ax.grid(alpha=0.3, which="both")
    ax.legend(fontsize=8)
    return _png(figure)


def checks_figure(checks: list[CheckResult], title: str) -> bytes:
    """Each check's deviation from its expected value in units of its tolerance (a case with no
    ``[figure]`` table): inside the band [-1, 1] it passes."""
    figure = Figure(figsize=(7.5, 1.2 + 0.35 * max(len(checks), 1)), layout="constrained")
    ax = figure.subplots()
    ratio = [(c.value - c.expected) / c.tolerance if c.tolerance > 0 else
             (0.0 if c.value == c.expected else np.inf) for c in checks]
    shown = np.clip(np.nan_to_num(np.asarray(ratio, float), nan=np.inf), -3.0, 3.0)
    y = np.arange(len(checks))
    ax.barh(y, shown, color=["tab:green" if c.passed else "tab:red" for c in checks])
    ax.axvspan(-1.0, 1.0, color="0.85", zorder=0)
    ax.set_yticks(y, [c.label for c in checks], fontsize=8)
    ax.invert_yaxis()
    ax.set_xlim(-3.2, 3.2)
    ax.set_xlabel("(value - expected) / tolerance (clipped at 3)")
    ax.set_title(title)
    return _png(figure)
