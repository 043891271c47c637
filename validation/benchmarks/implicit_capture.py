"""Benchmark: the capture of docs/capture.md with the target free, implicit against explicit.

The scene of the capture study (the reference net, lumped model, thrown at the tumbling 1400 kg
cylinder; validation/cases/capture_reference/study.py writes it) is run through the public CLI
(``rodnet run``, each run its own process) for 4 s: with the model's default integrator
(explicit) and with ``simulation.integrator = "bdf2"`` and no step keys (default step control).
The free target is six unknowns of the implicit system (elements/contact/FORMULATION.md
section 9). Reported: wall time, steps, Newton iterations, factorisations, the target's speed
and spin at 2.5 s and 4 s (before and after the snap of the whole net against the target at
2.9 s), the largest mouth area and the deepest node inside the target.

Usage: ``python validation/benchmarks/implicit_capture.py``; writes
``results/implicit_capture.md`` (the runs go to a temporary folder).
"""

from __future__ import annotations

import json
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

from rodnet.kernels import so3

HERE = Path(__file__).parent
sys.path.insert(0, str(HERE.parent / "cases" / "capture_reference"))
from study import LENGTH, RADIUS, scene_text  # noqa: E402

RESULT = HERE / "results" / "implicit_capture.md"
DURATION = 4.0
TIMES = (2.5, 4.0)
RUNS = {"explicit (default)": [], "bdf2, default step control": ["simulation.integrator=bdf2"]}


def deepest(arrays: dict) -> float:
    """Largest depth of a node inside the cylinder over the frames [m]."""
    worst = 0.0
    for x, p, q in zip(arrays["positions"], arrays["body_positions"][:, 0],
                       arrays["body_rotations"][:, 0]):
        local = (x - p) @ so3.quat_to_matrix(q)
        depth = np.minimum(RADIUS - np.hypot(local[:, 0], local[:, 1]),
                           0.5 * LENGTH - np.abs(local[:, 2]))
        worst = max(worst, float(depth.max(initial=0.0)))
    return worst


def run(label: str, overrides: list[str], scene: Path, folder: Path) -> dict:
    out = folder / label.split()[0].replace(",", "")
    args = [sys.executable, "-m", "rodnet", "run", str(scene), "-o", str(out), "--quiet",
            "--set", f"simulation.duration={DURATION}", "--set", "output.vtk=false"]
    for o in overrides:
        args += ["--set", o]
    subprocess.run(args, check=False)
    summary = json.loads((out / "summary.json").read_text())
    arrays = dict(np.load(out / "result.npz"))
    t = arrays["time"]
    record = {"status": summary["status"], "wall": summary.get("wall_time_s"),
              "steps": summary.get("steps"), "newton": summary.get("newton_iterations"),
              "factorizations": summary.get("factorizations"),
              "mouth": summary["metrics"]["max_mouth_area"], "deepest": deepest(arrays)}
    for time in TIMES:
        i = int(np.argmin(np.abs(t - time)))
        record[f"v{time}"] = arrays["body_velocities"][i, 0]
        record[f"w{time}"] = np.degrees(arrays["body_angular_velocities"][i, 0])
    return record


def main() -> str:
    with tempfile.TemporaryDirectory(prefix="rodnet-capture-") as tmp:
        folder = Path(tmp)
        scene = folder / "capture.toml"
        scene.write_text(scene_text("cylinder"))
        records = {label: run(label, o, scene, folder) for label, o in RUNS.items()}
    ref = records["explicit (default)"]
    lines = ["# Capture with a free target: implicit BDF2 against explicit", "",
             f"Scene: docs/capture.md (cylinder target, lumped model), {DURATION:g} s, run by "
             "`python validation/benchmarks/implicit_capture.py` through `rodnet run`.", "",
             "| run | status | wall [s] | steps | Newton iterations | factorisations | "
             + " | ".join(f"speed at {t:g} s [cm/s] | spin at {t:g} s [deg/s]" for t in TIMES)
             + " | largest mouth area [m^2] | deepest node [mm] |",
             "|---|---|---:|---:|---:|---:|" + "---:|---:|" * len(TIMES) + "---:|---:|"]
    for label, r in records.items():
        cells = [label, r["status"], f"{r['wall']:.1f}", f"{r['steps']:,}", f"{r['newton']:,}",
                 f"{r['factorizations']:,}"]
        for t in TIMES:
            cells += [f"{100 * np.linalg.norm(r[f'v{t}']):.4f}",
                      f"{np.linalg.norm(r[f'w{t}']):.4f}"]
        cells += [f"{r['mouth']:.2f}", f"{1e3 * r['deepest']:.1f}"]
        lines.append("| " + " | ".join(cells) + " |")
    lines.append("")
    for label, r in records.items():
        if r is ref:
            continue
        for t in TIMES:
            dv = np.linalg.norm(r[f"v{t}"] - ref[f"v{t}"]) / np.linalg.norm(ref[f"v{t}"])
            lines.append(f"- {label}: target velocity at {t:g} s differs from the explicit "
                         f"run's by {100 * dv:.2f} % of its magnitude.")
        lines.append(f"- {label}: wall time {r['wall'] / ref['wall']:.0f} times the explicit "
                     "run's (same invocation, one after the other; the machine is shared).")
    text = "\n".join(lines) + "\n"
    RESULT.write_text(text)
    return text


if __name__ == "__main__":
    print(main())
