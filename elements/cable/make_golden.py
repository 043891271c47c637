"""Regenerate ``golden.json``: frozen random cable states and the oracle's outputs.

Run ``python elements/cable/make_golden.py``. It is seeded, so a rerun reproduces the file
unless ``reference.py`` changed; tests check the file against the oracle.
"""

from __future__ import annotations

import dataclasses
import importlib.util
import json
import re
import sys
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
SEED = 20240612


def _load_reference():
    spec = importlib.util.spec_from_file_location("cable_reference", HERE / "reference.py")
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module
    spec.loader.exec_module(module)
    return module


ref = _load_reference()

# (name, strain e, strain rate de/dt along the chord, section parameters)
CASES = [
    ("taut, tension-only, damped", 0.02, 3.0, dict(EA=1e3, tau=2e-3)),
    ("taut but fast shortening, clamped", 0.01, -20.0, dict(EA=1e3, tau=2e-3)),
    ("slack, tension-only", -0.03, 1.0, dict(EA=1e3, tau=2e-3)),
    ("inside the ramp, tension-only", 0.02, 0.5, dict(EA=1e3, tau=1e-3, delta=0.05)),
    ("compressed, linear, damped", -0.02, -1.0, dict(EA=5e2, tau=1e-3, axial="linear")),
]


def random_state(rng: np.random.Generator, strain: float, strain_rate: float) -> dict:
    """A random element with chord strain ``strain`` and chord strain rate ``strain_rate``.

    The relative velocity also has a random transverse part, which the damping ignores but the
    velocity-dependent stiffness (CB10) does not.
    """
    Le = float(rng.uniform(0.05, 0.2))
    t = rng.normal(size=3)
    t /= np.linalg.norm(t)
    x1 = rng.normal(size=3)
    x2 = x1 + (1.0 + strain) * Le * t
    transverse = rng.normal(size=3)
    transverse -= (transverse @ t) * t
    v1 = 0.1 * rng.normal(size=3)
    v2 = v1 + strain_rate * Le * t + 0.5 * transverse
    return dict(x1=x1, x2=x2, v1=v1, v2=v2, Le=Le)


def _compact_lists(text: str) -> str:
    """Put each innermost list of numbers (a vector, a matrix row) on one line."""
    return re.sub(r"\[\s+([-+0-9.eE,\s]+?)\s+\]",
                  lambda m: "[" + ", ".join(x.strip() for x in m.group(1).split(",")) + "]", text)


def main() -> None:
    rng = np.random.default_rng(SEED)
    cases = []
    for name, strain, strain_rate, params in CASES:
        state = random_state(rng, strain, strain_rate)
        section = ref.CableSection(**params)
        x1, x2, v1, v2, Le = (state[k] for k in ("x1", "x2", "v1", "v2", "Le"))
        _, e, _, e_rate = ref.kinematics(x1, x2, Le, v1, v2)
        outputs = dict(
            strain=e, strain_rate=e_rate, axial_force=ref.axial_force(e, e_rate, section),
            energy=ref.energy(x1, x2, Le, section),
            internal_force=ref.internal_force(x1, x2, Le, section, v1, v2).tolist(),
            tangent_stiffness=ref.tangent_stiffness(x1, x2, Le, section, v1, v2).tolist(),
            tangent_fd=ref.tangent_fd(x1, x2, Le, section, v1, v2).tolist(),
            damping_matrix=ref.damping_matrix(x1, x2, Le, section, v1, v2).tolist(),
        )
        inputs = {k: (v.tolist() if isinstance(v, np.ndarray) else v) for k, v in state.items()}
        cases.append(dict(
            name=name, inputs=inputs | {"section": dataclasses.asdict(section)}, outputs=outputs
        ))
    data = dict(
        formulation="cable",
        generator="elements/cable/make_golden.py",
        seed=SEED,
        layout="DOF [dx1, dx2], global axes; velocities v1, v2 global",
        cases=cases,
    )
    (HERE / "golden.json").write_text(_compact_lists(json.dumps(data, indent=1)) + "\n")


if __name__ == "__main__":
    main()
