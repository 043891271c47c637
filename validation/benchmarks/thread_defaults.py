"""Benchmark: the clamped thread of ``thread_gravity.py`` at rodnet's default settings, and what
the step control's tolerance and the integrator change.

The 1.5 m x 1 mm nylon thread, clamped at one end and released straight and horizontal under
gravity, 1 s, with 20 and with 80 Cosserat elements. Each run leaves out ``dt``, ``adaptive``,
``integrator`` and ``rho_inf`` (so the defaults: BDF2 with the local error control at
``simulation.error_tolerance`` = rodnet.run.ERROR_FRACTION of the thread's size) except for the
keys its row names. The tip error is the largest distance over the saved frames (every 0.01 s)
from a run of the same elements at a fixed step small enough to be converged in time
(generalized-alpha, rho_inf 0.7; its own error is bounded by its distance from the run at twice
that step, printed under the table). CPU time (``time.process_time``) is the least of
``REPEATS`` identical runs of ``run()``, the build and the result files included.

Usage: ``python validation/benchmarks/thread_defaults.py [--quick]`` (``--quick``: 20 elements,
references at 1e-4 and 2e-4 s). Writes ``results/thread_defaults.md``.
"""

from __future__ import annotations

import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from rodnet.run import ERROR_FRACTION, run
from rodnet.scene import scene_from_toml

HERE = Path(__file__).parent
sys.path.insert(0, str(HERE))
from thread_gravity import SCENE, simulate  # noqa: E402  (the same thread)

REPEATS = 3
STEP_KEYS = ("dt", "adaptive", "integrator", "rho_inf")

DEFAULT_SCENE = "\n".join(line for line in SCENE.splitlines()
                          if line.split(" =")[0] not in STEP_KEYS)
"""The thread with no step keys: ``{duration}`` and ``{elements}`` still to fill in."""

VARIANTS = [
    ("defaults", []),
    ("error_tolerance 1e-5 m", ["simulation.error_tolerance=1e-5"]),
    ("error_tolerance 3e-6 m", ["simulation.error_tolerance=3e-6"]),
    ("error_tolerance 1e-6 m", ["simulation.error_tolerance=1e-6"]),
    ("generalized-alpha", ["simulation.integrator=generalized-alpha"]),
    ("generalized-alpha, error_tolerance 3e-6 m",
     ["simulation.integrator=generalized-alpha", "simulation.error_tolerance=3e-6"]),
]
"""Rows: a label and the ``--set`` overrides of the default scene."""


def tip(result) -> np.ndarray:  # type: ignore[no-untyped-def]
    """The free end's positions (frames, 3) [m]."""
    return result.arrays["positions"][:, result.summary["nodes"]["thread:end"]]


def timed(elements: int, overrides: list[str]) -> tuple[float, object]:
    """The least CPU seconds of ``REPEATS`` runs of the default scene with ``overrides``, and the
    last run's result."""
    text = DEFAULT_SCENE.format(duration=1.0, elements=elements)
    best, result = np.inf, None
    for _ in range(REPEATS):
        cpu = time.process_time()
        result = run(scene_from_toml(text, overrides), tempfile.mkdtemp(prefix="rodnet-thread-"),
                     progress=False)
        best = min(best, time.process_time() - cpu)
    return best, result


def main(quick: bool = False) -> str:
    timed(20, ["simulation.duration=0.02"])   # compiles what the runs need
    lines = ["| elements | settings | CPU s per simulated s | steps | rejected | Newton iterations "
             "| factorisations | tip error mm (max over run) | at t s |",
             "|---|---|---|---|---|---|---|---|---|"]
    notes = []
    for elements in ([20] if quick else [20, 80]):
        fine = 1e-4 if quick else (1e-5 if elements == 20 else 2e-5)
        ref = simulate(fine, elements=elements)
        check = simulate(2 * fine, elements=elements)
        own = np.linalg.norm(check["tip"] - ref["tip"], axis=1)
        notes.append(f"{elements} elements: reference dt {fine:g} s ({ref['cpu']:.1f} CPU s); "
                     f"the run at {2 * fine:g} s is {1e3 * own.max():.4f} mm from it")
        for label, overrides in VARIANTS:
            cpu, r = timed(elements, overrides)
            s = r.summary  # type: ignore[attr-defined]
            if r.status != "ok":  # type: ignore[attr-defined]
                lines.append(f"| {elements} | {label} | failed: {r.message[:60]} | | | | | | |")  # type: ignore[attr-defined]
                continue
            err = np.linalg.norm(tip(r) - ref["tip"], axis=1)
            k = int(np.argmax(err))
            lines.append(f"| {elements} | {label} | {cpu:.3f} | {s['steps']} | "
                         f"{s['rejected_steps']} | {s['newton_iterations']} | "
                         f"{s['factorizations']} | {1e3 * err[k]:.3f} | "
                         f"{r.arrays['time'][k]:.2f} |")  # type: ignore[attr-defined]
    text = "\n".join([*lines, "",
                      f"Default tolerance: ERROR_FRACTION = {ERROR_FRACTION:g} of the thread's "
                      f"size, {ERROR_FRACTION * 1.5:.3g} m. CPU time: the least of {REPEATS} "
                      "identical runs (build and result files included).",
                      *[f"- {n}." for n in notes]])
    (HERE / "results").mkdir(exist_ok=True)
    (HERE / "results" / "thread_defaults.md").write_text(
        "# Clamped thread at default settings\n\n" + text + "\n")
    return text


if __name__ == "__main__":
    print(main(quick="--quick" in sys.argv))
