"""Two runs of the same deployment side by side: their histories of mouth area, distance
travelled and largest thread tension, and the difference between them.

:func:`compare_runs` reads two finished output directories (``result.npz``) and returns the
histories on the first run's frame times (the second interpolated linearly where its frames
differ) with the largest differences; :func:`plot_comparison` draws them.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]

QUANTITIES = (("mouth_area", "mouth area", "m$^2$"), ("distance", "distance travelled", "m"),
              ("largest_tension", "largest thread tension", "N"))
"""Compared histories: key, title and unit."""


@dataclass(frozen=True)
class Comparison:
    """The histories of two runs on common frame times.

    Attributes
    ----------
    time : (F,) float
        Frame times of the first run [s] within the second run's time span.
    labels : tuple of str
        Names of the two runs.
    histories : dict
        Key of :data:`QUANTITIES` -> (2, F) float, the first and the second run.
    """

    time: FloatArray
    labels: tuple[str, str]
    histories: dict[str, FloatArray]

    def largest_difference(self, key: str) -> tuple[float, float]:
        """The largest ``|first - second|`` of a history and that difference relative to the
        second run's largest absolute value."""
        pair = self.histories[key]
        diff = float(np.abs(pair[0] - pair[1]).max(initial=0.0))
        ref = float(np.abs(pair[1]).max(initial=0.0))
        return diff, diff / ref if ref > 0.0 else 0.0


def _histories(directory: Path) -> tuple[FloatArray, dict[str, FloatArray]]:
    """Frame times and the compared histories of one output directory."""
    path = directory / "result.npz"
    if not path.is_file():
        raise FileNotFoundError(f"{directory} holds no result.npz: not a finished rodnet run")
    with np.load(path) as data:
        missing = [k for k in ("mouth_area", "distance", "tension") if k not in data.files]
        if missing:
            raise ValueError(f"{path} has no {', '.join(missing)}: only net runs can be compared")
        tension = np.asarray(data["tension"], dtype=float)
        return np.asarray(data["time"], dtype=float), {
            "mouth_area": np.asarray(data["mouth_area"], dtype=float),
            "distance": np.asarray(data["distance"], dtype=float),
            "largest_tension": tension.max(axis=1, initial=0.0)}


def compare_runs(first: Path, second: Path, labels: tuple[str, str]) -> Comparison:
    """The histories of the runs in ``first`` and ``second`` on the first run's frame times
    that lie within the second's (the second interpolated linearly)."""
    t1, h1 = _histories(first)
    t2, h2 = _histories(second)
    keep = (t1 >= t2[0] - 1e-12) & (t1 <= t2[-1] + 1e-12)
    time = t1[keep]
    return Comparison(time, labels, {key: np.vstack([h1[key][keep], np.interp(time, t2, h2[key])])
                                     for key, _, _ in QUANTITIES})


def plot_comparison(comparison: Comparison, path: Path) -> Path:
    """Draw each history of both runs (left axis) and their difference, first minus second
    (right axis), one panel per quantity, to ``path`` (PNG)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(len(QUANTITIES), 1, figsize=(8, 3.2 * len(QUANTITIES)),
                             sharex=True, constrained_layout=True)
    first, second = comparison.labels
    for ax, (key, title, unit) in zip(axes, QUANTITIES):
        pair = comparison.histories[key]
        ax.plot(comparison.time, pair[0], color="tab:blue", label=first)
        ax.plot(comparison.time, pair[1], color="tab:green", linestyle="--", label=second)
        ax.set_ylabel(f"{title} [{unit}]")
        twin = ax.twinx()
        twin.plot(comparison.time, pair[0] - pair[1], color="tab:red", linewidth=0.8,
                  label=f"{first} - {second}")
        twin.set_ylabel(f"difference [{unit}]", color="tab:red")
        handles = ax.get_legend_handles_labels()
        more = twin.get_legend_handles_labels()
        ax.legend(handles[0] + more[0], handles[1] + more[1], fontsize=8, loc="best")
        ax.set_title(title)
    axes[-1].set_xlabel("time [s]")
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path
