"""Benchmark: what rigid-body contact costs while the target is far away.

The reference deployment (``rodnet demo``: lumped model, explicit, 3 s, 301 frames; VTK, picture
and plot off) runs without a body and with the capture study's target, a free cylinder of 2.4 m
diameter, 6.5 m length and 1400 kg, 100 m down-range (never reached). Both run in this one
process after a warm-up run of each (compiled kernels loaded), alternating, ``--repeats`` times;
the table gives the smallest integration wall time (``summary.json`` ``wall_time_s``: the step
loop and the saved frames) of each. Prints a Markdown table and writes it to
``results/contact_overhead.md``.

Usage, from the repository root, with one BLAS thread:
``OPENBLAS_NUM_THREADS=1 python validation/benchmarks/contact_overhead.py [--repeats 3]``
"""

from __future__ import annotations

import argparse
import tempfile
from pathlib import Path

from rodnet.cli import demo_scene_text
from rodnet.run import run
from rodnet.scene import scene_from_toml

HERE = Path(__file__).parent
TARGET = """
[[bodies]]
name = "sl8"
shape = "cylinder"
size = [2.4, 2.4, 6.5]
mass = 1400.0
position = [0.0, 0.0, 100.0]
orientation_deg = [0.0, 90.0, 0.0]
angular_velocity_deg = [0.0, 2.0, 0.0]

[contact]
stiffness = 1.0e4
damping = 2.0
friction = 0.3
"""
OVERRIDES = ["output.vtk=false", "output.picture=false", "output.plot=false"]
CASES = {"no body": "", "cylinder 100 m down-range": TARGET}


def once(text: str, out: str) -> dict:
    """One run of the scene ``text``; its summary."""
    result = run(scene_from_toml(text, OVERRIDES), out, progress=False)
    assert result.status == "ok", result.message
    return result.summary


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args()
    walls: dict[str, list[float]] = {name: [] for name in CASES}
    summaries: dict[str, dict] = {}
    with tempfile.TemporaryDirectory(prefix="rodnet-bench-") as out:
        for name, extra in CASES.items():  # warm-up: compiled kernels loaded from the cache
            once(demo_scene_text() + extra, out)
        for _ in range(args.repeats):
            for name, extra in CASES.items():
                summaries[name] = once(demo_scene_text() + extra, out)
                walls[name].append(float(summaries[name]["wall_time_s"]))
    base = min(walls["no body"])
    lines = ["# Contact overhead while the target is far", "",
             f"The reference deployment (3 s, explicit, 301 frames), best of {args.repeats} "
             "runs each, alternating, one process, `OPENBLAS_NUM_THREADS=1`. Script: "
             "`validation/benchmarks/contact_overhead.py`.", "",
             "| case | steps | dt far [s] | dt near a body [s] | wall, best [s] | all runs [s] "
             "| overhead |", "|---|---|---|---|---|---|---|"]
    for name in CASES:
        s = summaries[name]["integrator"]
        near = s.get("dt_near_bodies")
        lines.append(f"| {name} | {summaries[name]['steps']} | {s['dt']:.3e} | "
                     f"{'-' if near is None else f'{near:.3e}'} | {min(walls[name]):.3f} | "
                     f"{', '.join(f'{w:.3f}' for w in walls[name])} | "
                     f"{min(walls[name]) / base - 1:+.1%} |")
    text = "\n".join(lines) + "\n"
    print(text)
    (HERE / "results").mkdir(exist_ok=True)
    (HERE / "results" / "contact_overhead.md").write_text(text)


if __name__ == "__main__":
    main()
