"""Write reference.csv: the tip of the 45-degree bend at 17 loads, P = 0 to 600 in steps of 37.5,
from the Cosserat rod equations of the curved cantilever integrated along the arc and shot on the
tip position (``bend_tip`` of tests/validation/test_statics.py, independent of rodnet's
elements; README.md). Run from the repository root (about a minute of CPU):

    .venv/bin/python validation/cases/bend45/make_reference.py
"""

from __future__ import annotations

import importlib.util
import tomllib
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
LEVELS = 16


def main() -> None:
    spec = importlib.util.spec_from_file_location(
        "test_statics", HERE.parents[2] / "tests" / "validation" / "test_statics.py")
    assert spec is not None and spec.loader is not None
    statics = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(statics)
    scene = tomllib.loads((HERE / "scene.toml").read_text())
    mat = scene["materials"][0]
    force = np.asarray(scene["loads"][0]["force"], float)
    rows = ["# the tip of the bend45 scene from the rod equations (make_reference.py)",
            "load_factor,x,y,z"]
    for level in range(LEVELS + 1):
        factor = level / LEVELS
        tip = statics.bend_tip(force * factor, 100.0, np.pi / 4, mat["axial_stiffness"],
                               mat["shear_stiffness"], mat["bending_stiffness"],
                               mat["torsional_stiffness"], steps=max(level, 1))
        rows.append(f"{factor:.6f}," + ",".join(f"{v:.12g}" for v in tip))
        print(rows[-1], flush=True)
    (HERE / "reference.csv").write_text("\n".join(rows) + "\n")


if __name__ == "__main__":
    main()
